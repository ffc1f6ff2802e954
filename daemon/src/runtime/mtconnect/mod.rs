//! The MTConnect agent served by cncd (docs/mtconnect.md): an HTTP listener of its own
//! (`[mtconnect]`, by default 127.0.0.1:5000), fed from the controller's status snapshots by a
//! tokio task. Read-only: no request changes anything on the machine, and nothing here touches
//! the RT thread.

pub mod feed;
pub mod http;

use std::future::Future;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use hyper_util::rt::TokioIo;
use tokio::net::TcpListener;
use tokio_rustls::TlsAcceptor;
use tokio_rustls::rustls;
use tokio_rustls::rustls::pki_types::pem::PemObject;
use tokio_rustls::rustls::pki_types::{CertificateDer, PrivateKeyDer};

pub use super::config::MtconnectConfig;

use super::controller::Controller;
use feed::Shared;

/// Why the agent could not be served (each message names the configuration key concerned).
#[derive(Debug, thiserror::Error)]
pub enum MtconnectError {
    #[error("mtconnect.listen: cannot listen on {addr}: {source}")]
    Listen {
        addr: std::net::SocketAddr,
        #[source]
        source: std::io::Error,
    },
    #[error(
        "mtconnect.listen: {0} is not a loopback address: serving beyond the machine needs TLS (api.tls_cert and api.tls_key)"
    )]
    TlsRequired(std::net::SocketAddr),
    #[error("{key}: {}: {reason}", path.display())]
    Tls {
        key: &'static str,
        path: std::path::PathBuf,
        reason: String,
    },
    #[error(transparent)]
    Config(#[from] super::config::InvalidConfig),
}

impl MtconnectError {
    /// Stable code (tests and logs match it; the message may improve).
    pub fn code(&self) -> &'static str {
        match self {
            MtconnectError::Listen { .. } => "mtconnect_listen",
            MtconnectError::TlsRequired(_) => "mtconnect_tls_required",
            MtconnectError::Tls { .. } => "mtconnect_tls",
            MtconnectError::Config(e) => e.code(),
        }
    }
}

/// The TLS acceptor of a non-loopback listener: the API's certificate and key.
pub fn tls_acceptor(cert: &Path, key: &Path) -> Result<TlsAcceptor, MtconnectError> {
    let err = |key: &'static str, path: &Path, reason: String| MtconnectError::Tls {
        key,
        path: path.to_path_buf(),
        reason,
    };
    let certs: Vec<CertificateDer<'static>> = CertificateDer::pem_file_iter(cert)
        .and_then(|i| i.collect::<Result<_, _>>())
        .map_err(|e| err("api.tls_cert", cert, e.to_string()))?;
    let pk =
        PrivateKeyDer::from_pem_file(key).map_err(|e| err("api.tls_key", key, e.to_string()))?;
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let cfg = rustls::ServerConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .and_then(|b| b.with_no_client_auth().with_single_cert(certs, pk))
        .map_err(|e| err("api.tls_cert", cert, e.to_string()))?;
    Ok(TlsAcceptor::from(Arc::new(cfg)))
}

/// The TLS acceptor `listen` needs under the configuration: none on loopback.
pub fn tls_for(
    ctl: &Controller,
    listen: std::net::SocketAddr,
) -> Result<Option<TlsAcceptor>, MtconnectError> {
    if listen.ip().is_loopback() {
        return Ok(None);
    }
    let api = &ctl.config().api;
    match (&api.tls_cert, &api.tls_key) {
        (Some(c), Some(k)) => tls_acceptor(c, k).map(Some),
        _ => Err(MtconnectError::TlsRequired(listen)),
    }
}

/// Binds `cfg.listen` (what `cncd` calls).
pub async fn bind(cfg: &MtconnectConfig) -> Result<TcpListener, MtconnectError> {
    TcpListener::bind(cfg.listen)
        .await
        .map_err(|source| MtconnectError::Listen {
            addr: cfg.listen,
            source,
        })
}

/// Serves the agent on `listener` until `shutdown` resolves (`tls`: for a non-loopback
/// listener, see [`tls_for`]).
pub async fn serve(
    ctl: Arc<Controller>,
    cfg: MtconnectConfig,
    listener: TcpListener,
    tls: Option<TlsAcceptor>,
    shutdown: impl Future<Output = ()> + Send,
) -> Result<(), MtconnectError> {
    cfg.validate(tls.is_some())?;
    let shared = Arc::new(Shared::new(&ctl, &cfg));
    let period = Duration::from_millis(cfg.sample_period_ms);
    let feed = tokio::spawn(feed::run(ctl.clone(), shared.clone(), period));
    let mut conns = tokio::task::JoinSet::new();
    tokio::pin!(shutdown);
    loop {
        tokio::select! {
            _ = &mut shutdown => break,
            Some(_) = conns.join_next(), if !conns.is_empty() => {}
            r = listener.accept() => {
                let Ok((sock, _)) = r else {
                    // Out of descriptors (EMFILE): the listener stays readable, so pause
                    // rather than spin until connections end.
                    tokio::time::sleep(Duration::from_millis(50)).await;
                    continue;
                };
                let _ = sock.set_nodelay(true);
                conns.spawn(connection(shared.clone(), sock, tls.clone()));
            }
        }
    }
    // Streams end with their current part; idle keep-alive connections are closed.
    shared.closing.send_replace(true);
    let _ = tokio::time::timeout(super::server::SHUTDOWN_DRAIN, feed).await;
    conns.shutdown().await;
    Ok(())
}

/// How long a client has to send a request's head (and, on the idle keep-alive connection,
/// to begin the next one) before the agent closes the connection: the HMI's listener has the
/// same (tonic's, hyper's default).
const HEADER_READ: Duration = Duration::from_secs(30);

async fn connection(shared: Arc<Shared>, sock: tokio::net::TcpStream, tls: Option<TlsAcceptor>) {
    let svc = hyper::service::service_fn(move |req| http::handle(shared.clone(), req));
    let mut b = hyper::server::conn::http1::Builder::new();
    // hyper enforces the header read timeout only with a timer: without one, a client that
    // sends half a request and waits holds its socket and buffers for ever, and a few thousand
    // of them exhaust the daemon's file descriptors (benches/flood.rs).
    b.timer(hyper_util::rt::TokioTimer::new())
        .header_read_timeout(HEADER_READ);
    let r = match tls {
        None => b.serve_connection(TokioIo::new(sock), svc).await,
        // The handshake is bounded the same way (a client that never sends its hello).
        Some(t) => match tokio::time::timeout(HEADER_READ, t.accept(sock)).await {
            Ok(Ok(s)) => b.serve_connection(TokioIo::new(s), svc).await,
            Ok(Err(e)) => {
                tracing::debug!("MTConnect: TLS handshake failed: {e}");
                return;
            }
            Err(_) => {
                tracing::debug!("MTConnect: TLS handshake not finished in time");
                return;
            }
        },
    };
    if let Err(e) = r {
        tracing::debug!("MTConnect: connection ended: {e}");
    }
}

/// What `cncd` runs: the agent of `cfg` (when enabled) until `shutdown`. The agent only
/// watches: when its address cannot be bound or its TLS files are unusable the error is
/// logged with its code and the machine runs on without it.
pub async fn run_configured(
    ctl: Arc<Controller>,
    cfg: MtconnectConfig,
    shutdown: impl Future<Output = ()> + Send,
) {
    if !cfg.enabled {
        return;
    }
    let started = async {
        let tls = tls_for(&ctl, cfg.listen)?;
        let listener = bind(&cfg).await?;
        let scheme = if tls.is_some() { "https" } else { "http" };
        tracing::info!(
            "MTConnect agent on {scheme}://{}/ (device {})",
            cfg.listen,
            cfg.device_name
        );
        Ok::<_, MtconnectError>((listener, tls))
    };
    match started.await {
        Ok((listener, tls)) => {
            if let Err(e) = serve(ctl, cfg, listener, tls, shutdown).await {
                tracing::error!(code = e.code(), "MTConnect agent: {e}");
            }
        }
        Err(e) => tracing::error!(code = e.code(), "MTConnect agent not served: {e}"),
    }
}
