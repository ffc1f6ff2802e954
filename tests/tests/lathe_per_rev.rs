//! Feed per revolution on a simulated lathe (issue #17, SPEC §5, §6): the manual's example
//! `N20 G96 G1 F200 S90 X50` (R329 d3 = 3: G96 is KŘR with mm/rev, S in m/min) runs through
//! the daemon's pipeline and RT core in the single-threaded harness, with a spindle drive that
//! ramps and a load knob. Every tick the feed follows the spindle's *actual* speed.

use daemon::runtime::clock::SimClock;
use daemon::runtime::config::{AxisConfig, Config};
use daemon::runtime::harness::Harness;
use daemon::runtime::rt::{MachineState, Snapshot};

/// A bound on the ticks of a run (about 1.1 hours of machining): not a timing.
const MAX_TICKS: u64 = 1_000_000;
/// Spindle acceleration of the simulated drive, rpm/s.
const RAMP_RPM_S: f64 = 1000.0;
/// The manual's example: 90 m/min, 0.2 mm/rev.
const V_MM_MIN: f64 = 90_000.0;
const BETA_MM_REV: f64 = 0.2;

const MANUAL_EXAMPLE: &str = "\
N10 G0 X300 Z100 M44 M3 S100
N15 Z-1
N20 G96 G1 F200 S90 X50
";

/// Lathe X (diameter), Z at X300 Z100; R67 = 1 (X), R329 d3 = 3; gears M41..M44.
fn lathe_config() -> Config {
    let mut cfg = tests::test_config();
    cfg.axes = vec![AxisConfig::new('X'), AxisConfig::new('Z')];
    // X is programmed as a diameter; machine coordinates (home, setpoints) are the radius.
    cfg.kr.radius_input = daemon::runtime::config::RadiusInputConfig::Diameter;
    cfg.axes[0].home_mm = 150.0;
    cfg.axes[1].home_mm = 100.0;
    cfg.kr.gears = tests::lathe_gears();
    tests::save_lathe_constants(&cfg, true);
    cfg
}

fn lathe() -> (Harness, sim::SpindleLoad) {
    let cfg = lathe_config();
    let bus = sim::SimBus::new(sim::SimDriveParams::default(), &[150.0, 100.0])
        .with_spindle_ramp(RAMP_RPM_S);
    let load = bus.spindle_load();
    let h = Harness::new(cfg, Box::new(bus), SimClock::seeded(17, 500_000, 200)).unwrap();
    (h, load)
}

/// Runs `text`, calling `each` after every tick with the previous and this snapshot.
fn run(h: &mut Harness, text: &str, mut each: impl FnMut(&Snapshot, &Snapshot, &mut Harness)) {
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    let job = h.start_program(text).unwrap();
    let mut prev = h.snapshot();
    for _ in 0..MAX_TICKS {
        let s = h.step();
        each(&prev, &s, h);
        prev = s;
        if s.progress.finished_job == job || s.progress.aborted_job == job {
            assert_eq!(s.progress.finished_job, job, "aborted: {s:?}");
            return;
        }
    }
    panic!("not finished: {:?}", h.snapshot());
}

/// Feed of this tick, mm/min, and the spindle speed the RT core fed from (last tick's).
fn feed_and_spindle(prev: &Snapshot, s: &Snapshot) -> (f64, f64) {
    (s.axes.path_v_mm_s * 60.0, prev.spindle.rpm)
}

fn within(a: f64, b: f64, share: f64) -> bool {
    (a - b).abs() <= share * b.abs()
}

/// The manual's example runs; along the cut v = 2π·n·r (r = X/2, X in diameter) and the feed
/// equals n_actual × 0.2 mm/rev, both within 1 %, every tick.
#[test]
fn manual_lathe_example_feeds_per_revolution_of_the_actual_spindle() {
    let (mut h, _) = lathe();
    let mut checked = 0;
    run(&mut h, MANUAL_EXAMPLE, |prev, s, _| {
        let x = 2.0 * s.axes.commanded[0]; // diameter: the setpoint is the radius
        if s.progress.block_n != Some(20) || !(60.0..290.0).contains(&x) {
            return;
        }
        let n = s.spindle.rpm;
        let v = 2.0 * std::f64::consts::PI * n * s.axes.commanded[0];
        assert!(within(v, V_MM_MIN, 0.01), "X{x}: n {n} rpm gives v {v}");
        let (feed, n_fed) = feed_and_spindle(prev, s);
        assert!(
            within(feed, n_fed * BETA_MM_REV, 0.01),
            "X{x}: feed {feed} mm/min at {n_fed} rpm"
        );
        checked += 1;
    });
    assert!(checked > 10_000, "only {checked} ticks checked");
    let s = h.snapshot();
    assert!((s.axes.commanded[0] - 25.0).abs() < 1e-9 && (s.axes.commanded[1] + 1.0).abs() < 1e-9);
}

/// With `G76 S400` the spindle is clamped at 400 rpm below Ø71.6 and the feed with it
/// (80 mm/min); a spindle slowed by load slows the feed in proportion; a stalled spindle holds
/// it (the status says it waits for the spindle) and the cut continues when it turns again.
#[test]
fn g76_clamp_load_and_a_stalled_spindle_rule_the_feed() {
    let (mut h, load) = lathe();
    let text = "\
N10 G0 X300 Z100 M44 M3 S100
N12 G76 S400
N15 Z-1
N20 G96 G1 F200 S90 X50
";
    let (mut clamped, mut loaded, mut held, mut after) = (0, 0, 0, 0);
    run(&mut h, text, |prev, s, _| {
        let x = 2.0 * s.axes.commanded[0]; // diameter
        if s.progress.block_n != Some(20) {
            return;
        }
        // The load knob: 30 % of the speed lost between Ø250 and Ø200, stalled between Ø150
        // and 149 (set as the carriage passes; the hold keeps it there until released).
        let l = if (200.0..250.0).contains(&x) {
            0.3
        } else if (149.0..150.0).contains(&x) && held < 2000 {
            1.0
        } else {
            0.0
        };
        load.set(l);
        let (feed, n_fed) = feed_and_spindle(prev, s);
        if x < 70.0 && x > 51.0 {
            assert_eq!(s.spindle.kr.spindle_rpm, 400.0, "X{x}: clamp");
            assert!(within(feed, 400.0 * BETA_MM_REV, 0.01), "X{x}: feed {feed}");
            clamped += 1;
        }
        if (205.0..245.0).contains(&x) && within(n_fed, 0.7 * s.spindle.kr.spindle_rpm, 0.005) {
            // Settled under load: the feed follows the slowed spindle.
            assert!(
                within(feed, n_fed * BETA_MM_REV, 0.01),
                "X{x}: feed {feed} at {n_fed} rpm"
            );
            loaded += 1;
        }
        if prev.spindle.rpm < 1.0 && s.axes.path_v_mm_s == 0.0 && prev.axes.path_v_mm_s == 0.0 {
            assert!(s.spindle.waiting, "X{x}: held without saying why");
            assert!((149.0..150.0).contains(&x));
            held += 1;
        }
        if x < 148.0 {
            after += 1;
        }
    });
    assert!(clamped > 1000, "clamped ticks {clamped}");
    assert!(loaded > 1000, "loaded ticks {loaded}");
    assert!(held >= 2000, "held ticks {held}");
    assert!(after > 1000, "the cut did not continue: {after}");
}

/// Gears come from `[kr.gears]`: an M code without a configured range is refused at
/// validation with its block; G95 is planned at S capped by the gear's maximum.
#[test]
fn gears_from_the_configuration() {
    let mut cfg = lathe_config();
    cfg.kr.gears.truncate(2); // M41, M42 only
    let bus = sim::SimBus::new(sim::SimDriveParams::default(), &[150.0, 100.0]);
    let mut h = Harness::new(cfg, Box::new(bus), SimClock::seeded(1, 0, 0)).unwrap();
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    tests::assert_refused_at(&mut h, "N10 M44 M3 S100\n", 10, "M44 without a gear");
    // Gear 2 caps the spindle at 500 rpm: S3000 with 1 mm/rev feeds 500 mm/min, not 3000.
    let mut top = 0.0f64;
    let job = h
        .start_program("N10 M42 M3 S3000\nN20 G95 G1 X200 F1.0\n")
        .unwrap();
    let end = h
        .run_until(MAX_TICKS, |s| {
            top = top.max(s.axes.path_v_mm_s * 60.0);
            s.progress.finished_job == job || s.progress.aborted_job == job
        })
        .unwrap();
    assert_eq!(end.progress.finished_job, job);
    assert!(within(top, 500.0, 0.01), "top feed {top} mm/min");
}

/// SPEC §5: βmax = Vmax/S. 10 mm/rev at 2000 rpm (S capped by M44's P) is 20000 mm/min, above
/// the fastest axis (12000 mm/min): a warning with the block, at validation; 5 mm/rev is not.
#[test]
fn feed_above_beta_max_is_a_warning_with_the_block() {
    let (h, _) = lathe();
    let warnings = |text: &str| {
        let setup = h.machine_setup().unwrap();
        let c = kernel::program::compile(text, setup.program());
        assert!(!c.has_errors(), "{:?}", c.diagnostics);
        c.diagnostics
            .into_iter()
            .filter(|d| d.severity == kernel::diag::Severity::Warning)
            .map(|d| d.block)
            .collect::<Vec<_>>()
    };
    assert_eq!(
        warnings("N10 M44 M3 S3000\nN20 G95 G1 X200 F10.0\n"),
        vec![Some(20)]
    );
    assert!(warnings("N10 M44 M3 S3000\nN20 G95 G1 X200 F5.0\n").is_empty());
}

/// The lathe example of the repository (`programs/lathe/`): its configuration and constants
/// load as `cncd` loads them (bus opened from the configuration: the simulated lathe with a
/// spindle ramp), and every sample program runs to its end.
#[test]
fn lathe_example_configuration_runs_its_sample_programs() {
    let dir = std::path::Path::new("../programs/lathe");
    let mut cfg = Config::load(&dir.join("cncd-lathe.toml")).unwrap();
    cfg.storage.dir = tests::test_config().storage.dir;
    cfg.rt.lock_memory = false;
    std::fs::create_dir_all(&cfg.storage.dir).unwrap();
    std::fs::copy(dir.join("TAB0.REK"), cfg.storage.constants_path()).unwrap();
    let io = daemon::runtime::buses::IoWiring::of(&cfg);
    let bus = daemon::runtime::buses::open_bus(&cfg.bus, &cfg.axes, &cfg.sim, &io).unwrap();
    let mut h = Harness::new(cfg, bus, SimClock::seeded(5, 500_000, 200)).unwrap();
    // Program, its cutting blocks, the top feed expected there, where it ends (X).
    for (name, cuts, feed_mm_min, end_x) in [
        ("manual_css.nc", &[20][..], None, 300.0),
        ("turning_g95.nc", &[20, 30][..], Some(250.0), 300.0),
        ("facing_clamped.nc", &[30][..], Some(1500.0 * 0.15), 200.0),
        ("profile_g41.nc", &[40, 70][..], Some(800.0 * 0.15), 300.0),
    ] {
        let text = std::fs::read_to_string(dir.join(name)).unwrap();
        h.wait_state(MachineState::Idle, 10_000).unwrap();
        let job = h.start_program(&text).unwrap();
        let mut top_cut = 0.0f64;
        let end = h
            .run_until(MAX_TICKS, |s| {
                if s.progress.block_n.is_some_and(|n| cuts.contains(&n)) {
                    top_cut = top_cut.max(s.axes.path_v_mm_s * 60.0);
                }
                s.progress.finished_job == job || s.progress.aborted_job == job
            })
            .unwrap();
        assert_eq!(end.progress.finished_job, job, "{name}: {end:?}");
        assert_eq!(end.spindle.kr.spindle_rpm, 0.0, "{name}: M5 at the end");
        assert!(
            (2.0 * end.axes.commanded[0] - end_x).abs() < 1e-9
                && (end.axes.commanded[1] - 100.0).abs() < 1e-9,
            "{name}: ends at Ø{end_x} Z100: {:?}",
            end.axes.commanded
        );
        if let Some(f) = feed_mm_min {
            assert!(
                within(top_cut, f, 0.01),
                "{name}: top feed {top_cut}, expected {f}"
            );
        }
    }
}
