//! Shared harness of the API tests: an in-process daemon on the simulated machine, served on a
//! Unix socket in the test's temporary data directory (local trust: `api.local_role`, what
//! [`Daemon::channel`] gives), a loopback port (`api.loopback_role`, observer by default) and a
//! "remote" loopback port (TLS + token required).
#![allow(dead_code)]

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use daemon::runtime::config::{Config, Role, TokenConfig};
use daemon::runtime::controller::{ClockKind, Controller};
use daemon::runtime::rt::MachineState;
use daemon::runtime::server::{self, Listeners};
use hal::{BusFault, CycleCommand, CycleFeedback, DriveBus, FaultReason};
use proto::v1 as pb;
use proto::v1::machine_client::MachineClient;
use proto::v1::preview_client::PreviewClient;
use tonic::transport::{Channel, ServerTlsConfig};

#[allow(unused_imports)] // each test binary uses a different subset
pub use tests::{wait_job_finished, wait_state};

pub const OBSERVER_TOKEN: &str = "observer-secret-1";
pub const OPERATOR_TOKEN: &str = "operator-secret-2";
pub const ADMIN_TOKEN: &str = "admin-secret-3";

/// The simulated bus with a fault switch.
pub struct FaultBus {
    inner: sim::SimBus,
    pub fault: Arc<AtomicBool>,
}

impl DriveBus for FaultBus {
    daemon::delegate_drive_bus!(inner: name, axes, enable);
    fn cycle(&mut self, cmd: &CycleCommand, fb: &mut CycleFeedback) -> Result<(), BusFault> {
        let r = self.inner.cycle(cmd, fb);
        if self.fault.load(Ordering::Relaxed) {
            return Err(BusFault {
                axis: Some(0),
                node: Some(1),
                reason: FaultReason::DriveFault { code: 0x2310 },
            });
        }
        r
    }
    fn reset(&mut self) {
        self.fault.store(false, Ordering::Relaxed);
        self.inner.reset()
    }
}

pub struct Daemon {
    pub ctl: Arc<Controller>,
    /// Loopback TCP (`api.loopback_role` without a token).
    pub local: String,
    /// Loopback served as a remote listener: TLS and a token required.
    pub remote: String,
    /// Unix socket path.
    pub unix: std::path::PathBuf,
    pub fault: Arc<AtomicBool>,
    pub ca_pem: String,
}

/// The test configuration with the three tokens.
pub fn config(local_role: Role) -> Config {
    let mut cfg = tests::test_config();
    cfg.api.local_role = local_role;
    cfg.api.tokens = [
        ("hmi-view", Role::Observer, OBSERVER_TOKEN),
        ("hmi-op", Role::Operator, OPERATOR_TOKEN),
        ("setter", Role::Admin, ADMIN_TOKEN),
    ]
    .into_iter()
    .map(|(n, r, t)| TokenConfig {
        name: n.into(),
        role: r,
        sha256: daemon::runtime::api::auth::hash_token_hex(t),
    })
    .collect();
    cfg
}

pub async fn start(cfg: Config) -> Daemon {
    let fault = Arc::new(AtomicBool::new(false));
    let bus = FaultBus {
        inner: sim::SimBus::new(sim::SimDriveParams::default(), &vec![0.0; cfg.axes.len()]),
        fault: fault.clone(),
    };
    let unix = cfg.storage.dir.join("cncd.sock");
    let ctl = Controller::start_with_bus(cfg, ClockKind::Monotonic, Box::new(bus)).unwrap();
    let local = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let remote = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let local_addr = local.local_addr().unwrap();
    let remote_addr = remote.local_addr().unwrap();
    let cert = rcgen::generate_simple_self_signed(vec!["localhost".to_string()]).unwrap();
    let ca_pem = cert.cert.pem();
    let tls = ServerTlsConfig::new().identity(tonic::transport::Identity::from_pem(
        cert.cert.pem(),
        cert.signing_key.serialize_pem(),
    ));
    let l = Listeners {
        local_tcp: vec![local],
        remote_tcp: vec![remote],
        unix: Some(server::bind_unix(&unix, 0o660, None).unwrap()),
    };
    tokio::spawn(server::serve_listeners_with(
        ctl.clone(),
        l,
        Some(tls),
        std::future::pending(),
    ));
    wait_state(&ctl, MachineState::Idle).await;
    Daemon {
        ctl,
        local: format!("http://{local_addr}"),
        remote: format!("https://localhost:{}", remote_addr.port()),
        unix,
        fault,
        ca_pem,
    }
}

impl Daemon {
    /// The tests' local channel: the Unix socket (tokenless callers get `api.local_role`).
    pub async fn channel(&self) -> Channel {
        self.unix_channel().await
    }

    /// The Unix socket's address for cncctl and tonic (`unix:/path`).
    pub fn socket(&self) -> String {
        format!("unix:{}", self.unix.display())
    }

    /// Loopback TCP: tokenless callers get `api.loopback_role` (observer by default).
    pub async fn loopback_channel(&self) -> Channel {
        Channel::from_shared(self.local.clone())
            .unwrap()
            .connect()
            .await
            .unwrap()
    }

    pub async fn tls_channel(&self) -> Channel {
        let tls = tonic::transport::ClientTlsConfig::new()
            .ca_certificate(tonic::transport::Certificate::from_pem(&self.ca_pem))
            .domain_name("localhost");
        Channel::from_shared(self.remote.clone())
            .unwrap()
            .tls_config(tls)
            .unwrap()
            .connect()
            .await
            .unwrap()
    }

    pub async fn unix_channel(&self) -> Channel {
        tonic::transport::Endpoint::from_shared(format!("unix:{}", self.unix.display()))
            .unwrap()
            .connect()
            .await
            .unwrap()
    }
}

/// Adds `authorization: Bearer <token>` to a request.
pub fn with_token<T>(msg: T, token: &str) -> tonic::Request<T> {
    let mut r = tonic::Request::new(msg);
    r.metadata_mut()
        .insert("authorization", format!("Bearer {token}").parse().unwrap());
    r
}

/// Waits until `f` holds; fails the test after [`tests::PATIENCE`] (a hang bound, not a timing).
pub async fn wait_until(what: &str, mut f: impl FnMut() -> bool) {
    let t0 = Instant::now();
    while !f() {
        assert!(
            t0.elapsed() < tests::PATIENCE,
            "timed out waiting for {what}"
        );
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

/// Decodes the `Diagnostics` details of an INVALID_ARGUMENT status.
pub fn diagnostics(s: &tonic::Status) -> Vec<pb::Diagnostic> {
    use prost::Message;
    pb::Diagnostics::decode(s.details()).unwrap().items
}

/// A status stream at 50 Hz.
pub async fn status_stream(
    m: &mut pb::machine_client::MachineClient<Channel>,
) -> tonic::Streaming<pb::Status> {
    m.stream_status(pb::StatusRequest { rate_hz: 50 })
        .await
        .unwrap()
        .into_inner()
}

/// The first status of a fresh status stream (the state now).
pub async fn status_now(m: &mut pb::machine_client::MachineClient<Channel>) -> pb::Status {
    status_stream(m).await.message().await.unwrap().unwrap()
}

/// How far the lagging axis of [`LaggingBus`] reads behind its setpoint, mm.
pub const LAG_MM: f64 = 0.05;

/// The simulated machine whose axis `axis` always reads [`LAG_MM`] behind: a following error
/// that never settles, to see which G24 window a job runs with.
pub struct LaggingBus {
    inner: sim::SimBus,
    axis: usize,
}

impl LaggingBus {
    /// `axes` simulated drives at 0, axis `axis` lagging.
    pub fn new(axes: usize, axis: usize) -> LaggingBus {
        let inner = sim::SimBus::new(sim::SimDriveParams::default(), &vec![0.0; axes]);
        LaggingBus { inner, axis }
    }
}

impl DriveBus for LaggingBus {
    daemon::delegate_drive_bus!(inner: name, axes, enable, reset);
    fn cycle(&mut self, cmd: &CycleCommand, fb: &mut CycleFeedback) -> Result<(), BusFault> {
        let r = self.inner.cycle(cmd, fb);
        fb.axes[self.axis].position_mm -= LAG_MM;
        r
    }
}

/// A daemon on [`LaggingBus`] (axis `axis` of `cfg` lagging) served on its Unix socket (local
/// trust: `cfg.api.local_role`): the controller and a channel to it, the machine idle.
pub async fn lagging_daemon(cfg: Config, axis: usize) -> (Arc<Controller>, Channel) {
    let bus = LaggingBus::new(cfg.axes.len(), axis);
    let ctl = Controller::start_with_bus(cfg, ClockKind::Monotonic, Box::new(bus)).unwrap();
    let ch = serve_unix_channel(&ctl).await;
    wait_state(&ctl, MachineState::Idle).await;
    (ctl, ch)
}

/// Serves the API of `ctl` on its Unix socket ([`tests::serve_unix`]: local trust) and connects
/// a channel to it.
pub async fn serve_unix_channel(ctl: &Arc<Controller>) -> Channel {
    let socket = tests::serve_unix(ctl).await;
    tonic::transport::Endpoint::from_shared(socket)
        .unwrap()
        .connect()
        .await
        .unwrap()
}

/// The request of `LoadProgram` and `UploadProgram`: `text` stored as `name`.
pub fn named_program(name: &str, text: &str) -> pb::LoadProgramRequest {
    pb::LoadProgramRequest {
        name: name.into(),
        text: text.into(),
        dialect: String::new(),
    }
}

/// The request of `SetConstants`: each `(number, value)`, as `cncctl constants set` sends it.
pub fn constant_values(values: &[(u32, f64)]) -> pb::SetConstantsRequest {
    pb::SetConstantsRequest {
        values: values
            .iter()
            .map(|&(number, value)| pb::ConstantValue { number, value })
            .collect(),
    }
}

/// `Start` of the selected program: its job number.
pub async fn start_job(m: &mut MachineClient<Channel>) -> u32 {
    m.start(pb::StartRequest::default())
        .await
        .unwrap()
        .into_inner()
        .job
}

/// `LoadProgram` of `text` as `name`, then `Start`: the job number.
pub async fn load_and_start(m: &mut MachineClient<Channel>, name: &str, text: &str) -> u32 {
    m.load_program(named_program(name, text)).await.unwrap();
    start_job(m).await
}

/// `ValidateProgram` of `text`.
pub async fn validate(m: &mut MachineClient<Channel>, text: &str) -> pb::ValidateProgramReply {
    m.validate_program(pb::ValidateProgramRequest {
        text: text.into(),
        dialect: String::new(),
    })
    .await
    .unwrap()
    .into_inner()
}

/// `ListPrograms`: the library and the selected program.
pub async fn list_programs(m: &mut MachineClient<Channel>) -> pb::ListProgramsReply {
    m.list_programs(pb::ListProgramsRequest {})
        .await
        .unwrap()
        .into_inner()
}

/// `GetPreviewData` of `text` (empty: the selected program), with or without junctions.
pub async fn preview_data(
    p: &mut PreviewClient<Channel>,
    text: &str,
    junctions: bool,
) -> Result<pb::PreviewData, tonic::Status> {
    p.get_preview_data(pb::PreviewDataRequest {
        text: text.into(),
        junctions,
        from_block: None,
        dialect: String::new(),
    })
    .await
    .map(tonic::Response::into_inner)
}

/// The service names server reflection lists, in the reflection protocol version `$v` of
/// `tonic_reflection::pb` (`v1` or `v1alpha`), over channel `$ch`.
#[macro_export]
macro_rules! reflected_services {
    ($v:ident, $ch:expr) => {{
        use tonic_reflection::pb::$v::ServerReflectionRequest;
        use tonic_reflection::pb::$v::server_reflection_client::ServerReflectionClient;
        use tonic_reflection::pb::$v::server_reflection_request::MessageRequest;
        use tonic_reflection::pb::$v::server_reflection_response::MessageResponse;
        let req = ServerReflectionRequest {
            host: String::new(),
            message_request: Some(MessageRequest::ListServices(String::new())),
        };
        let mut resp = ServerReflectionClient::new($ch)
            .server_reflection_info(tokio_stream::iter(vec![req]))
            .await
            .unwrap()
            .into_inner();
        let m = resp.message().await.unwrap().unwrap();
        let Some(MessageResponse::ListServicesResponse(l)) = m.message_response else {
            panic!("unexpected reflection answer");
        };
        l.service
            .into_iter()
            .map(|s| s.name)
            .collect::<Vec<String>>()
    }};
}

/// Job `job` waits with G24 at the end of N10 for ever: at rest with axis `axis` at `at_mm`,
/// and still there 250 ticks (1 s of machine time) later, running. Then stops it.
pub async fn assert_g24_waits_at_the_end_of_n10(
    ctl: &Arc<Controller>,
    m: &mut MachineClient<Channel>,
    job: u32,
    axis: usize,
    at_mm: f64,
) {
    let c = ctl.clone();
    wait_until("at the end of N10", || {
        let s = c.snapshot();
        s.progress.job == job
            && (s.axes.commanded[axis] - at_mm).abs() < 1e-9
            && s.axes.path_v_mm_s == 0.0
    })
    .await;
    let t0 = ctl.snapshot().tick.sequence;
    let c = ctl.clone();
    wait_until("250 ticks", || c.snapshot().tick.sequence > t0 + 250).await;
    let s = ctl.snapshot();
    assert_eq!(s.progress.block_n, Some(10), "{s:?}");
    assert_eq!(s.state, MachineState::Running);
    assert!((s.axes.commanded[axis] - at_mm).abs() < 1e-9);
    m.stop(pb::StopRequest {}).await.unwrap();
    wait_state(ctl, MachineState::Idle).await;
}

/// The request of `Mdi`: one block.
pub fn mdi_block(block: &str) -> pb::MdiRequest {
    pb::MdiRequest {
        block: block.into(),
        dialect: String::new(),
    }
}

/// `Mdi` of `block`: its job number (panics with the block when it is refused).
pub async fn start_mdi(m: &mut MachineClient<Channel>, block: &str) -> u32 {
    m.mdi(mdi_block(block))
        .await
        .unwrap_or_else(|e| panic!("{block}: {e:?}"))
        .into_inner()
        .job
}
