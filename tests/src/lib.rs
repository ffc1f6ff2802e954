//! Helpers shared by the integration tests in `tests/tests/`.
//!
//! [`RecordingBus`] wraps the simulated bus and records every setpoint the real-time thread
//! sends, so tests can check the whole setpoint stream, tick by tick.

pub mod bins;
pub mod can_sim;

pub use bins::workspace_bin;

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

use hal::{BusFault, CycleCommand, CycleFeedback, DriveBus};

/// Every setpoint sent, one entry per tick (test code: a mutex on the RT thread is fine here).
pub type Recording = Arc<Mutex<Vec<[f64; hal::MAX_AXES]>>>;

/// Spindle speed setpoint of every tick, rpm.
pub type SpindleRecording = Arc<Mutex<Vec<f64>>>;

pub struct RecordingBus<B: DriveBus> {
    inner: B,
    pub record: Recording,
    pub spindle: SpindleRecording,
}

impl<B: DriveBus> RecordingBus<B> {
    pub fn new(inner: B) -> (Self, Recording) {
        let (bus, record, _) = Self::with_spindle(inner);
        (bus, record)
    }

    /// Records the spindle speed setpoints too.
    pub fn with_spindle(inner: B) -> (Self, Recording, SpindleRecording) {
        let record: Recording = Arc::default();
        let spindle: SpindleRecording = Arc::default();
        (
            RecordingBus {
                inner,
                record: record.clone(),
                spindle: spindle.clone(),
            },
            record,
            spindle,
        )
    }
}

impl<B: DriveBus> DriveBus for RecordingBus<B> {
    daemon::delegate_drive_bus!(inner: name, axes, has_spindle, enable, reset, safe_state);
    fn cycle(&mut self, cmd: &CycleCommand, fb: &mut CycleFeedback) -> Result<(), BusFault> {
        // Both locks at once (always record first), so a reader that takes them in the same
        // order sees both recordings with the same ticks.
        let mut record = self.record.lock().unwrap();
        let mut spindle = self.spindle.lock().unwrap();
        record.push(cmd.positions_mm);
        spindle.push(cmd.spindle_rpm);
        drop((record, spindle));
        self.inner.cycle(cmd, fb)
    }
}

/// A simulated bus that faults one drive when the test says so (it stores the axis; the next
/// cycle forces the fault).
pub struct FaultableBus {
    inner: sim::SimBus,
    fault_axis: Arc<AtomicUsize>,
}

impl FaultableBus {
    /// The bus and the cell to store the axis to fault in (`usize::MAX`: none).
    pub fn new(inner: sim::SimBus) -> (Self, Arc<AtomicUsize>) {
        let fault_axis = Arc::new(AtomicUsize::new(usize::MAX));
        (
            FaultableBus {
                inner,
                fault_axis: fault_axis.clone(),
            },
            fault_axis,
        )
    }
}

impl DriveBus for FaultableBus {
    daemon::delegate_drive_bus!(inner: axes, has_spindle, enable, reset);
    fn name(&self) -> &str {
        "sim"
    }
    fn cycle(&mut self, cmd: &CycleCommand, fb: &mut CycleFeedback) -> Result<(), BusFault> {
        let a = self.fault_axis.swap(usize::MAX, Ordering::Relaxed);
        if a != usize::MAX {
            self.inner.drive_mut(a).force_fault();
        }
        self.inner.cycle(cmd, fb)
    }
}

/// Per-axis finite differences of a setpoint stream: (max |v| mm/s, max |a| mm/s²) per axis.
pub fn max_rates(points: &[[f64; hal::MAX_AXES]], axes: usize, ts_s: f64) -> Vec<(f64, f64)> {
    (0..axes)
        .map(|i| {
            let v: Vec<f64> = points
                .windows(2)
                .map(|w| (w[1][i] - w[0][i]) / ts_s)
                .collect();
            let vmax = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let amax = v
                .windows(2)
                .fold(0.0f64, |m, w| m.max(((w[1] - w[0]) / ts_s).abs()));
            (vmax, amax)
        })
        .collect()
}

/// Index of the largest per-axis acceleration (for diagnosing a failed limit check).
pub fn worst_accel_at(points: &[[f64; hal::MAX_AXES]], axis: usize, ts_s: f64) -> usize {
    let v: Vec<f64> = points
        .windows(2)
        .map(|w| (w[1][axis] - w[0][axis]) / ts_s)
        .collect();
    let mut best = (0, 0.0f64);
    for (i, w) in v.windows(2).enumerate() {
        let a = ((w[1] - w[0]) / ts_s).abs();
        if a > best.1 {
            best = (i, a);
        }
    }
    best.0
}

/// The default (simulated mill) configuration with its data files in a fresh temporary
/// directory, so tests never touch the working tree or each other.
/// Serves the API of `ctl` on a Unix socket in its data directory, the way the shop's own
/// tools reach cncd (callers without a token get `api.local_role`, admin by default; loopback
/// TCP gives only `api.loopback_role`, observer). Returns the address for tonic and cncctl,
/// `unix:/path`.
pub async fn serve_unix(ctl: &Arc<daemon::runtime::controller::Controller>) -> String {
    use daemon::runtime::server;
    let path = ctl.config().storage.dir.join("cncd.sock");
    let unix = server::bind_unix(&path, 0o600, None).expect("bind the API socket");
    let listeners = server::Listeners {
        unix: Some(unix),
        ..server::Listeners::default()
    };
    tokio::spawn(server::serve_listeners(
        ctl.clone(),
        listeners,
        std::future::pending(),
    ));
    format!("unix:{}", path.display())
}

pub fn test_config() -> daemon::runtime::config::Config {
    use std::sync::atomic::{AtomicU32, Ordering};
    static N: AtomicU32 = AtomicU32::new(0);
    let dir = std::env::temp_dir().join(format!(
        "cnc-test-{}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    let _ = std::fs::remove_dir_all(&dir);
    let mut cfg = daemon::runtime::config::Config::default();
    cfg.storage.dir = dir;
    // Not the tests' business to lock the whole test process's memory.
    cfg.rt.lock_memory = false;
    cfg
}

/// How long the waits of the threaded tests give the daemon before calling it a hang. A bound,
/// not a measurement: on a loaded 2-core CI machine threads may be starved for seconds, so the
/// waits return as soon as their condition holds and fail only after this (tests of logic
/// rather than of threads run in the single-threaded harness, `daemon::runtime::harness`).
pub const PATIENCE: std::time::Duration = std::time::Duration::from_secs(120);

/// Waits (polling the snapshot) until the machine is in `state`; fails the test after
/// [`PATIENCE`].
pub async fn wait_state(
    ctl: &daemon::runtime::controller::Controller,
    state: daemon::runtime::rt::MachineState,
) {
    let t0 = std::time::Instant::now();
    while ctl.snapshot().state != state {
        assert!(
            t0.elapsed() < PATIENCE,
            "state {:?} not reached: {:?}",
            state,
            ctl.snapshot()
        );
        tokio::time::sleep(std::time::Duration::from_millis(2)).await;
    }
}

/// Waits until job `job` ran to its end; fails the test if it was aborted or after
/// [`PATIENCE`].
pub async fn wait_job_finished(ctl: &daemon::runtime::controller::Controller, job: u32) {
    let t0 = std::time::Instant::now();
    loop {
        let s = ctl.snapshot();
        if s.progress.finished_job == job {
            return;
        }
        assert_ne!(s.progress.aborted_job, job, "job aborted: {s:?}");
        assert!(t0.elapsed() < PATIENCE, "job {job} did not finish: {s:?}");
        tokio::time::sleep(std::time::Duration::from_millis(5)).await;
    }
}

/// The daemon's pipeline and RT core in the single-threaded harness (deterministic, virtual
/// time) on the simulated bus with the axes at `at_mm`, every commanded setpoint recorded;
/// idle and stepped once, ready for a program.
pub fn recorded_harness(
    cfg: daemon::runtime::config::Config,
    at_mm: &[f64],
) -> (daemon::runtime::harness::Harness, Recording) {
    use daemon::runtime::clock::SimClock;
    use daemon::runtime::harness::Harness;
    use daemon::runtime::rt::MachineState;
    let sim = sim::SimBus::new(sim::SimDriveParams::default(), at_mm);
    let (bus, record) = RecordingBus::new(sim);
    let mut h = Harness::new(cfg, Box::new(bus), SimClock::exact()).unwrap();
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    h.step();
    (h, record)
}

/// Asserts that the harness refuses to start `text`, with an error diagnostic at block
/// `block` (`what` names the case in the failure).
pub fn assert_refused_at(
    h: &mut daemon::runtime::harness::Harness,
    text: &str,
    block: u32,
    what: &str,
) {
    use daemon::runtime::harness::HarnessError;
    match h.start_program(text) {
        Err(HarnessError::InvalidProgram(d)) => {
            assert!(
                d.iter().any(|d| d.is_error() && d.block == Some(block)),
                "{what}: {d:?}"
            );
        }
        other => panic!("{what} accepted: {other:?}"),
    }
}

/// Steps `h` until job `job` has finished, checking every tick's next deadline: on the grid of
/// `period_ns` (the clock starts at 0, so the grid is the multiples of the period), the first
/// grid point after the wake-up, so that a late tick skips `lateness / period` grid points.
/// Returns the largest lateness, ns. Fails after 100 000 ticks (a bound, not a timing).
pub fn run_on_the_grid(h: &mut daemon::runtime::harness::Harness, job: u32, period_ns: u64) -> u64 {
    let mut deadline = h.core().next_deadline_ns();
    let mut max_lateness_ns = 0;
    while h.snapshot().progress.finished_job != job {
        let s = h.step();
        let lateness = s.tick.time_ns - deadline;
        max_lateness_ns = max_lateness_ns.max(lateness);
        let next = h.core().next_deadline_ns();
        assert_eq!(next % period_ns, 0, "{s:?}");
        assert!(
            next > s.tick.time_ns && next - s.tick.time_ns <= period_ns,
            "{s:?}"
        );
        assert_eq!(next - deadline, (lateness / period_ns + 1) * period_ns);
        deadline = next;
        assert!(s.tick.sequence < 100_000, "{s:?}");
    }
    max_lateness_ns
}

/// A part program with rapids, lines, arcs (G2 and G3), a feed change, G23 continuity and block
/// ends at rest (G98): the run the harness and bus-cycle tests compare.
pub const PART: &str = "\
N10 G0 X10 Y5 Z1
N20 G1 Z-1 F600
N30 G23 X40 F3000
N40 G3 X60 Y25 I0 J20
N50 G2 X40 Y45 I-20 J0
N60 G1 X10 F1800
N70 G98 Y5
N80 G0 Z5
N90 X0 Y0
";

/// The gear table of the lathe tests: M41..M44 up to 250, 500, 1000 and 2000 rpm.
pub const LATHE_GEARS: [(u16, f64); 4] = [(41, 250.0), (42, 500.0), (43, 1000.0), (44, 2000.0)];

/// [`LATHE_GEARS`] as configuration entries (full output range).
pub fn lathe_gears() -> Vec<daemon::runtime::config::GearConfig> {
    LATHE_GEARS
        .iter()
        .map(|&(m, p)| daemon::runtime::config::GearConfig {
            max_rpm: p,
            output_range: 0x7FFF,
            m_code: Some(m),
        })
        .collect()
}

/// Saves the lathe's constants in `cfg`'s storage directory: R0 = X, R1 = Z, no other axis,
/// R67 = 1 (X is the facing axis); with `g96_per_rev`, R329 d3 = 3 (G96 is KŘR with mm/rev,
/// S in m/min).
pub fn save_lathe_constants(cfg: &daemon::runtime::config::Config, g96_per_rev: bool) {
    let mut c = kernel::constants::Constants::new();
    c.set(0, 1.0); // X
    c.set(1, 3.0); // Z
    for r in 2..6 {
        c.set(r, 0.0);
    }
    c.set(67, 1.0);
    if g96_per_rev {
        let d3 = f64::from(c.decade(329, 3));
        c.set(329, c.get(329) + (3.0 - d3) * 0.1);
    }
    std::fs::create_dir_all(&cfg.storage.dir).unwrap();
    daemon::runtime::storage::save_constants(&cfg.storage.constants_path(), &c).unwrap();
}
