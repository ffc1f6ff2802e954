//! Sample programs of the repository run end to end on the simulated machine, in simulated
//! time: the daemon's pipeline and RT core stepped in one thread (`runtime::harness`), so
//! nothing here depends on the load of the machine running the tests.

use daemon::runtime::clock::SimClock;
use daemon::runtime::harness::{Harness, JobEnd};
use daemon::runtime::rt::RtCommand;
use tests::RecordingBus;

/// Ticks any of these programs may take (about 2 hours of machining): a bound, not a timing.
const MAX_TICKS: u64 = 2_000_000;

/// The daemon's pipeline and RT core on one thread, with a jittery seeded clock that now and
/// then misses deadlines (the setpoints must not care).
fn machine(cfg: daemon::runtime::config::Config, bus: impl hal::DriveBus + 'static) -> Harness {
    Harness::new(cfg, Box::new(bus), SimClock::seeded(20, 500_000, 200)).unwrap()
}

fn run_to_end(h: &mut Harness, name: &str, text: &str) {
    let end = h
        .run_program(text, MAX_TICKS)
        .unwrap_or_else(|e| panic!("{name}: {e:?}"));
    assert_eq!(end, JobEnd::Finished, "{name}: {:?}", h.snapshot());
}

/// MIKROPROG template (issue #4): a 10 mm cutter (D1 = 5 mm, written by G92 in the program)
/// runs outside the contour; the tool centre on the first side (N50, X0 from Y0 to Y20, moving
/// +Y with G41) is 5 mm to the left of it, at X-5.
#[test]
fn mikroprog_template_runs_compensated() {
    let text = std::fs::read_to_string("../programs/mikroprog_template.nc").unwrap();
    let mut cfg = tests::test_config();
    cfg.axes[0].home_mm = -30.0;
    let sim = sim::SimBus::new(sim::SimDriveParams::default(), &[-30.0, 0.0, 0.0]);
    let (bus, record) = RecordingBus::new(sim);
    let mut h = machine(cfg, bus);
    run_to_end(&mut h, "mikroprog_template.nc", &text);
    let s = h.snapshot();
    assert!((s.axes.commanded[0] + 30.0).abs() < 1e-9 && s.axes.commanded[1].abs() < 1e-9);
    let points = record.lock().unwrap().clone();
    let side: Vec<&[f64; 6]> = points
        .iter()
        .filter(|p| p[1] > 2.0 && p[1] < 18.0 && p[0] < 0.0)
        .collect();
    assert!(side.len() > 10, "no setpoints along N50");
    for p in side {
        assert!(
            (p[0] + 5.0).abs() < 1e-6,
            "tool centre off the equidistant: {p:?}"
        );
    }
    // Nothing is ever commanded inside the template (0 < X < 80, 0 < Y < 40 well inside).
    assert!(
        !points
            .iter()
            .any(|p| p[0] > 5.0 && p[0] < 35.0 && p[1] > 5.0 && p[1] < 35.0),
        "the cutter entered the template"
    );
    // G92 D1 R0=5.0 wrote the memory table only (SPEC §3 c).
    let offsets = h.offsets();
    let offsets = offsets.lock().unwrap();
    let entry = offsets.memory().entry(1).copied().unwrap_or_default();
    assert_eq!(entry.values()[0], 5.0);
    assert!(
        !offsets.file_text().contains("01:"),
        "G92 must not touch the file"
    );
}

/// The README's sample program.
#[test]
fn readme_sample_program_runs() {
    let text = std::fs::read_to_string("../programs/sample.nc").unwrap();
    let cfg = tests::test_config();
    let bus = sim::SimBus::new(sim::SimDriveParams::default(), &[0.0; 3]);
    let mut h = machine(cfg, bus);
    run_to_end(&mut h, "sample.nc", &text);
    let s = h.snapshot();
    assert_eq!(&s.axes.commanded.0[..3], &[0.0, 0.0, 5.0]);
}

/// A simulated lathe X (programmed as a diameter) Z at Ø300 Z100, recording every setpoint
/// and spindle speed. Setpoints are machine coordinates: X is the radius.
fn lathe() -> (Harness, tests::Recording, tests::SpindleRecording) {
    let mut cfg = tests::test_config();
    cfg.axes = vec![
        daemon::runtime::config::AxisConfig::new('X'),
        daemon::runtime::config::AxisConfig::new('Z'),
    ];
    cfg.kr.radius_input = daemon::runtime::config::RadiusInputConfig::Diameter;
    cfg.axes[0].home_mm = 150.0;
    cfg.axes[1].home_mm = 100.0;
    let sim = sim::SimBus::new(sim::SimDriveParams::default(), &[150.0, 100.0]);
    let (bus, record, spindle) = RecordingBus::with_spindle(sim);
    (machine(cfg, bus), record, spindle)
}

/// Runs `text` on the lathe; returns the setpoints and spindle speeds of the run.
fn run_recorded(
    h: &mut Harness,
    record: &tests::Recording,
    spindle: &tests::SpindleRecording,
    text: &str,
) -> (Vec<[f64; hal::MAX_AXES]>, Vec<f64>) {
    let both = || (record.lock().unwrap(), spindle.lock().unwrap());
    {
        let (mut r, mut s) = both();
        r.clear();
        s.clear();
    }
    run_to_end(h, "lathe.nc", text);
    let (r, s) = both();
    assert_eq!(r.len(), s.len());
    (r.clone(), s.clone())
}

/// Constant cutting speed on a simulated lathe (issue #7): facing from Ø300 to Ø50 under G96
/// at 90 m/min, the spindle setpoint follows n = v/(π·d) every tick, clamped by G76; it reaches
/// the drives through the bus; M5 stops it.
#[test]
fn lathe_facing_under_g96_follows_the_diameter() {
    let (mut h, record, spindle) = lathe();
    let text = "\
N10 G0 X300 Z1 M41 M3 S500
N15 G76 S400
N20 G96 G1 X50 F2000 S900
N30 G94 G0 X300 Z50 S500
N40 M5
";
    let (points, rpm) = run_recorded(&mut h, &record, &spindle, text);
    let v_mm_min = 90_000.0; // S900 = 90 m/min (S in 0.1 m/min, SPEC §6)
    let mut checked = 0;
    let mut clamped = 0;
    for (i, p) in points.iter().enumerate().skip(1) {
        let d = 2.0 * p[0]; // the setpoint is the radius
        let facing = (p[1] - 1.0).abs() < 1e-9 && d < 299.0 && d > 50.0;
        let moving = points[i - 1][0] != p[0];
        if facing && moving {
            let expect = (v_mm_min / (std::f64::consts::PI * d)).min(400.0);
            assert!(
                (rpm[i] - expect).abs() <= 1e-6 * expect,
                "tick {i}: Ø{d} spindle {} rpm, expected {expect}",
                rpm[i]
            );
            checked += 1;
            clamped += usize::from(expect == 400.0);
        }
    }
    assert!(checked > 100, "only {checked} facing ticks");
    assert!(clamped > 10, "the G76 limit was never reached");
    // M5 at the end stops the spindle.
    assert_eq!(*rpm.last().unwrap(), 0.0);
    assert_eq!(h.snapshot().spindle.rpm, 0.0);
}

/// Spindle speeds of the facing ticks of a run (X moving at Z1), with the carriage diameter
/// (twice the X setpoint, a radius).
fn facing_ticks(points: &[[f64; hal::MAX_AXES]], rpm: &[f64]) -> Vec<(f64, f64)> {
    (1..points.len())
        .filter(|&i| {
            let p = points[i];
            (p[1] - 1.0).abs() < 1e-9 && points[i - 1][0] != p[0] && 2.0 * p[0] < 299.0
        })
        .map(|i| (2.0 * points[i][0], rpm[i]))
        .collect()
}

/// KŘR at the tool tip (issue #7, SPEC §6 version 2): the same G96 facing with a tool whose X
/// length offset is Ø20 (written by G92, selected by &1) runs the carriage Ø20 further out,
/// but the spindle speed follows the tip diameter: the same speeds at the same tip positions.
/// With EXT_AKRR_SUPORT set by the PLC, the speed follows the carriage diameter instead.
#[test]
fn lathe_g96_speed_follows_the_tool_tip_and_ext_akrr_suport_the_carriage() {
    let (mut h, record, spindle) = lathe();
    let plain = "\
N10 G0 X300 Z1 M41 M3 S500
N20 G96 G1 X50 F2000 S900
N30 G94 G0 Z50 S500
";
    let offset = "\
N5 G92 D1 R1=20
N10 G0 X300 Z1 M41 M3 S500 &1
N20 G96 G1 X50 F2000 S900
N30 G94 G0 Z50 S500 &0
";
    let v_mm_min = 90_000.0;
    let check = |ticks: &[(f64, f64)], diameter_of: &dyn Fn(f64) -> f64, what: &str| {
        assert!(
            ticks.len() > 100,
            "{what}: only {} facing ticks",
            ticks.len()
        );
        for &(x, n) in ticks {
            let expect = v_mm_min / (std::f64::consts::PI * diameter_of(x));
            assert!(
                (n - expect).abs() <= 1e-6 * expect,
                "{what}: carriage X{x}: spindle {n} rpm, expected {expect}"
            );
        }
    };

    let (points, rpm) = run_recorded(&mut h, &record, &spindle, plain);
    let no_offset = facing_ticks(&points, &rpm);
    check(&no_offset, &|x| x, "without offset");

    let (points, rpm) = run_recorded(&mut h, &record, &spindle, offset);
    let with_offset = facing_ticks(&points, &rpm);
    // The carriage went to Ø320 .. Ø70: the tip to Ø300 .. Ø50.
    assert!(with_offset.iter().all(|&(x, _)| x > 69.999));
    assert!(with_offset.iter().any(|&(x, _)| x < 75.0));
    check(&with_offset, &|x| x - 20.0, "tip with offset");

    // The PLC asks for the carriage (AKRR_CNTR bit 5, EXT_AKRR_SUPORT).
    let suport = kernel::plc::PlcWrite::by_name("AKRR_CNTR", 1 << 5).unwrap();
    h.send(RtCommand::Plc(suport)).unwrap();
    let (points, rpm) = run_recorded(&mut h, &record, &spindle, offset);
    let at_carriage = facing_ticks(&points, &rpm);
    check(&at_carriage, &|x| x, "carriage with EXT_AKRR_SUPORT");
}

/// A spindle started in a block without motion runs from that block on, before the first
/// cut (which waits for it to be at speed); a program of technology blocks alone (`M5`)
/// reaches the spindle too (a zero-length segment carries its state).
#[test]
fn spindle_started_without_motion_runs_before_the_first_cut() {
    let (mut h, record, spindle) = lathe();
    let (points, rpm) = run_recorded(
        &mut h,
        &record,
        &spindle,
        "N10 M3 S1000\nN20 M41\nN30 G1 X250 F2000\n",
    );
    let first_motion = (1..points.len())
        .find(|&i| points[i] != points[i - 1])
        .expect("motion");
    let first_spindle = rpm.iter().position(|&n| n > 0.0).expect("spindle on");
    assert!(
        first_spindle < first_motion,
        "spindle at {first_spindle}, motion at {first_motion}"
    );
    let (_, rpm) = run_recorded(&mut h, &record, &spindle, "N10 M5\n");
    assert_eq!(rpm.last(), Some(&0.0), "M5 alone stops the spindle");
}
