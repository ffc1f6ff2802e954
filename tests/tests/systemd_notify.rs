//! systemd notify protocol against a fake service manager: a `UnixDatagram` bound by the test
//! plays `NOTIFY_SOCKET`.
//!
//! - In process (the socket path is passed explicitly, the process environment is untouched):
//!   READY=1 once the drives are operational, WATCHDOG=1 every half period while the real-time
//!   thread ticks, no pings while a test bus holds the real-time thread inside `cycle()`, pings
//!   again after it lets go; no READY=1 while the drives are faulted at start-up.
//! - The real `cncd` binary, started with `NOTIFY_SOCKET` and `WATCHDOG_USEC` in its own
//!   environment: READY=1, WATCHDOG=1, then STOPPING=1 and exit status 0 on SIGTERM.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use daemon::runtime::config::Config;
use daemon::runtime::controller::{ClockKind, Controller};
use daemon::runtime::rt::MachineState;
use daemon::runtime::systemd::{self, Notifier};
use hal::{BusFault, CycleCommand, CycleFeedback, DriveBus, FaultReason};
use tokio::net::UnixDatagram;

mod systemd_support;
use systemd_support::cncd_binary;

/// A fresh directory for one test's sockets and files.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("cncd-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The fake service manager: receives notify datagrams.
struct Manager {
    sock: UnixDatagram,
}

impl Manager {
    fn bind(path: &Path) -> Manager {
        Manager {
            sock: UnixDatagram::bind(path).unwrap(),
        }
    }

    /// Every message line received during `d`, with its arrival time.
    async fn collect(&self, d: Duration) -> Vec<(Instant, String)> {
        let end = Instant::now() + d;
        let mut out = Vec::new();
        let mut buf = vec![0u8; 4096];
        while let Some(left) = end.checked_duration_since(Instant::now()) {
            match tokio::time::timeout(left, self.sock.recv(&mut buf)).await {
                Ok(Ok(n)) => {
                    let t = Instant::now();
                    for line in String::from_utf8_lossy(&buf[..n]).lines() {
                        out.push((t, line.to_owned()));
                    }
                }
                Ok(Err(e)) => panic!("receiving notify datagrams: {e}"),
                Err(_) => break,
            }
        }
        out
    }

    /// Waits up to `timeout` for the line `want`; returns everything received until then.
    async fn wait_for(&self, want: &str, timeout: Duration) -> Vec<String> {
        let end = Instant::now() + timeout;
        let mut seen = Vec::new();
        let mut buf = vec![0u8; 4096];
        loop {
            let left = end
                .checked_duration_since(Instant::now())
                .unwrap_or_else(|| panic!("no {want} within {timeout:?}; received {seen:?}"));
            match tokio::time::timeout(left, self.sock.recv(&mut buf)).await {
                Ok(Ok(n)) => {
                    for line in String::from_utf8_lossy(&buf[..n]).lines() {
                        seen.push(line.to_owned());
                    }
                    if seen.iter().any(|l| l == want) {
                        return seen;
                    }
                }
                Ok(Err(e)) => panic!("receiving notify datagrams: {e}"),
                Err(_) => panic!("no {want} within {timeout:?}; received {seen:?}"),
            }
        }
    }
}

fn count(msgs: &[(Instant, String)], line: &str) -> usize {
    msgs.iter().filter(|(_, l)| l == line).count()
}

/// What a [`SwitchedBus`] does while its switch is on.
#[derive(Clone, Copy)]
enum WhileOn {
    /// `cycle()` blocks: a hung bus driver holding the real-time thread.
    Stall,
    /// Axis Y's drive reports a fault.
    FaultY,
}

/// The simulated bus, but doing [`WhileOn`] while `on` is set.
struct SwitchedBus {
    inner: sim::SimBus,
    on: Arc<AtomicBool>,
    while_on: WhileOn,
}

impl SwitchedBus {
    /// The bus with its switch set to `on`, and the switch.
    fn new(while_on: WhileOn, on: bool) -> (SwitchedBus, Arc<AtomicBool>) {
        let on = Arc::new(AtomicBool::new(on));
        let inner = sim::SimBus::new(sim::SimDriveParams::default(), &[0.0; 3]);
        let bus = SwitchedBus {
            inner,
            on: on.clone(),
            while_on,
        };
        (bus, on)
    }
}

impl DriveBus for SwitchedBus {
    daemon::delegate_drive_bus!(inner: axes, enable, reset);
    fn name(&self) -> &str {
        match self.while_on {
            WhileOn::Stall => "stall",
            WhileOn::FaultY => "faulty",
        }
    }
    fn cycle(&mut self, cmd: &CycleCommand, fb: &mut CycleFeedback) -> Result<(), BusFault> {
        match self.while_on {
            WhileOn::Stall => {
                while self.on.load(Ordering::Acquire) {
                    std::thread::sleep(Duration::from_millis(1));
                }
            }
            WhileOn::FaultY if self.on.load(Ordering::Acquire) => {
                return Err(BusFault {
                    axis: Some(1),
                    node: Some(2),
                    reason: FaultReason::DriveFault { code: 0x7500 },
                });
            }
            WhileOn::FaultY => {}
        }
        self.inner.cycle(cmd, fb)
    }
}

fn config(dir: &Path) -> Config {
    let mut cfg = Config::default();
    cfg.storage.dir = dir.join("data");
    // Not the tests' business to lock the test process's memory.
    cfg.rt.lock_memory = false;
    cfg
}

/// Watchdog period of the tests: long enough that a loaded test machine (other suites
/// compiling and running on the same two cores) does not starve a look window.
const WATCHDOG: Duration = Duration::from_millis(1000);
/// Half the watchdog period.
const PING: Duration = Duration::from_millis(500);

/// The daemon in process on a [`SwitchedBus`], supervised with a watchdog of `WATCHDOG`, and
/// the fake service manager it notifies.
struct Supervised {
    /// The test's directory.
    dir: PathBuf,
    mgr: Manager,
    /// The bus's switch.
    switch: Arc<AtomicBool>,
    ctl: Arc<Controller>,
    sup: systemd::Supervision,
}

/// [`Supervised`] in a fresh directory `name`, on a bus doing `while_on` while its switch (set
/// to `on` at start-up) is on.
fn supervised(name: &str, while_on: WhileOn, on: bool) -> Supervised {
    cncd_binary();
    let dir = scratch(name);
    let path = dir.join("notify.sock");
    let mgr = Manager::bind(&path);
    let (bus, switch) = SwitchedBus::new(while_on, on);
    let ctl =
        Controller::start_with_bus(config(&dir), ClockKind::Monotonic, Box::new(bus)).unwrap();
    let notifier = Arc::new(Notifier::new(&path).unwrap());
    let sup = systemd::supervise(
        ctl.subscribe(),
        Some(notifier),
        Some(WATCHDOG),
        ctl.config().axis_names(),
        "test machine".into(),
    );
    Supervised {
        dir,
        mgr,
        switch,
        ctl,
        sup,
    }
}

/// Shuts the in-process daemon down (off the async threads: it joins the real-time thread) and
/// removes the test's directory.
async fn shut_down(ctl: Arc<Controller>, dir: &Path) {
    tokio::task::spawn_blocking(move || ctl.shutdown())
        .await
        .unwrap();
    let _ = std::fs::remove_dir_all(dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn ready_after_start_up_pings_while_ticking_and_not_while_the_rt_thread_stalls() {
    let Supervised {
        dir,
        mgr,
        switch: stall,
        ctl,
        sup,
    } = supervised("notify-stall", WhileOn::Stall, false);

    // READY=1 after start-up, and only once the drives are operational.
    let before = mgr.wait_for("READY=1", Duration::from_secs(10)).await;
    assert_eq!(ctl.snapshot().state, MachineState::Idle);
    assert!(
        before.iter().any(|l| l == "STATUS=test machine"),
        "{before:?}"
    );
    assert!(
        before.iter().any(|l| l == "STATUS=enabling drives"),
        "{before:?}"
    );
    assert!(
        sup.ready.is_finished()
            || tokio::time::timeout(Duration::from_secs(1), async {
                while !sup.ready.is_finished() {
                    tokio::time::sleep(Duration::from_millis(5)).await;
                }
            })
            .await
            .is_ok()
    );

    // Periodic pings while the real-time thread ticks: ~6 in three seconds.
    let ticking = mgr.collect(Duration::from_secs(3)).await;
    let pings = count(&ticking, "WATCHDOG=1");
    assert!(
        (4..=7).contains(&pings),
        "{pings} pings in 3 s: {ticking:?}"
    );
    assert_eq!(count(&ticking, "READY=1"), 0, "READY=1 twice: {ticking:?}");
    let times: Vec<Instant> = ticking
        .iter()
        .filter(|(_, l)| l == "WATCHDOG=1")
        .map(|(t, _)| *t)
        .collect();
    for w in times.windows(2) {
        let gap = w[1] - w[0];
        assert!(
            gap < WATCHDOG,
            "pings {gap:?} apart, watchdog period {WATCHDOG:?}"
        );
    }

    // Stall the real-time thread inside cycle(): the pings stop.
    stall.store(true, Ordering::Release);
    // One look may still see the ticks made before the stall.
    let settling = mgr.collect(PING * 5 / 2).await;
    let seq = ctl.snapshot().tick.sequence;
    let stalled = mgr.collect(Duration::from_millis(2500)).await;
    assert_eq!(
        ctl.snapshot().tick.sequence,
        seq,
        "the test bus did not stall the real-time thread"
    );
    assert_eq!(
        count(&stalled, "WATCHDOG=1"),
        0,
        "pings while the real-time thread is stalled: {stalled:?}"
    );
    let all: Vec<_> = settling.iter().chain(&stalled).collect();
    assert!(
        all.iter()
            .any(|(_, l)| l == "STATUS=real-time thread stalled"),
        "{all:?}"
    );

    // Let go: the pings come back.
    stall.store(false, Ordering::Release);
    let resumed = mgr.collect(Duration::from_millis(2500)).await;
    assert!(
        count(&resumed, "WATCHDOG=1") >= 3,
        "pings did not resume: {resumed:?}"
    );
    assert!(
        resumed.iter().any(|(_, l)| l == "STATUS=running"),
        "{resumed:?}"
    );

    sup.stop();
    shut_down(ctl, &dir).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn no_ready_while_the_drives_are_faulted_at_start_up() {
    let Supervised {
        dir,
        mgr,
        switch: faulted,
        ctl,
        sup,
    } = supervised("notify-fault", WhileOn::FaultY, true);

    let msgs = mgr.collect(Duration::from_secs(3)).await;
    assert_eq!(ctl.snapshot().state, MachineState::Fault);
    assert_eq!(
        count(&msgs, "READY=1"),
        0,
        "READY=1 with faulted drives: {msgs:?}"
    );
    assert!(!sup.ready.is_finished());
    assert!(
        msgs.iter()
            .any(|(_, l)| l.starts_with("STATUS=drive fault during start-up (axis Y)")),
        "{msgs:?}"
    );
    // The real-time thread ticks in Fault: the process is alive, the watchdog is fed.
    assert!(count(&msgs, "WATCHDOG=1") >= 4, "{msgs:?}");

    // The operator clears the cause and resets before systemd's start timeout: ready.
    faulted.store(false, Ordering::Release);
    ctl.reset().unwrap();
    mgr.wait_for("READY=1", Duration::from_secs(10)).await;
    assert_eq!(ctl.snapshot().state, MachineState::Idle);
    assert!(
        sup.ready.await.unwrap(),
        "the readiness task says it did not report"
    );

    sup.watchdog.as_ref().unwrap().abort();
    shut_down(ctl, &dir).await;
}

/// A configuration for a `cncd` child: any free loopback port, data files in `dir`.
fn test_config(dir: &Path) -> String {
    format!(
        "[api]\nlisten = \"127.0.0.1:0\"\n[hmi]\nlisten = \"127.0.0.1:0\"\n[rt]\nlock_memory = false\n[storage]\ndir = {:?}\n",
        dir.join("data")
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cncd_binary_notifies_ready_pings_and_stops_on_sigterm() {
    let (bin, dir, path, cfg) = cncd_scratch("notify-bin");
    let mgr = Manager::bind(&path);
    let child = spawn_cncd(&bin, &dir, &cfg, &path, Some(WATCHDOG));
    let pid = child.id() as libc::pid_t;
    // The checks run in a task so that a failed one still lets us reap cncd and show its log.
    let checks = tokio::spawn(async move {
        let start = mgr.wait_for("READY=1", Duration::from_secs(20)).await;
        assert!(
            start.iter().any(
                |l| l.starts_with("STATUS=axes XYZ on bus sim, API on 127.0.0.1:")
                    && l.ends_with("data/cncd.sock")
            ),
            "{start:?}"
        );
        let msgs = mgr.collect(Duration::from_secs(3)).await;
        assert!(count(&msgs, "WATCHDOG=1") >= 4, "{msgs:?}");
        // SAFETY: signalling our own child.
        assert_eq!(unsafe { libc::kill(pid, libc::SIGTERM) }, 0);
        mgr.wait_for("STOPPING=1", Duration::from_secs(10)).await;
    });
    let ((), log) = reap(child, checks.await).await;
    assert!(log.contains("drives operational"), "{log}");
    assert!(log.contains("axis at rest"), "{log}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Starts `cncd` with stderr into `stderr_file`, `JOURNAL_STREAM` as given, and a fake notify
/// socket; waits for READY=1, stops it with SIGTERM. Returns cncd's pid and what it wrote to
/// stderr.
async fn run_with_journal_stream(
    name: &str,
    stream: impl Fn(&std::fs::Metadata) -> String,
) -> (u32, String) {
    let (bin, dir, path, cfg) = cncd_scratch(name);
    let log_path = dir.join("stderr.log");
    let log = std::fs::File::create(&log_path).unwrap();
    let meta = log.metadata().unwrap();
    let mgr = Manager::bind(&path);
    let mut child = Command::new(&bin)
        .arg("--config")
        .arg(&cfg)
        .env("NOTIFY_SOCKET", &path)
        .env("JOURNAL_STREAM", stream(&meta))
        .env_remove("WATCHDOG_USEC")
        .stdout(Stdio::null())
        .stderr(Stdio::from(log))
        .current_dir(&dir)
        .spawn()
        .unwrap();
    let pid = child.id();
    // The manager stays bound until cncd has exited (it sends STOPPING=1 on the way out).
    let ready = tokio::spawn(async move {
        mgr.wait_for("READY=1", Duration::from_secs(20)).await;
        mgr
    })
    .await;
    // SAFETY: signalling our own child.
    unsafe { libc::kill(pid as libc::pid_t, libc::SIGTERM) };
    let status = child.wait().unwrap();
    let text = std::fs::read_to_string(&log_path).unwrap();
    if let Err(e) = ready {
        eprintln!("cncd stderr:\n{text}");
        std::panic::resume_unwind(e.into_panic());
    }
    assert!(status.success(), "cncd exit {status}:\n{text}");
    let _ = std::fs::remove_dir_all(&dir);
    (pid, text)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn logs_go_to_the_journal_only_when_stderr_is_the_journal_stream() {
    use std::os::unix::fs::MetadataExt as _;
    // JOURNAL_STREAM names another stream (inherited, stderr redirected): plain stderr.
    let (_, text) =
        run_with_journal_stream("journal-other", |m| format!("{}:{}", m.dev(), m.ino() + 1)).await;
    assert!(text.contains("cncd started"), "{text}");
    assert!(text.contains("axis at rest"), "{text}");
    assert!(!text.contains("cannot log to the journal"), "{text}");

    // JOURNAL_STREAM names our stderr: systemd connected it to the journal.
    let (pid, text) =
        run_with_journal_stream("journal-ours", |m| format!("{}:{}", m.dev(), m.ino())).await;
    let journald = std::os::unix::net::UnixDatagram::unbound()
        .and_then(|u| u.connect("/run/systemd/journal/socket"))
        .is_ok();
    if journald {
        // A journald runs here: the events went there, with their fields, not to stderr.
        assert!(!text.contains("cncd started"), "{text}");
        let out = Command::new("journalctl")
            .args(["--no-pager", "-o", "json", "-t", "cncd"])
            .arg(format!("_PID={pid}"))
            .output();
        match out {
            Ok(o) if o.status.success() => {
                let json = String::from_utf8_lossy(&o.stdout);
                assert!(json.contains("\"MESSAGE\":\"axis at rest\""), "{json}");
                assert!(json.contains("\"CNC_AXIS\":\"X\""), "{json}");
                assert!(json.contains("\"CNC_BLOCK\":\"-\""), "{json}");
            }
            _ => eprintln!("journalctl unavailable: fields not checked"),
        }
    } else {
        // No journald to talk to: cncd says so and falls back to stderr.
        assert!(text.contains("cannot log to the journal"), "{text}");
        assert!(text.contains("cncd started"), "{text}");
    }
}

/// `systemctl stop` with an HMI watching: SIGTERM brakes the axes, then every open status and
/// alarm stream ends cleanly (its last message, then the end of the stream, no transport
/// error) and cncd exits 0 — without the fix the open stream kept it alive until SIGKILL
/// (issue #19). The systemd VM suite checks the same under a real systemd.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_ends_open_streams_and_cncd_exits() {
    use proto::v1 as pb;
    use proto::v1::machine_client::MachineClient;

    let (bin, dir, path, cfg) = cncd_scratch("stop-streams");
    let mgr = Manager::bind(&path);
    let child = spawn_cncd(&bin, &dir, &cfg, &path, None);
    let pid = child.id() as libc::pid_t;
    let socket = dir.join("data/cncd.sock");
    let checks = tokio::spawn(async move {
        mgr.wait_for("READY=1", Duration::from_secs(20)).await;
        let ch = tonic::transport::Endpoint::from_shared(format!("unix:{}", socket.display()))
            .unwrap()
            .connect()
            .await
            .unwrap();
        let mut m = MachineClient::new(ch);
        let mut status = m
            .stream_status(pb::StatusRequest { rate_hz: 10 })
            .await
            .unwrap()
            .into_inner();
        let mut alarms = m
            .stream_alarms(pb::StreamAlarmsRequest { skip_history: true })
            .await
            .unwrap()
            .into_inner();
        // The status stream is live before the stop.
        assert!(status.message().await.unwrap().is_some());
        // SAFETY: signalling our own child.
        assert_eq!(unsafe { libc::kill(pid, libc::SIGTERM) }, 0);
        mgr.wait_for("STOPPING=1", Duration::from_secs(10)).await;
        let mut last = None;
        while let Some(s) = status
            .message()
            .await
            .unwrap_or_else(|e| panic!("status stream ended with an error: {e}"))
        {
            last = Some(s);
        }
        let alarm_end = alarms.message().await;
        assert!(matches!(alarm_end, Ok(None)), "alarm stream: {alarm_end:?}");
        last.expect("a status after SIGTERM")
    });
    let (last, log) = reap(child, checks.await).await;
    // The last status the HMI saw is the machine at rest, after the brake.
    assert_eq!(last.path_velocity_mm_s, 0.0, "{last:?}");
    let rest = log.find("axis at rest").expect("axis at rest logged");
    let stopped = log.find("cncd stopped").expect("cncd stopped logged");
    assert!(rest < stopped, "{log}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A scratch directory `name` with a `cncd` configuration in it ([`test_config`]): the cncd
/// binary, the directory, the fake notify socket's path and the configuration file.
fn cncd_scratch(name: &str) -> (PathBuf, PathBuf, PathBuf, PathBuf) {
    let bin = cncd_binary();
    let dir = scratch(name);
    let path = dir.join("notify.sock");
    let cfg = dir.join("cncd.toml");
    std::fs::write(&cfg, test_config(&dir)).unwrap();
    (bin, dir, path, cfg)
}

/// `cncd` on `cfg` in `dir`, notifying `notify`, its log on stderr (piped); with `watchdog`,
/// supervised by a watchdog of that period.
fn spawn_cncd(
    bin: &Path,
    dir: &Path,
    cfg: &Path,
    notify: &Path,
    watchdog: Option<Duration>,
) -> std::process::Child {
    let mut cmd = Command::new(bin);
    cmd.arg("--config")
        .arg(cfg)
        .args(["--log", "stderr"])
        .env("NOTIFY_SOCKET", notify)
        .env_remove("WATCHDOG_USEC")
        .env_remove("WATCHDOG_PID")
        .env_remove("JOURNAL_STREAM")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .current_dir(dir);
    if let Some(w) = watchdog {
        cmd.env("WATCHDOG_USEC", w.as_micros().to_string());
    }
    cmd.spawn().unwrap()
}

/// Reaps `child` after the checks that signalled it ended with `outcome`: waits for its exit
/// (a hang bound: killed after 30 s), shows its log when a check failed and fails the test
/// with that check, then asserts exit status 0. Returns what the checks gave and the log.
async fn reap<T>(
    mut child: std::process::Child,
    outcome: Result<T, tokio::task::JoinError>,
) -> (T, String) {
    let status = wait_exit(&mut child, Duration::from_secs(30)).await;
    let output = child.wait_with_output().unwrap();
    let log = String::from_utf8_lossy(&output.stderr).into_owned();
    let checked = match outcome {
        Ok(checked) => checked,
        Err(p) => {
            eprintln!("cncd log:\n{log}");
            std::panic::resume_unwind(p.into_panic());
        }
    };
    let status = status.unwrap_or_else(|| panic!("cncd did not exit after SIGTERM:\n{log}"));
    assert!(status.success(), "cncd exit {status}:\n{log}");
    (checked, log)
}

/// Waits up to `limit` for `child` to exit; kills it when it does not (then `None`).
async fn wait_exit(
    child: &mut std::process::Child,
    limit: Duration,
) -> Option<std::process::ExitStatus> {
    let deadline = Instant::now() + limit;
    loop {
        if let Some(s) = child.try_wait().unwrap() {
            return Some(s);
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            return None;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}
