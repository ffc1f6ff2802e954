//! systemd integration through the notify protocol (`sd_notify(3)`): readiness, watchdog and
//! status lines. Everything here runs on the Tokio runtime, never on the real-time thread: it
//! only reads the snapshots the status pump publishes ([`Controller::subscribe`]).
//!
//! - **Readiness**: `READY=1` is sent once, when the machine state first goes from `Enabling` to
//!   `Idle` (all drives operational; the API listener is bound before the controller starts).
//!   A drive fault during start-up is logged with its axis, node and block and shown as
//!   `STATUS=`, and no `READY=1` is sent: systemd's `TimeoutStartSec=` acts (an operator reset
//!   through the API before that still completes the start).
//! - **Watchdog**: every half `WATCHDOG_USEC` the snapshot `sequence` (one per tick of the bus
//!   period `cycle_ns` the snapshot carries) is
//!   compared with the previous look. `WATCHDOG=1` is sent only if the real-time thread made at
//!   least [`MIN_TICK_FRACTION`] of the ticks the elapsed time allows; a stalled real-time thread
//!   (a blocking bus `cycle()`, a dead status pump, a wedged runtime) stops the pings and
//!   systemd restarts the service.
//!
//! The [`sd_notify`] crate provides the message vocabulary ([`NotifyState`]) and the
//! `WATCHDOG_USEC`/`WATCHDOG_PID` parsing. Sending goes through [`Notifier`], which takes the
//! socket address explicitly (from `NOTIFY_SOCKET` in production, from a test's own socket in
//! tests), so tests never mutate the process environment.
//!
//! [`Controller::subscribe`]: super::controller::Controller::subscribe

use std::ffi::OsStr;
use std::fmt::Write as _;
use std::io;
use std::os::unix::ffi::OsStrExt;
use std::os::unix::net::{SocketAddr, UnixDatagram};
use std::sync::Arc;
use std::time::{Duration, Instant};

use kernel::units::TS_NS;
pub use sd_notify::NotifyState;
use tokio::sync::watch;
use tokio::task::JoinHandle;

use super::logging::BlockNo;
use super::rt::{MachineState, Snapshot};

/// A watchdog ping needs at least this fraction of the ticks the elapsed time allows (half: a
/// thread that only makes every other deadline is not "ticking" in any useful sense).
pub const MIN_TICK_FRACTION: f64 = 0.5;

/// Sends notify-protocol datagrams to the service manager's socket.
#[derive(Debug)]
pub struct Notifier {
    sock: UnixDatagram,
    addr: SocketAddr,
    /// The address as given, for messages.
    shown: String,
}

impl Notifier {
    /// The notifier of the service manager that started us (`NOTIFY_SOCKET`); `None` when the
    /// variable is not set (not run by systemd, or not `Type=notify`).
    pub fn from_env() -> io::Result<Option<Notifier>> {
        match std::env::var_os("NOTIFY_SOCKET") {
            None => Ok(None),
            Some(p) if p.is_empty() => Ok(None),
            Some(p) => Notifier::new(&p).map(Some),
        }
    }

    /// A notifier sending to `socket`: an absolute path, or `@name` for an abstract socket
    /// (both forms systemd uses for `NOTIFY_SOCKET`).
    pub fn new(socket: impl AsRef<OsStr>) -> io::Result<Notifier> {
        let socket = socket.as_ref();
        let bytes = socket.as_bytes();
        let addr = if let Some(name) = bytes.strip_prefix(b"@") {
            use std::os::linux::net::SocketAddrExt;
            SocketAddr::from_abstract_name(name)?
        } else if bytes.starts_with(b"/") {
            SocketAddr::from_pathname(socket)?
        } else {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!(
                    "notify socket {:?} is neither an absolute path nor an abstract socket (@name)",
                    socket
                ),
            ));
        };
        Ok(Notifier {
            sock: UnixDatagram::unbound()?,
            addr,
            shown: socket.to_string_lossy().into_owned(),
        })
    }

    /// Sends `states` as one datagram (one `KEY=VALUE` line each).
    pub fn notify(&self, states: &[NotifyState<'_>]) -> io::Result<()> {
        let mut msg = String::new();
        for s in states {
            // Writing to a String cannot fail.
            let _ = writeln!(msg, "{s}");
        }
        let sent = self.sock.send_to_addr(msg.as_bytes(), &self.addr)?;
        if sent == msg.len() {
            Ok(())
        } else {
            Err(io::Error::new(
                io::ErrorKind::WriteZero,
                "incomplete notify datagram",
            ))
        }
    }

    /// As [`Notifier::notify`], logging a failure instead of returning it (a missing manager
    /// must not stop the machine).
    pub fn send(&self, states: &[NotifyState<'_>]) {
        if let Err(e) = self.notify(states) {
            tracing::warn!(socket = %self.shown, "cannot notify the service manager: {e}");
        }
    }
}

/// The watchdog period systemd asked for (`WATCHDOG_USEC`, for this process per
/// `WATCHDOG_PID`), or `None` when `WatchdogSec=` is not set.
pub fn watchdog_from_env() -> Option<Duration> {
    sd_notify::watchdog_enabled().filter(|d| !d.is_zero())
}

/// How often to look at the real-time thread and ping: half the watchdog period, as
/// `sd_watchdog_enabled(3)` recommends.
pub fn ping_interval(watchdog: Duration) -> Duration {
    watchdog / 2
}

/// What one look at the real-time thread found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Progress {
    /// Enough ticks since the previous look: ping.
    Ticking { ticks: u64 },
    /// Too few ticks: withhold the ping.
    Stalled { ticks: u64, expected: u64 },
}

/// Judges the real-time thread from two snapshot sequence numbers taken `elapsed` apart, with
/// one tick due every `tick` (the bus period).
pub fn judge(previous_sequence: u64, sequence: u64, elapsed: Duration, tick: Duration) -> Progress {
    let ticks = sequence.saturating_sub(previous_sequence);
    let expected = (elapsed.as_nanos() / tick.as_nanos().max(1)) as u64;
    let needed = ((expected as f64 * MIN_TICK_FRACTION).floor() as u64).max(1);
    if ticks >= needed {
        Progress::Ticking { ticks }
    } else {
        Progress::Stalled { ticks, expected }
    }
}

/// Waits until the drives are operational: the first `Enabling` → `Idle` transition. Faults on
/// the way are logged and shown as `STATUS=`, and the wait goes on (a reset may still bring the
/// drives up). Returns the snapshot that was `Idle`, or `None` if the controller went away.
pub async fn wait_operational(
    mut status: watch::Receiver<Snapshot>,
    axis_names: &[char],
    notifier: Option<&Notifier>,
) -> Option<Snapshot> {
    let mut reported_fault = None;
    loop {
        let s = *status.borrow_and_update();
        match s.state {
            MachineState::Idle => return Some(s),
            MachineState::Fault if s.alarm.fault != reported_fault => {
                reported_fault = s.alarm.fault;
                let (axis, node, reason) = match s.alarm.fault {
                    Some(f) => (
                        axis_label(f.axis, axis_names),
                        f.node.map(i64::from).unwrap_or(-1),
                        f.reason.to_string(),
                    ),
                    None => ("-".to_owned(), -1, "unknown fault".to_owned()),
                };
                tracing::error!(
                    axis,
                    node,
                    block = %BlockNo(s.progress.block_n),
                    line = s.progress.line,
                    "drives not operational at start-up: {reason}; not reporting ready \
                     (reset through the API, or systemd's start timeout restarts the service)"
                );
                if let Some(n) = notifier {
                    let msg = format!("drive fault during start-up (axis {axis}): {reason}");
                    n.send(&[NotifyState::Status(&msg)]);
                }
            }
            MachineState::Shutdown => return None,
            _ => {}
        }
        if status.changed().await.is_err() {
            return None;
        }
    }
}

fn axis_label(axis: Option<u8>, names: &[char]) -> String {
    hal::fault_axis_label(axis, names).unwrap_or_else(|| "-".into())
}

/// Sends `WATCHDOG=1` every `interval` while the real-time thread is ticking (see [`judge`]).
/// Runs until aborted. Stalls and recoveries are logged once each, with the block that was
/// executing.
pub async fn watchdog(
    status: watch::Receiver<Snapshot>,
    notifier: Arc<Notifier>,
    interval: Duration,
) {
    let mut ticker = tokio::time::interval(interval);
    ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    ticker.tick().await; // the first tick is immediate
    let mut last_seq = status.borrow().tick.sequence;
    let mut last_at = Instant::now();
    let mut stalled = false;
    loop {
        ticker.tick().await;
        let s = *status.borrow();
        let now = Instant::now();
        // A snapshot from before the core existed carries no period: the default 4 ms.
        let tick = Duration::from_nanos(if s.tick.cycle_ns == 0 {
            TS_NS
        } else {
            s.tick.cycle_ns
        });
        match judge(last_seq, s.tick.sequence, now - last_at, tick) {
            Progress::Ticking { ticks } => {
                if stalled {
                    stalled = false;
                    tracing::warn!(
                        ticks,
                        block = %BlockNo(s.progress.block_n),
                        line = s.progress.line,
                        "real-time thread ticking again: watchdog pings resume"
                    );
                    notifier.send(&[NotifyState::Status("running")]);
                }
                notifier.send(&[NotifyState::Watchdog]);
            }
            Progress::Stalled { ticks, expected } => {
                if !stalled {
                    stalled = true;
                    tracing::error!(
                        ticks,
                        expected,
                        state = ?s.state,
                        job = s.progress.job,
                        block = %BlockNo(s.progress.block_n),
                        line = s.progress.line,
                        "real-time thread stalled: {ticks} ticks where {expected} were due; \
                         withholding the watchdog ping"
                    );
                    notifier.send(&[NotifyState::Status("real-time thread stalled")]);
                }
            }
        }
        last_seq = s.tick.sequence;
        last_at = now;
    }
}

/// The systemd tasks of a running daemon.
pub struct Supervision {
    pub ready: JoinHandle<bool>,
    pub watchdog: Option<JoinHandle<()>>,
}

impl Supervision {
    /// Stops the watchdog pings (the real-time thread ends on shutdown).
    pub fn stop(&self) {
        if let Some(w) = &self.watchdog {
            w.abort();
        }
        self.ready.abort();
    }
}

/// Starts the readiness task (sends `READY=1` with `ready_status` as `STATUS=` once the drives
/// are operational; its result says whether it did) and, with `watchdog` set, the watchdog
/// task pinging every half period. Call from within a Tokio runtime.
pub fn supervise(
    status: watch::Receiver<Snapshot>,
    notifier: Option<Arc<Notifier>>,
    watchdog: Option<Duration>,
    axis_names: Vec<char>,
    ready_status: String,
) -> Supervision {
    let wd = match (&notifier, watchdog) {
        (Some(n), Some(period)) => {
            let interval = ping_interval(period);
            tracing::info!(
                period_ms = period.as_millis() as u64,
                interval_ms = interval.as_millis() as u64,
                "systemd watchdog: pinging while the real-time thread ticks"
            );
            Some(tokio::spawn(self::watchdog(
                status.clone(),
                n.clone(),
                interval,
            )))
        }
        _ => None,
    };
    let ready = tokio::spawn(async move {
        if let Some(n) = &notifier {
            n.send(&[NotifyState::Status("enabling drives")]);
        }
        let Some(s) = wait_operational(status, &axis_names, notifier.as_deref()).await else {
            return false;
        };
        tracing::info!(block = %BlockNo(s.progress.block_n), line = s.progress.line, "drives operational: {ready_status}");
        if let Some(n) = &notifier {
            n.send(&[NotifyState::Ready, NotifyState::Status(&ready_status)]);
        }
        true
    });
    Supervision {
        ready,
        watchdog: wd,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn judge_asks_for_half_the_due_ticks() {
        let ms = Duration::from_millis;
        let ticking = |ticks| Progress::Ticking { ticks };
        let stalled = |ticks, expected| Progress::Stalled { ticks, expected };
        // (sequence at the previous look, sequence now, time between the looks, tick, verdict)
        let cases = [
            // 1 s is 250 ticks: 125 are enough, 124 are not.
            (1000, 1125, ms(1000), ms(4), ticking(125)),
            (1000, 1124, ms(1000), ms(4), stalled(124, 250)),
            // At a 1 ms bus period 1 s is 1000 ticks: 250 are a stall, 500 are enough.
            (0, 250, ms(1000), ms(1), stalled(250, 1000)),
            (0, 500, ms(1000), ms(1), ticking(500)),
            // At 10 ms, 50 of 100.
            (0, 50, ms(1000), ms(10), ticking(50)),
            // No progress at all is a stall even over a very short look.
            (7, 7, ms(1), ms(4), stalled(0, 0)),
            // A virtual clock may run ahead of wall time: still ticking.
            (0, 100_000, ms(10), ms(4), ticking(100_000)),
        ];
        for (previous, now, elapsed, tick, verdict) in cases {
            assert_eq!(
                judge(previous, now, elapsed, tick),
                verdict,
                "{previous} -> {now} in {elapsed:?}, tick {tick:?}"
            );
        }
        assert_eq!(ping_interval(Duration::from_secs(3)), ms(1500));
    }

    #[test]
    fn notifier_refuses_relative_addresses_and_sends_lines() {
        let e = Notifier::new("relative/socket").unwrap_err();
        assert!(e.to_string().contains("absolute path"), "{e}");

        let dir = std::env::temp_dir().join(format!("cncd-sd-unit-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("notify.sock");
        let _ = std::fs::remove_file(&path);
        let rx = UnixDatagram::bind(&path).unwrap();
        let n = Notifier::new(&path).unwrap();
        n.notify(&[NotifyState::Ready, NotifyState::Status("up")])
            .unwrap();
        let mut buf = [0u8; 256];
        let len = rx.recv(&mut buf).unwrap();
        assert_eq!(&buf[..len], b"READY=1\nSTATUS=up\n");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn abstract_socket_addresses_work() {
        use std::os::linux::net::SocketAddrExt;
        let name = format!("cncd-sd-test-{}", std::process::id());
        let rx = UnixDatagram::bind_addr(&SocketAddr::from_abstract_name(&name).unwrap()).unwrap();
        let n = Notifier::new(format!("@{name}")).unwrap();
        n.notify(&[NotifyState::Watchdog]).unwrap();
        let mut buf = [0u8; 64];
        let len = rx.recv(&mut buf).unwrap();
        assert_eq!(&buf[..len], b"WATCHDOG=1\n");
    }
}
