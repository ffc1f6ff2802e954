//! What the API benches share: their knobs from the environment, the runtime they run on, and
//! the daemon's API served the way `cncd` serves it locally.

pub mod cyclic;

use std::future::Future;
use std::time::{Duration, Instant};

use daemon::runtime::controller::Controller;
use daemon::runtime::rt::MachineState;
use daemon::runtime::server;

/// The number in the environment variable `name` (a bench knob), else `default`.
pub fn env_number<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// Runs `bench` on a multi-threaded tokio runtime with two workers (the target's two cores).
pub fn run<F: Future>(bench: F) -> F::Output {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("tokio runtime");
    rt.block_on(bench)
}

/// Serves the API of `ctl` on its Unix socket, as `cncctl` and the shop's HMI reach cncd
/// (loopback TCP is observer-only), and waits until the drives are enabled (a hang bound of
/// 10 s). Returns the address for tonic, `unix:/path`. (`program_upload` runs the `cncd`
/// binary instead.)
#[allow(dead_code)]
pub async fn serve_unix(ctl: &std::sync::Arc<Controller>) -> String {
    let sock = ctl.config().storage.dir.join("cncd.sock");
    let listeners = server::Listeners {
        unix: Some(server::bind_unix(&sock, 0o600, None).expect("API socket")),
        ..server::Listeners::default()
    };
    tokio::spawn(server::serve_listeners(
        ctl.clone(),
        listeners,
        std::future::pending(),
    ));
    let t0 = Instant::now();
    while ctl.snapshot().state != MachineState::Idle {
        assert!(t0.elapsed() < Duration::from_secs(10), "drives not enabled");
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    format!("unix:{}", sock.display())
}
