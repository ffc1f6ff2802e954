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

mod health;
mod listeners;
mod routes;
mod tasks;
mod tls;

use std::future::Future;
use std::sync::Arc;
use std::time::Duration;

use tokio::net::TcpListener;
use tonic::transport::ServerTlsConfig;

use super::api::ApiState;
use super::api::auth::{Auth, Trust};
use super::config::{ApiConfig, Role};
use super::controller::Controller;
use super::hmi::Assets;
use health::health_watch;
use listeners::hmi_trust;
use tasks::Tasks;

pub use listeners::{HmiListener, Listeners, Reserved, bind_extra, bind_unix};
pub(crate) use routes::hmi_routes;
pub use routes::{MAX_MESSAGE_BYTES, size_refusal};
pub use tls::{check_hmi_tls, check_tls, hmi_tls_config, tls_config, tls_from_files};

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
    let hmi = match hmi {
        Some(h) => {
            let trust = hmi_trust(&h)?;
            Some((h, trust))
        }
        None => None,
    };
    let api = &ctl.config().api;
    warn_loopback_role(api, &listeners);
    let st = ApiState::new(ctl.clone()).map_err(ServerError::Library)?;
    let auth = Auth::from_config(api);
    let (reporter, health) = tonic_health::server::health_reporter();
    let health_task = tokio::spawn(health_watch(ctl.clone(), reporter));
    let mut tasks = Tasks::new(&st, &auth, &health);
    for l in listeners.local_tcp {
        tasks.spawn_tcp(l, Trust::Loopback, None)?;
    }
    for l in listeners.remote_tcp {
        tasks.spawn_tcp(l, Trust::Remote, tls.clone())?;
    }
    if let Some((h, trust)) = hmi {
        tasks.spawn_hmi(h, trust)?;
    }
    if let Some(u) = listeners.unix {
        tasks.spawn_unix(u)?;
    }
    let first_err = tasks.serve_until(shutdown).await;
    health_task.abort();
    match first_err {
        Some(e) => Err(ServerError::Serve(e)),
        None => Ok(()),
    }
}

/// A loopback role above observer is the operator's choice, but worth a line in the log.
fn warn_loopback_role(api: &ApiConfig, listeners: &Listeners) {
    if !listeners.local_tcp.is_empty() && api.loopback_role > Role::Observer {
        tracing::warn!(
            role = api.loopback_role.name(),
            "api.loopback_role: every local account can connect to loopback TCP and gets this \
             role without a token"
        );
    }
}
