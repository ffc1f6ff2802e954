//! Harness of the HMI tests (issue #30): an in-process daemon on the simulated machine whose
//! HMI listener (loopback, `api.loopback_role` without a token) serves a fixture of static
//! files and every gRPC service over grpc-web. Clients talk to it as a browser does: HTTP/1.1,
//! grpc-web frames (tonic-web's client layer over hyper), no client streaming.
#![allow(dead_code)]

use std::path::PathBuf;
use std::sync::Arc;

use bytes::Bytes;
use daemon::runtime::config::Config;
use daemon::runtime::controller::{ClockKind, Controller};
use daemon::runtime::hmi::Assets;
use daemon::runtime::rt::MachineState;
use daemon::runtime::server::{self, HmiListener, Listeners};
use http_body_util::{BodyExt, Empty};
use hyper_util::client::legacy::Client;
use hyper_util::client::legacy::connect::HttpConnector;
use hyper_util::rt::TokioExecutor;
use proto::v1::machine_client::MachineClient;
use proto::v1::programs_client::ProgramsClient;
use tonic_web::{GrpcWebCall, GrpcWebClientLayer, GrpcWebClientService};

pub use tests::wait_state;

/// A grpc-web channel over HTTP/1.1.
pub type Web = GrpcWebClientService<Client<HttpConnector, GrpcWebCall<tonic::body::Body>>>;

/// The fixture standing in for `hmi/dist/` (the web code is not this suite's business).
pub fn fixture_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/hmi_dist")
}

pub fn fixture() -> Assets {
    Assets::from_dir(&fixture_dir()).expect("the HMI fixture")
}

pub struct Hmi {
    pub ctl: Arc<Controller>,
    /// `http://127.0.0.1:PORT`.
    pub base: String,
}

/// A daemon on the simulated machine serving the fixture HMI on a loopback port.
pub async fn start(cfg: Config) -> Hmi {
    start_with(cfg, fixture()).await
}

/// As [`start`] with `assets` as the HMI's files.
pub async fn start_with(cfg: Config, assets: Assets) -> Hmi {
    let bus = sim::SimBus::new(sim::SimDriveParams::default(), &vec![0.0; cfg.axes.len()]);
    let ctl = Controller::start_with_bus(cfg, ClockKind::Monotonic, Box::new(bus)).unwrap();
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let base = format!("http://{}", listener.local_addr().unwrap());
    let hmi = HmiListener {
        listener,
        assets: Arc::new(assets),
        tls: None,
    };
    tokio::spawn(server::serve_with_hmi(
        ctl.clone(),
        Listeners::default(),
        None,
        Some(hmi),
        std::future::pending(),
    ));
    wait_state(&ctl, MachineState::Idle).await;
    Hmi { ctl, base }
}

/// A grpc-web channel to `base` (HTTP/1.1, as browsers talk to a plain-text port).
pub fn web_channel(base: &str) -> (Web, http::Uri) {
    let client = Client::builder(TokioExecutor::new()).build_http();
    let svc = tower::ServiceBuilder::new()
        .layer(GrpcWebClientLayer::new())
        .service(client);
    (svc, base.parse().unwrap())
}

impl Hmi {
    pub fn machine(&self) -> MachineClient<Web> {
        let (svc, origin) = web_channel(&self.base);
        MachineClient::with_origin(svc, origin)
    }

    pub fn programs(&self) -> ProgramsClient<Web> {
        let (svc, origin) = web_channel(&self.base);
        ProgramsClient::with_origin(svc, origin)
    }

    /// `GET path` with `headers`: status, headers and body.
    pub async fn get(&self, path: &str, headers: &[(&str, &str)]) -> Page {
        get(&format!("{}{path}", self.base), headers).await
    }
}

/// One HTTP answer.
pub struct Page {
    pub status: http::StatusCode,
    pub headers: http::HeaderMap,
    pub body: Bytes,
}

impl Page {
    pub fn header(&self, name: &str) -> &str {
        self.headers
            .get(name)
            .map(|v| v.to_str().unwrap())
            .unwrap_or("")
    }

    pub fn text(&self) -> String {
        String::from_utf8_lossy(&self.body).into_owned()
    }
}

/// `GET url` with `headers` over HTTP/1.1.
pub async fn get(url: &str, headers: &[(&str, &str)]) -> Page {
    let client: Client<HttpConnector, Empty<Bytes>> =
        Client::builder(TokioExecutor::new()).build_http();
    let mut req = http::Request::get(url);
    for (k, v) in headers {
        req = req.header(*k, *v);
    }
    let r = client
        .request(req.body(Empty::new()).unwrap())
        .await
        .unwrap();
    let (parts, body) = r.into_parts();
    Page {
        status: parts.status,
        headers: parts.headers,
        body: body.collect().await.unwrap().to_bytes(),
    }
}
