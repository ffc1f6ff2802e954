//! The listener tasks of one API: every listener served on its own task over one shared API
//! state, and their stop (streams end first, then the listeners drain the calls in flight).

use std::future::Future;
use std::sync::Arc;

use tokio::net::{TcpListener, UnixListener};
use tokio::sync::watch;
use tokio::task::JoinSet;
use tokio_stream::wrappers::UnixListenerStream;
use tonic::transport::server::TcpIncoming;
use tonic::transport::{Server, ServerTlsConfig};

use super::listeners::HmiListener;
use super::routes::{Health, hmi_routes, router};
use super::{SHUTDOWN_DRAIN, ServerError};
use crate::runtime::api::ApiState;
use crate::runtime::api::auth::{Auth, Trust};

type Served = Result<(), tonic::transport::Error>;

/// The listener tasks sharing one API state, token table and health service.
pub(super) struct Tasks<'a, H> {
    st: &'a Arc<ApiState>,
    auth: &'a Arc<Auth>,
    health: &'a Health<H>,
    /// Set once the listeners are to stop accepting and drain.
    stop: watch::Sender<bool>,
    set: JoinSet<Served>,
}

impl<'a, H: tonic_health::pb::health_server::Health> Tasks<'a, H> {
    pub(super) fn new(st: &'a Arc<ApiState>, auth: &'a Arc<Auth>, health: &'a Health<H>) -> Self {
        Tasks {
            st,
            auth,
            health,
            stop: watch::channel(false).0,
            set: JoinSet::new(),
        }
    }

    /// Resolves once the listeners are told to stop.
    fn stopped(&self) -> impl Future<Output = ()> + Send + 'static {
        let mut rx = self.stop.subscribe();
        async move {
            let _ = rx.wait_for(|v| *v).await;
        }
    }

    /// Serves a TCP listener of kind `trust` (TLS given for remote listeners).
    pub(super) fn spawn_tcp(
        &mut self,
        l: TcpListener,
        trust: Trust,
        tls: Option<ServerTlsConfig>,
    ) -> Result<(), ServerError> {
        let r = router(self.st, self.auth, trust, tls, self.health)?;
        let inc = TcpIncoming::from(l).with_nodelay(Some(true));
        self.set
            .spawn(r.serve_with_incoming_shutdown(inc, self.stopped()));
        Ok(())
    }

    /// Serves the Unix socket (local trust).
    pub(super) fn spawn_unix(&mut self, u: UnixListener) -> Result<(), ServerError> {
        let r = router(self.st, self.auth, Trust::Socket, None, self.health)?;
        let inc = UnixListenerStream::new(u);
        self.set
            .spawn(r.serve_with_incoming_shutdown(inc, self.stopped()));
        Ok(())
    }

    /// Serves the browser HMI: its files and every service over grpc-web (HTTP/1.1 too).
    pub(super) fn spawn_hmi(&mut self, h: HmiListener, trust: Trust) -> Result<(), ServerError> {
        let app = hmi_routes(self.st, self.auth, trust, self.health, h.assets)?;
        let mut b = Server::builder().accept_http1(true);
        if let Some(t) = h.tls {
            b = b
                .tls_config(t)
                .map_err(|e| ServerError::Tls(e.to_string()))?;
        }
        let inc = TcpIncoming::from(h.listener).with_nodelay(Some(true));
        self.set.spawn(
            b.add_routes(app)
                .serve_with_incoming_shutdown(inc, self.stopped()),
        );
        Ok(())
    }

    /// Serves until `shutdown` resolves or a listener fails, then stops every listener;
    /// returns the first listener's failure.
    pub(super) async fn serve_until(
        mut self,
        shutdown: impl Future<Output = ()> + Send,
    ) -> Option<String> {
        let mut first_err = None;
        tokio::select! {
            _ = shutdown => {}
            Some(r) = self.set.join_next() => {
                if let Ok(Err(e)) = r { first_err = Some(e.to_string()); }
            }
        }
        // Streams end first (their last message is sent), then the listeners stop accepting
        // and wait for the calls in flight; a client that does not read its stream any more
        // must not hold the daemon past the drain time.
        self.st.close_streams();
        let _ = self.stop.send(true);
        let drain = async {
            while let Some(r) = self.set.join_next().await {
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
            self.set.shutdown().await;
        }
        first_err
    }
}
