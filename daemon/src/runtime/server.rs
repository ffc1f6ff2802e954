//! Serving the API: used by `cncd` and by the in-process integration tests.
//!
//! Listeners (docs/api.md):
//! - the Unix socket `api.unix_socket` (mode `api.socket_mode`, group `api.socket_group`):
//!   callers without a token get `api.local_role` (default admin: the socket's permissions are
//!   the gate);
//! - loopback TCP addresses: callers without a token get `api.loopback_role` (default
//!   observer, since every local account can connect);
//! - any other TCP address is **remote**: TLS (`api.tls_cert`, `api.tls_key`) and a bearer
//!   token are required.
//!
//! Every listener serves the same services: `cnc.v1.Machine`, `Offsets`, `Plc`, `Constants`,
//! `Preview`, `Trajectory`, `grpc.health.v1.Health` (NOT_SERVING while the machine is faulted)
//! and server reflection (`grpc.reflection.v1` and `grpc.reflection.v1alpha`).

use std::future::Future;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use proto::v1::constants_server::ConstantsServer;
use proto::v1::machine_server::MachineServer;
use proto::v1::offsets_server::OffsetsServer;
use proto::v1::plc_server::PlcServer;
use proto::v1::preview_server::PreviewServer;
use proto::v1::programs_server::ProgramsServer;
use proto::v1::trajectory_server::TrajectoryServer;
use tokio::net::{TcpListener, UnixListener};
use tokio_stream::wrappers::UnixListenerStream;
use tonic::service::Routes;
use tonic::service::interceptor::InterceptedService;
use tonic::transport::server::{Router, TcpIncoming};
use tonic::transport::{Identity, Server, ServerTlsConfig};
use tonic_health::ServingStatus;
use tonic_health::server::HealthReporter;

use super::api::auth::{Auth, Trust};
use super::api::{
    ApiState, ConstantsSvc, MachineSvc, OffsetsSvc, PlcSvc, PreviewSvc, ProgramsSvc, TrajectorySvc,
};
use super::config::{ApiConfig, Config, Role};
use super::controller::Controller;
use super::hmi::Assets;
use super::rt::MachineState;

/// How long the API waits at shutdown for calls in flight (open streams end at once): the
/// daemon exits within a second after the axes are at rest (issue #19), well inside the unit's
/// `TimeoutStopSec=`.
pub const SHUTDOWN_DRAIN: Duration = Duration::from_millis(500);

/// Why the API could not be served (each message names the configuration key concerned).
#[derive(Debug, thiserror::Error)]
pub enum ServerError {
    /// A TCP address could not be bound (`key` is `api.listen`, `api.extra_listen` or
    /// `hmi.listen`).
    #[error("{key}: cannot listen on {addr}: {source}")]
    Listen {
        key: &'static str,
        addr: std::net::SocketAddr,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot read the listener's address: {0}")]
    LocalAddr(#[source] std::io::Error),
    #[error("api.unix_socket: {}: {source}", path.display())]
    UnixSocket {
        path: std::path::PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("api.unix_socket: {}: exists and is not a socket", path.display())]
    NotASocket { path: std::path::PathBuf },
    #[error("api.socket_group: no group named {0:?}")]
    NoGroup(String),
    /// `key` is `api.tls_cert`, `api.tls_key`, `hmi.tls_cert` or `hmi.tls_key`.
    #[error("{key}: {}: {source}", path.display())]
    TlsFile {
        key: &'static str,
        path: std::path::PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("api.tls_cert/api.tls_key: {0}")]
    Tls(String),
    #[error("a non-loopback listener needs api.tls_cert and api.tls_key")]
    TlsRequired,
    #[error(
        "a non-loopback hmi.listen needs TLS: hmi.tls_cert and hmi.tls_key (or api.tls_cert and \
         api.tls_key)"
    )]
    HmiTlsRequired,
    #[error("reflection: {0}")]
    Reflection(String),
    /// A listener failed while serving.
    #[error("{0}")]
    Serve(String),
    /// The program library could not be opened (`storage.programs_dir`).
    #[error(transparent)]
    Library(#[from] super::api::ApiStateError),
}

impl ServerError {
    /// Stable code (tests and logs match it; the message may improve).
    pub fn code(&self) -> &'static str {
        match self {
            ServerError::Listen { .. } => "api_listen",
            ServerError::LocalAddr(_) => "api_local_addr",
            ServerError::UnixSocket { .. } => "api_unix_socket",
            ServerError::NotASocket { .. } => "api_not_a_socket",
            ServerError::NoGroup(_) => "api_no_group",
            ServerError::TlsFile { .. } => "api_tls_file",
            ServerError::Tls(_) => "api_tls",
            ServerError::TlsRequired => "api_tls_required",
            ServerError::HmiTlsRequired => "hmi_tls_required",
            ServerError::Reflection(_) => "api_reflection",
            ServerError::Serve(_) => "api_serve",
            ServerError::Library(e) => e.code(),
        }
    }
}

/// Sockets to serve on, already bound.
#[derive(Default)]
pub struct Listeners {
    /// Loopback TCP: local trust.
    pub local_tcp: Vec<TcpListener>,
    /// Other TCP addresses: TLS (when configured) and a token required.
    pub remote_tcp: Vec<TcpListener>,
    /// The Unix socket: local trust.
    pub unix: Option<UnixListener>,
}

/// Serves the API on one loopback `listener` (local trust) until `shutdown` resolves.
pub async fn serve(
    ctl: Arc<Controller>,
    listener: TcpListener,
    shutdown: impl Future<Output = ()> + Send,
) -> Result<(), ServerError> {
    let l = Listeners {
        local_tcp: vec![listener],
        ..Listeners::default()
    };
    serve_listeners(ctl, l, shutdown).await
}

/// What `cncd` calls: serves `listener` (bound to `api.listen`) and binds and serves every
/// other listener of the configuration (`api.extra_listen`, `api.unix_socket`).
pub async fn serve_all(
    ctl: Arc<Controller>,
    listener: TcpListener,
    shutdown: impl Future<Output = ()> + Send,
) -> Result<(), ServerError> {
    let api = ctl.config().api.clone();
    let mut l = bind_extra(&api, &ctl.config().storage.dir).await?;
    let addr = listener.local_addr().map_err(ServerError::LocalAddr)?;
    if addr.ip().is_loopback() {
        l.local_tcp.insert(0, listener);
    } else {
        l.remote_tcp.insert(0, listener);
    }
    let r = serve_listeners(ctl, l, shutdown).await;
    if let Err(e) = &r {
        tracing::error!("API: {e}");
    }
    r
}

/// Binds `api.extra_listen` and the Unix socket.
pub async fn bind_extra(api: &ApiConfig, storage_dir: &Path) -> Result<Listeners, ServerError> {
    let mut l = Listeners::default();
    for a in &api.extra_listen {
        let t = TcpListener::bind(a)
            .await
            .map_err(|source| ServerError::Listen {
                key: "api.extra_listen",
                addr: *a,
                source,
            })?;
        if a.ip().is_loopback() {
            l.local_tcp.push(t);
        } else {
            l.remote_tcp.push(t);
        }
    }
    if let Some(path) = api.unix_socket_path(storage_dir) {
        l.unix = Some(bind_unix(
            &path,
            api.socket_mode,
            api.socket_group.as_deref(),
        )?);
    }
    Ok(l)
}

/// Binds the Unix socket: a stale socket file is replaced; mode and group are set before the
/// first connection can be accepted.
pub fn bind_unix(path: &Path, mode: u32, group: Option<&str>) -> Result<UnixListener, ServerError> {
    use std::os::unix::fs::{FileTypeExt, PermissionsExt};
    let err = |source| ServerError::UnixSocket {
        path: path.to_path_buf(),
        source,
    };
    if let Ok(m) = std::fs::symlink_metadata(path) {
        if m.file_type().is_socket() {
            std::fs::remove_file(path).map_err(err)?;
        } else {
            return Err(ServerError::NotASocket {
                path: path.to_path_buf(),
            });
        }
    }
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(err)?;
    }
    let l = UnixListener::bind(path).map_err(err)?;
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(mode)).map_err(err)?;
    if let Some(g) = group {
        let gid = group_id(g).ok_or_else(|| ServerError::NoGroup(g.to_string()))?;
        std::os::unix::fs::chown(path, None, Some(gid)).map_err(err)?;
    }
    Ok(l)
}

fn group_id(name: &str) -> Option<u32> {
    let c = std::ffi::CString::new(name).ok()?;
    // SAFETY: getgrnam with a valid C string; the result is read at once (start-up, one thread).
    let g = unsafe { libc::getgrnam(c.as_ptr()) };
    if g.is_null() {
        None
    } else {
        // SAFETY: non-null pointer returned by getgrnam.
        Some(unsafe { (*g).gr_gid })
    }
}

/// TLS settings of remote listeners, when configured.
pub fn tls_config(api: &ApiConfig) -> Result<Option<ServerTlsConfig>, ServerError> {
    match (&api.tls_cert, &api.tls_key) {
        (Some(c), Some(k)) => tls_from_files(("api.tls_cert", c), ("api.tls_key", k)).map(Some),
        _ => Ok(None),
    }
}

/// TLS settings from a PEM certificate and key file, each with the configuration key it
/// came from (named when it cannot be read).
pub fn tls_from_files(
    cert: (&'static str, &Path),
    key: (&'static str, &Path),
) -> Result<ServerTlsConfig, ServerError> {
    let read = |(key, path): (&'static str, &Path)| {
        std::fs::read(path).map_err(|source| ServerError::TlsFile {
            key,
            path: path.to_path_buf(),
            source,
        })
    };
    let (cert, key) = (read(cert)?, read(key)?);
    Ok(ServerTlsConfig::new().identity(Identity::from_pem(cert, key)))
}

/// TLS of the HMI's listener: on a non-loopback `hmi.listen` the HMI's files, else the
/// API's; on loopback only when the HMI's own are set (a loopback screen stays plain HTTP
/// when only the API has a certificate).
pub fn hmi_tls_config(cfg: &Config) -> Result<Option<ServerTlsConfig>, ServerError> {
    let hmi = &cfg.hmi;
    if hmi.listen.ip().is_loopback() && hmi.tls_cert.is_none() {
        return Ok(None);
    }
    hmi.tls_files(&cfg.api)
        .map(|f| tls_from_files(f.cert, f.key))
        .transpose()
}

/// Reads and parses the TLS certificate and key when configured (`--check-config` and
/// start-up): a missing or unreadable file, or PEM without a certificate or key, is refused
/// with the key's name.
pub fn check_tls(api: &ApiConfig) -> Result<(), ServerError> {
    if let Some(t) = tls_config(api)? {
        Server::builder()
            .tls_config(t)
            .map_err(|e| ServerError::Tls(e.to_string()))?;
    }
    Ok(())
}

/// As [`check_tls`] for the HMI's listener when it is enabled.
pub fn check_hmi_tls(cfg: &Config) -> Result<(), ServerError> {
    if !cfg.hmi.enabled {
        return Ok(());
    }
    if let Some(t) = hmi_tls_config(cfg)? {
        Server::builder()
            .tls_config(t)
            .map_err(|e| ServerError::Tls(e.to_string()))?;
    }
    Ok(())
}

/// Largest unary request message, bytes (the gRPC default, stated). Programs of any size go
/// through the client-streaming `Programs.Upload` in chunks below this.
pub const MAX_MESSAGE_BYTES: usize = 4 << 20;

/// tonic refuses an oversized message with OUT_OF_RANGE and a transport-level text; clients
/// get RESOURCE_EXHAUSTED with the limit and what to use instead.
pub fn size_refusal<B>(mut r: http::Response<B>) -> http::Response<B> {
    let h = r.headers_mut();
    let too_large = h.get("grpc-status").is_some_and(|v| v == "11")
        && h.get("grpc-message").is_some_and(|m| {
            String::from_utf8_lossy(m.as_bytes())
                .replace("%20", " ")
                .contains("message length too large")
        });
    if too_large {
        let msg = format!(
            "the request is larger than {} MiB, the limit of one message (docs/api.md): upload \
             programs with Programs.Upload (cncctl load/upload/run do)",
            MAX_MESSAGE_BYTES >> 20
        );
        h.insert("grpc-status", http::HeaderValue::from_static("8"));
        if let Ok(v) = http::HeaderValue::from_str(&msg.replace('%', "%25")) {
            h.insert("grpc-message", v);
        }
    }
    r
}

type SizeLayer = tower::util::MapResponseLayer<
    fn(http::Response<tonic::body::Body>) -> http::Response<tonic::body::Body>,
>;
type ApiRouter = Router<tower::layer::util::Stack<SizeLayer, tower::layer::util::Identity>>;

type Health<H> = tonic_health::pb::health_server::HealthServer<H>;

fn router<H: tonic_health::pb::health_server::Health>(
    st: &Arc<ApiState>,
    auth: &Arc<Auth>,
    trust: Trust,
    tls: Option<ServerTlsConfig>,
    health: &Health<H>,
) -> Result<ApiRouter, ServerError> {
    let mut b = Server::builder();
    if let Some(t) = tls {
        b = b
            .tls_config(t)
            .map_err(|e| ServerError::Tls(e.to_string()))?;
    }
    let layer: SizeLayer = tower::util::MapResponseLayer::new(size_refusal);
    Ok(b.layer(layer).add_routes(routes(st, auth, trust, health)?))
}

/// Every service of the API behind the interceptor of a listener of kind `trust`.
fn routes<H: tonic_health::pb::health_server::Health>(
    st: &Arc<ApiState>,
    auth: &Arc<Auth>,
    trust: Trust,
    health: &Health<H>,
) -> Result<Routes, ServerError> {
    let i = auth.interceptor(trust);
    // Both reflection versions: grpcurl speaks v1, Python's grpcio-reflection and many older
    // tools only v1alpha.
    let reflection_builder = || {
        tonic_reflection::server::Builder::configure()
            .register_encoded_file_descriptor_set(proto::FILE_DESCRIPTOR_SET)
            .register_encoded_file_descriptor_set(tonic_health::pb::FILE_DESCRIPTOR_SET)
            .register_encoded_file_descriptor_set(tonic_reflection::pb::v1::FILE_DESCRIPTOR_SET)
            .register_encoded_file_descriptor_set(
                tonic_reflection::pb::v1alpha::FILE_DESCRIPTOR_SET,
            )
    };
    let reflection = reflection_builder()
        .build_v1()
        .map_err(|e| ServerError::Reflection(e.to_string()))?;
    let reflection_alpha = reflection_builder()
        .build_v1alpha()
        .map_err(|e| ServerError::Reflection(e.to_string()))?;
    let m = MAX_MESSAGE_BYTES;
    let mut rb = Routes::builder();
    rb.add_service(InterceptedService::new(
        MachineServer::new(MachineSvc(st.clone())).max_decoding_message_size(m),
        i.clone(),
    ))
    .add_service(InterceptedService::new(
        OffsetsServer::new(OffsetsSvc(st.clone())).max_decoding_message_size(m),
        i.clone(),
    ))
    .add_service(InterceptedService::new(
        PlcServer::new(PlcSvc(st.clone())).max_decoding_message_size(m),
        i.clone(),
    ))
    .add_service(InterceptedService::new(
        ConstantsServer::new(ConstantsSvc(st.clone())).max_decoding_message_size(m),
        i.clone(),
    ))
    .add_service(InterceptedService::new(
        PreviewServer::new(PreviewSvc(st.clone())).max_decoding_message_size(m),
        i.clone(),
    ))
    .add_service(InterceptedService::new(
        TrajectoryServer::new(TrajectorySvc(st.clone())).max_decoding_message_size(m),
        i.clone(),
    ))
    .add_service(InterceptedService::new(
        ProgramsServer::new(ProgramsSvc(st.clone())).max_decoding_message_size(m),
        i.clone(),
    ))
    .add_service(InterceptedService::new(health.clone(), i.clone()))
    .add_service(InterceptedService::new(reflection, i.clone()))
    .add_service(InterceptedService::new(reflection_alpha, i));
    Ok(rb.routes())
}

/// Serves every listener until `shutdown` resolves. Remote listeners use TLS from the
/// configuration; without it they are refused (the configuration check requires it).
pub async fn serve_listeners(
    ctl: Arc<Controller>,
    listeners: Listeners,
    shutdown: impl Future<Output = ()> + Send,
) -> Result<(), ServerError> {
    let tls = tls_config(&ctl.config().api)?;
    serve_listeners_with(ctl, listeners, tls, shutdown).await
}

/// What `cncd` serves: `listeners` with the API's TLS, and when `[hmi]` is enabled its
/// listener `hmi` (already bound to `hmi.listen`) with the files embedded in this binary.
pub async fn serve_with_configured_hmi(
    ctl: Arc<Controller>,
    listeners: Listeners,
    hmi: Option<TcpListener>,
    shutdown: impl Future<Output = ()> + Send,
) -> Result<(), ServerError> {
    let tls = tls_config(&ctl.config().api)?;
    let hmi = match hmi {
        Some(listener) => Some(HmiListener {
            listener,
            assets: Arc::new(Assets::embedded()),
            tls: hmi_tls_config(ctl.config())?,
        }),
        None => None,
    };
    serve_with_hmi(ctl, listeners, tls, hmi, shutdown).await
}

/// As [`serve_listeners`] with explicit TLS settings for the remote listeners (tests).
pub async fn serve_listeners_with(
    ctl: Arc<Controller>,
    listeners: Listeners,
    tls: Option<ServerTlsConfig>,
    shutdown: impl Future<Output = ()> + Send,
) -> Result<(), ServerError> {
    serve_with_hmi(ctl, listeners, tls, None, shutdown).await
}

/// The browser HMI's listener (`[hmi] listen`, docs/hmi.md): its static files and every
/// service over grpc-web on one origin.
pub struct HmiListener {
    pub listener: TcpListener,
    pub assets: Arc<Assets>,
    /// Required unless the address is loopback.
    pub tls: Option<ServerTlsConfig>,
}

/// As [`serve_listeners_with`], and the HMI's listener when given; every listener shares one
/// API state (stream limits, upload sessions, alarm history).
pub async fn serve_with_hmi(
    ctl: Arc<Controller>,
    listeners: Listeners,
    tls: Option<ServerTlsConfig>,
    hmi: Option<HmiListener>,
    shutdown: impl Future<Output = ()> + Send,
) -> Result<(), ServerError> {
    if !listeners.remote_tcp.is_empty() && tls.is_none() {
        return Err(ServerError::TlsRequired);
    }
    let hmi_trust = match &hmi {
        Some(h) => Some(hmi_trust(h)?),
        None => None,
    };
    let api = &ctl.config().api;
    if !listeners.local_tcp.is_empty() && api.loopback_role > Role::Observer {
        tracing::warn!(
            role = api.loopback_role.name(),
            "api.loopback_role: every local account can connect to loopback TCP and gets this \
             role without a token"
        );
    }
    let st = ApiState::new(ctl.clone()).map_err(ServerError::Library)?;
    let auth = Auth::from_config(api);
    let (reporter, health) = tonic_health::server::health_reporter();
    let health_task = tokio::spawn(health_watch(ctl.clone(), reporter));
    let (stop_tx, stop_rx) = tokio::sync::watch::channel(false);
    let stopped = move || {
        let mut rx = stop_rx.clone();
        async move {
            let _ = rx.wait_for(|v| *v).await;
        }
    };
    let mut tasks = tokio::task::JoinSet::new();
    for l in listeners.local_tcp {
        let r = router(&st, &auth, Trust::Loopback, None, &health)?;
        let inc = TcpIncoming::from(l).with_nodelay(Some(true));
        tasks.spawn(r.serve_with_incoming_shutdown(inc, stopped()));
    }
    for l in listeners.remote_tcp {
        let r = router(&st, &auth, Trust::Remote, tls.clone(), &health)?;
        let inc = TcpIncoming::from(l).with_nodelay(Some(true));
        tasks.spawn(r.serve_with_incoming_shutdown(inc, stopped()));
    }
    if let (Some(h), Some(trust)) = (hmi, hmi_trust) {
        let app = crate::runtime::hmi::app(
            routes(&st, &auth, trust, &health)?,
            tower::util::MapResponseLayer::new(size_refusal::<axum::body::Body>),
            h.assets,
        );
        let mut b = Server::builder().accept_http1(true);
        if let Some(t) = h.tls {
            b = b
                .tls_config(t)
                .map_err(|e| ServerError::Tls(e.to_string()))?;
        }
        let inc = TcpIncoming::from(h.listener).with_nodelay(Some(true));
        tasks.spawn(
            b.add_routes(app)
                .serve_with_incoming_shutdown(inc, stopped()),
        );
    }
    if let Some(u) = listeners.unix {
        let r = router(&st, &auth, Trust::Socket, None, &health)?;
        tasks.spawn(r.serve_with_incoming_shutdown(UnixListenerStream::new(u), stopped()));
    }
    let mut first_err = None;
    tokio::select! {
        _ = shutdown => {}
        Some(r) = tasks.join_next() => {
            if let Ok(Err(e)) = r { first_err = Some(e.to_string()); }
        }
    }
    // Streams end first (their last message is sent), then the listeners stop accepting and
    // wait for the calls in flight; a client that does not read its stream any more must not
    // hold the daemon past the drain time.
    st.close_streams();
    let _ = stop_tx.send(true);
    let drain = async {
        while let Some(r) = tasks.join_next().await {
            if let Ok(Err(e)) = r {
                first_err.get_or_insert(e.to_string());
            }
        }
    };
    if tokio::time::timeout(SHUTDOWN_DRAIN, drain).await.is_err() {
        tracing::warn!(
            drain_ms = SHUTDOWN_DRAIN.as_millis() as u64,
            "API calls still open after the drain time: closing their connections"
        );
        tasks.shutdown().await;
    }
    health_task.abort();
    match first_err {
        Some(e) => Err(ServerError::Serve(e)),
        None => Ok(()),
    }
}

/// Loopback HMI callers are local (`api.loopback_role` without a token); any other address
/// is remote: TLS and a token.
fn hmi_trust(h: &HmiListener) -> Result<Trust, ServerError> {
    let addr = h.listener.local_addr().map_err(ServerError::LocalAddr)?;
    if addr.ip().is_loopback() {
        Ok(Trust::Loopback)
    } else if h.tls.is_some() {
        Ok(Trust::Remote)
    } else {
        Err(ServerError::HmiTlsRequired)
    }
}

/// Keeps `grpc.health.v1` in step with the machine: NOT_SERVING while faulted (or when the
/// real-time thread has ended), SERVING otherwise.
async fn health_watch(ctl: Arc<Controller>, reporter: HealthReporter) {
    let names = [
        "",
        "cnc.v1.Machine",
        "cnc.v1.Offsets",
        "cnc.v1.Plc",
        "cnc.v1.Constants",
        "cnc.v1.Preview",
        "cnc.v1.Trajectory",
        "cnc.v1.Programs",
    ];
    let mut last = None;
    let mut every = tokio::time::interval(Duration::from_millis(20));
    loop {
        every.tick().await;
        let s = ctl.snapshot().state;
        let serving = if matches!(s, MachineState::Fault | MachineState::Shutdown) {
            ServingStatus::NotServing
        } else {
            ServingStatus::Serving
        };
        if last != Some(serving) {
            for n in names {
                reporter.set_service_status(n, serving).await;
            }
            last = Some(serving);
        }
    }
}
