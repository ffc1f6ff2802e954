//! `cncd`: the controller daemon.
//!
//! With no configuration it runs the built-in simulated 3-axis machine and serves the gRPC API
//! on 127.0.0.1:50051.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;
use daemon::runtime::config::Config;
use daemon::runtime::controller::{ClockKind, Controller};
use daemon::runtime::server;

#[derive(Parser)]
#[command(name = "cncd", version, about = "CNC motion controller daemon")]
struct Args {
    /// Configuration file (TOML). Without it: the simulated 3-axis machine.
    #[arg(long, short)]
    config: Option<PathBuf>,
    /// Validate the configuration file and exit.
    #[arg(long)]
    check_config: bool,
}

fn main() -> ExitCode {
    let args = Args::parse();
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_writer(std::io::stderr)
        .init();
    let config = match &args.config {
        Some(p) => match Config::load(p) {
            Ok(c) => c,
            Err(e) => {
                eprintln!("cncd: {e}");
                return ExitCode::from(2);
            }
        },
        None => Config::default(),
    };
    if args.check_config {
        println!("configuration is valid");
        return ExitCode::SUCCESS;
    }
    let rt = match tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
    {
        Ok(rt) => rt,
        Err(e) => {
            eprintln!("cncd: cannot start the async runtime: {e}");
            return ExitCode::FAILURE;
        }
    };
    match rt.block_on(run(config)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            tracing::error!("{e}");
            ExitCode::FAILURE
        }
    }
}

async fn run(config: Config) -> Result<(), String> {
    let listen = config.api.listen;
    let listener = tokio::net::TcpListener::bind(listen)
        .await
        .map_err(|e| format!("cannot listen on {listen}: {e}"))?;
    let names: String = config.axis_names().iter().collect();
    let bus = format!("{:?}", config.bus).to_lowercase();
    let ctl = Controller::start(config, ClockKind::Monotonic)?;
    tracing::info!(
        "cncd ready: axes {names} on bus {bus}, gRPC API on {}",
        listener.local_addr().map_err(|e| e.to_string())?
    );
    let (tx, rx) = tokio::sync::oneshot::channel::<()>();
    let serve = tokio::spawn(server::serve(ctl.clone(), listener, async {
        let _ = rx.await;
    }));
    shutdown_signal().await;
    tracing::info!("shutting down: bringing the axes to rest");
    let c = ctl.clone();
    tokio::task::spawn_blocking(move || c.shutdown())
        .await
        .map_err(|e| e.to_string())?;
    let s = ctl.snapshot();
    tracing::info!(commanded = ?&s.commanded.0[..s.axes], "axes at rest, exiting");
    let _ = tx.send(());
    let _ = serve.await;
    Ok(())
}

async fn shutdown_signal() {
    use tokio::signal::unix::{SignalKind, signal};
    let mut term = signal(SignalKind::terminate()).expect("SIGTERM handler");
    let mut int = signal(SignalKind::interrupt()).expect("SIGINT handler");
    tokio::select! {
        _ = term.recv() => {},
        _ = int.recv() => {},
    }
}
