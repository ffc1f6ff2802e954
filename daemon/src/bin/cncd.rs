//! `cncd`: the controller daemon.
//!
//! With no configuration it runs the built-in simulated 3-axis machine and serves the gRPC API
//! on 127.0.0.1:50051 and the browser HMI on http://127.0.0.1:8080/ (docs/hmi.md). Run by systemd (`deploy/cncd.service`, `Type=notify`) it reports ready
//! once the drives are operational, pings the watchdog while the real-time thread ticks, and
//! logs to the journal.
//!
//! Exit codes: 0 after a clean shutdown (SIGTERM/SIGINT) or a valid `--check-config`; 2 for a
//! configuration mistake (the unit does not restart on it); 1 for anything else.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Duration;

use clap::Parser;
use daemon::runtime::config::Config;
use daemon::runtime::controller::{ClockKind, Controller, StartError};
use daemon::runtime::logging::{self, BlockNo, LogTarget};
use daemon::runtime::mtconnect;
use daemon::runtime::systemd::{self, Notifier, NotifyState};
use daemon::runtime::{discovery, server};

/// Exit code of a configuration mistake (`RestartPreventExitStatus=2` in the unit).
const EXIT_CONFIG: u8 = 2;

/// Why `cncd` stopped with an error (logged with its code before the exit).
#[derive(Debug, thiserror::Error)]
enum CncdError {
    #[error("cannot handle {signal}: {source}")]
    Signal {
        signal: &'static str,
        #[source]
        source: std::io::Error,
    },
    #[error(transparent)]
    Api(#[from] server::ServerError),
    /// The controller did not start (bus, storage, configuration: the message says which).
    #[error(transparent)]
    Start(#[from] StartError),
    /// The test-only stall knob has a value that is not a tick count.
    #[error(transparent)]
    FaultInject(#[from] daemon::runtime::fault_inject::FaultKnobError),
    #[error("shutdown: {0}")]
    Shutdown(#[source] tokio::task::JoinError),
    #[error("stopped after the API failure above")]
    AfterApiFailure,
}

impl CncdError {
    /// Stable code (logged beside the message).
    fn code(&self) -> &'static str {
        match self {
            CncdError::Signal { .. } => "cncd_signal",
            CncdError::Api(e) => e.code(),
            CncdError::Start(e) => e.code(),
            CncdError::FaultInject(_) => "cncd_fault_inject",
            CncdError::Shutdown(_) => "cncd_shutdown",
            CncdError::AfterApiFailure => "cncd_after_api_failure",
        }
    }
}

#[derive(Parser)]
#[command(name = "cncd", version, about = "CNC motion controller daemon")]
struct Args {
    /// Configuration file (TOML). Without it: the simulated 3-axis machine.
    #[arg(long, short)]
    config: Option<PathBuf>,
    /// Validate the configuration file given with --config, print a summary and exit
    /// (status 0 when valid, 2 with the key of the first mistake otherwise).
    #[arg(long)]
    check_config: bool,
    /// Where logs go: the journal when run by systemd, stderr otherwise (auto).
    #[arg(long, value_enum, default_value_t = LogTarget::Auto)]
    log: LogTarget,
}

fn main() -> ExitCode {
    // Before any other thread: the allocator's arenas are set up once.
    daemon::runtime::rt::tune_allocator();
    let args = Args::parse();
    if args.check_config {
        return check_config(args.config.as_deref());
    }
    let target = logging::init(args.log);
    open_files_limit();
    let config = match &args.config {
        Some(p) => match Config::load(p) {
            Ok(c) => c,
            Err(e) => {
                // Once, where the operator looks: the journal (with a priority) or stderr.
                if target == LogTarget::Journal {
                    tracing::error!(code = e.code(), "configuration: {e}");
                } else {
                    eprintln!("cncd: error [{}]: {e}", e.code());
                }
                return ExitCode::from(EXIT_CONFIG);
            }
        },
        None => Config::default(),
    };
    let rt = match tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_stack_size(daemon::runtime::rt::THREAD_STACK_BYTES)
        .enable_all()
        .build()
    {
        Ok(rt) => rt,
        Err(e) => {
            tracing::error!("cannot start the async runtime: {e}");
            return ExitCode::FAILURE;
        }
    };
    match rt.block_on(run(config)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            tracing::error!(code = e.code(), "{e}");
            ExitCode::FAILURE
        }
    }
}

/// Raises the open-file limit (daemon::runtime::open_files); warns where it stays low enough
/// for a flood of idle connections to take every descriptor.
fn open_files_limit() {
    use daemon::runtime::open_files;
    match open_files::raise() {
        Some((before, after)) if after < open_files::LOW => tracing::warn!(
            before,
            after,
            "open-file limit stays low (hard limit): a flood of idle connections may use the \
             descriptors up until they time out (raise LimitNOFILE= in the unit)"
        ),
        Some((before, after)) => tracing::debug!(before, after, "open-file limit"),
        None => tracing::warn!("cannot read the open-file limit"),
    }
}

/// `--check-config`: parse and validate, print what would run.
fn check_config(path: Option<&std::path::Path>) -> ExitCode {
    let Some(path) = path else {
        eprintln!("cncd: --check-config needs the file: cncd --check-config --config FILE.toml");
        return ExitCode::from(EXIT_CONFIG);
    };
    // The TLS files are loaded too: a missing or broken certificate must fail here, not at
    // the next start.
    let checked = Config::load(path)
        .map_err(|e| (e.code(), e.to_string()))
        .and_then(|c| {
            server::check_tls(&c.api)
                .and_then(|()| server::check_hmi_tls(&c))
                .map(|()| c)
                .map_err(|e| (e.code(), format!("{}: {e}", path.display())))
        });
    match checked {
        Ok(c) => {
            let names: String = c.axis_names().iter().collect();
            let hmi = if c.hmi.enabled {
                format!("HMI on {}", c.hmi.listen)
            } else {
                "HMI disabled".into()
            };
            let agent = if c.mtconnect.enabled {
                format!(", MTConnect on {}", c.mtconnect.listen)
            } else {
                String::new()
            };
            println!(
                "{}: configuration is valid: axes {names}, bus {}, API on {}, {hmi}{agent}",
                path.display(),
                bus_label(&c),
                c.api.listen
            );
            ExitCode::SUCCESS
        }
        Err((code, message)) => {
            // The form cncctl gives diagnostics: `error [code]: message`.
            eprintln!("cncd: error [{code}]: {message}");
            ExitCode::from(EXIT_CONFIG)
        }
    }
}

/// `sim`, `can on can0`, `serial on /dev/ttyUSB0`: the bus kind and its device.
fn bus_label(c: &Config) -> String {
    use daemon::runtime::buses::BusConfig;
    match &c.bus {
        BusConfig::Sim { .. } => "sim".into(),
        BusConfig::Can(can) => format!("can on {}", can.interface),
        BusConfig::Serial(s) => format!("serial on {}", s.port),
    }
}

async fn run(config: Config) -> Result<(), CncdError> {
    let notifier = notifier_from_env();
    // Signal handlers first: a SIGTERM during start-up also brakes and exits cleanly.
    let mut signals = Signals::install()?;
    // Every API listener is bound before READY=1 (sent once the drives are operational), so
    // ready means reachable; a listener that cannot be bound ends the start with an error.
    // The TCP ports are taken now and listen once the Unix socket exists.
    let listener = server::Reserved::bind("api.listen", config.api.listen)?;
    let local = listener.addr;
    let hmi = config
        .hmi
        .enabled
        .then(|| server::Reserved::bind("hmi.listen", config.hmi.listen))
        .transpose()?;
    let summary = summary(&config, local);
    let axis_names = config.axis_names();
    // The controller creates the storage directory, where the Unix socket may live.
    let ctl = start_controller(config)?;
    tracing::info!("cncd started: {summary}; enabling drives");
    let (listeners, hmi) = listeners_beside(&ctl, listener, hmi).await?;
    log_hmi(&ctl, hmi.as_ref());
    // Bound: cncctl may find it now, whatever the data directory (issue #31).
    let socket = discovery::socket_of(ctl.config());
    if let Some(s) = &socket {
        discovery::publish(s);
    }
    let supervision = systemd::supervise(
        ctl.subscribe(),
        notifier.clone(),
        systemd::watchdog_from_env(),
        axis_names,
        summary,
    );
    let health = tokio::spawn(logging::rt_health(
        ctl.subscribe(),
        Duration::from_secs(10),
        Duration::from_secs(15 * 60),
    ));
    let mut services = Services::start(&ctl, listeners, hmi);
    let api_failure = services.until_signal_or_failure(&mut signals).await;
    bring_to_rest(&ctl, notifier.as_deref()).await?;
    supervision.stop();
    health.abort();
    log_rest_positions(&ctl);
    services.stop(api_failure.is_none()).await;
    if let Some(s) = &socket {
        discovery::unpublish(s);
    }
    tracing::info!("cncd stopped");
    match api_failure {
        None => Ok(()),
        Some(_) => Err(CncdError::AfterApiFailure),
    }
}

/// systemd's notification socket when cncd runs under it.
fn notifier_from_env() -> Option<Arc<Notifier>> {
    match Notifier::from_env() {
        Ok(n) => n.map(Arc::new),
        Err(e) => {
            tracing::warn!("NOTIFY_SOCKET unusable ({e}): systemd will not hear from cncd");
            None
        }
    }
}

/// `axes XYZ on bus sim, API on 127.0.0.1:50051 and /run/cnc/api.sock`: the start-up log line
/// and systemd's status.
fn summary(config: &Config, local: std::net::SocketAddr) -> String {
    let mut api_on = vec![local.to_string()];
    if let Some(p) = config.api.unix_socket_path(&config.storage.dir) {
        api_on.push(p.display().to_string());
    }
    let api_on = api_on.join(" and ");
    let names: String = config.axis_names().iter().collect();
    let bus = bus_label(config);
    format!("axes {names} on bus {bus}, API on {api_on}")
}

/// The API (with the HMI) and the MTConnect agent, each on its task with its stop signal.
struct Services {
    api: tokio::task::JoinHandle<Result<(), server::ServerError>>,
    stop_api: tokio::sync::oneshot::Sender<()>,
    agent: tokio::task::JoinHandle<()>,
    stop_agent: tokio::sync::oneshot::Sender<()>,
}

impl Services {
    fn start(
        ctl: &Arc<Controller>,
        listeners: server::Listeners,
        hmi: Option<tokio::net::TcpListener>,
    ) -> Services {
        let (stop_api, rx) = tokio::sync::oneshot::channel::<()>();
        let api = tokio::spawn(server::serve_with_configured_hmi(
            ctl.clone(),
            listeners,
            hmi,
            async {
                let _ = rx.await;
            },
        ));
        // The MTConnect agent (docs/mtconnect.md): read-only; it stops with the API.
        let (stop_agent, mt_rx) = tokio::sync::oneshot::channel::<()>();
        let agent = tokio::spawn(mtconnect::run_configured(
            ctl.clone(),
            ctl.config().mtconnect.clone(),
            async {
                let _ = mt_rx.await;
            },
        ));
        Services {
            api,
            stop_api,
            agent,
            stop_agent,
        }
    }

    /// Runs until a signal (`None`), or until the API fails (its failure: then cncd stops
    /// too, since an unreachable controller must not look healthy to systemd).
    async fn until_signal_or_failure(&mut self, signals: &mut Signals) -> Option<String> {
        let api_failure = tokio::select! {
            _ = signals.recv() => None,
            r = &mut self.api => Some(match r {
                Ok(Ok(())) => "the API stopped".to_owned(),
                Ok(Err(e)) => format!("API: {e}"),
                Err(e) => format!("API task: {e}"),
            }),
        };
        if let Some(e) = &api_failure {
            tracing::error!("{e}");
        }
        api_failure
    }

    /// Stops the agent and the API (waiting for the API's drain when it still runs).
    async fn stop(self, api_running: bool) {
        let _ = self.stop_api.send(());
        let _ = self.stop_agent.send(());
        let _ = tokio::time::timeout(server::SHUTDOWN_DRAIN, self.agent).await;
        if api_running {
            let _ = self.api.await;
        }
    }
}

/// Where the HMI is, or why it is not there (docs/hmi.md).
fn log_hmi(ctl: &Controller, hmi: Option<&tokio::net::TcpListener>) {
    let Some(addr) = hmi.and_then(|l| l.local_addr().ok()) else {
        tracing::info!("HMI disabled (hmi.enabled = false)");
        return;
    };
    let tls = ctl.config().hmi.tls_cert.is_some() || !addr.ip().is_loopback();
    let url = format!("{}://{addr}/", if tls { "https" } else { "http" });
    if daemon::runtime::hmi::Assets::embedded().is_empty() {
        tracing::warn!(
            "HMI on {url}: grpc-web only, this cncd was built without hmi/dist/ (the page says \
             the assets are missing)"
        );
    } else {
        tracing::info!("HMI on {url}");
    }
}

/// The other listeners (the Unix socket, extra addresses) with `listener` first, then the
/// reserved ports opened (the API's, the HMI's): no TCP listener answers before the Unix
/// socket exists. When one cannot be bound the controller is shut down before the error
/// returns.
async fn listeners_beside(
    ctl: &Arc<Controller>,
    listener: server::Reserved,
    hmi: Option<server::Reserved>,
) -> Result<(server::Listeners, Option<tokio::net::TcpListener>), CncdError> {
    let cfg = ctl.config();
    let local = listener.addr;
    let bound = server::bind_extra(&cfg.api, &cfg.storage.dir)
        .await
        .and_then(|l| Ok((l, listener.listen()?, hmi.map(|h| h.listen()).transpose()?)));
    let (mut listeners, listener, hmi) = match bound {
        Ok(b) => b,
        Err(e) => {
            let c = ctl.clone();
            let _ = tokio::task::spawn_blocking(move || c.shutdown()).await;
            return Err(e.into());
        }
    };
    if local.ip().is_loopback() {
        listeners.local_tcp.insert(0, listener);
    } else {
        listeners.remote_tcp.insert(0, listener);
    }
    Ok((listeners, hmi))
}

/// Brakes the axes to rest and stops the real-time thread (systemd hears STOPPING; the
/// watchdog keeps pinging while the thread brakes).
async fn bring_to_rest(
    ctl: &Arc<Controller>,
    notifier: Option<&Notifier>,
) -> Result<(), CncdError> {
    tracing::info!("shutting down: bringing the axes to rest");
    if let Some(n) = notifier {
        n.send(&[
            NotifyState::Stopping,
            NotifyState::Status("bringing the axes to rest"),
        ]);
    }
    let c = ctl.clone();
    tokio::task::spawn_blocking(move || c.shutdown())
        .await
        .map_err(CncdError::Shutdown)
}

/// Logs where every axis came to rest (and the block it was in).
fn log_rest_positions(ctl: &Controller) {
    let s = ctl.snapshot();
    for (i, name) in ctl
        .config()
        .axis_names()
        .iter()
        .enumerate()
        .take(s.axes.count)
    {
        tracing::info!(
            axis = %name,
            block = %BlockNo(s.progress.block_n),
            line = s.progress.line,
            position_mm = s.axes.commanded[i],
            "axis at rest"
        );
    }
}

/// Opens the bus and starts the controller; with the test-only stall knob set
/// (`daemon::runtime::fault_inject`), on a bus that wedges the real-time thread.
fn start_controller(config: Config) -> Result<Arc<Controller>, CncdError> {
    use daemon::runtime::buses::open_bus;
    use daemon::runtime::fault_inject::{self, STALL_RT_AFTER_TICKS, StallAfter};
    let knob = std::env::var(STALL_RT_AFTER_TICKS).ok();
    let Some(ticks) =
        fault_inject::stall_after_ticks(knob.as_deref()).map_err(CncdError::FaultInject)?
    else {
        return Ok(Controller::start(config, ClockKind::Monotonic)?);
    };
    tracing::warn!(
        ticks,
        "fault injection: the real-time thread will stall after {ticks} ticks \
         ({STALL_RT_AFTER_TICKS}; for tests only)"
    );
    let io = daemon::runtime::buses::IoWiring::of(&config);
    let bus = open_bus(&config.bus, &config.axes, &config.sim, &io).map_err(StartError::Bus)?;
    Ok(Controller::start_with_bus(
        config,
        ClockKind::Monotonic,
        Box::new(StallAfter::new(bus, ticks)),
    )?)
}

/// SIGTERM (systemd stop) and SIGINT (Ctrl-C).
struct Signals {
    term: tokio::signal::unix::Signal,
    int: tokio::signal::unix::Signal,
}

impl Signals {
    fn install() -> Result<Signals, CncdError> {
        use tokio::signal::unix::{SignalKind, signal};
        let handle = |kind: SignalKind, name: &'static str| {
            signal(kind).map_err(|source| CncdError::Signal {
                signal: name,
                source,
            })
        };
        Ok(Signals {
            term: handle(SignalKind::terminate(), "SIGTERM")?,
            int: handle(SignalKind::interrupt(), "SIGINT")?,
        })
    }

    async fn recv(&mut self) {
        tokio::select! {
            _ = self.term.recv() => {},
            _ = self.int.recv() => {},
        }
    }
}
