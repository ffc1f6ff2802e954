//! Diameter programming on a lathe (issue #17, docs/lathe.md): with `[kr] radius_input =
//! "diameter"` the controlling axis X is programmed as a diameter everywhere — its words, the
//! X length of the offset table — while a relative arc centre I is a radius. The interpreter
//! halves the diameters, so compensation, planning and the setpoints work in the true (radius)
//! geometry: a tool nose R0.8 is 0.8 mm off the contour radially as well as axially.
//!
//! Checked through the daemon's machine setup and pipeline (programmed and tool-centre blocks)
//! and through the run in the single-threaded harness (every setpoint).

use daemon::runtime::clock::SimClock;
use daemon::runtime::config::{AxisConfig, Config, RadiusInputConfig};
use daemon::runtime::harness::{Harness, JobEnd};
use daemon::runtime::rt::MachineState;
use kernel::block::{Block, BlockKind, Path};
use kernel::comp::CompBlock;
use kernel::pipeline::{self, Flow, Observer, Options};
use kernel::plan::Segment;

/// A bound on the ticks of a run (not a timing).
const MAX_TICKS: u64 = 2_000_000;
/// The acceptance tolerance: 1 µm.
const TOL_MM: f64 = 1e-3;

/// A turned profile written in diameter: face, taper, R5 arc, cylinder, shoulder, under tool
/// nose compensation R0.8 (G92 writes entry 1: R0.8, X length Ø4, Z length 1).
const PROFILE_DIAMETER: &str = "\
N5 G92 D1 R0=0.8 R1=4 R2=1
N10 G0 X100 Z5 M3 S800 &1
N20 G42 D1 G1 X10 Z2 F300
N30 Z0
N40 X20
N50 X30 Z-15
N60 G3 X40 Z-20 I5 J0
N70 G1 Z-40
N80 X60
N90 G40 G1 X100 Z5
N100 M5
";

/// The same profile in radius: every X (and the X length) halved; I is a radius either way.
const PROFILE_RADIUS: &str = "\
N5 G92 D1 R0=0.8 R1=2 R2=1
N10 G0 X50 Z5 M3 S800 &1
N20 G42 D1 G1 X5 Z2 F300
N30 Z0
N40 X10
N50 X15 Z-15
N60 G3 X20 Z-20 I5 J0
N70 G1 Z-40
N80 X30
N90 G40 G1 X50 Z5
N100 M5
";

/// A lathe X, Z at X150 Z100 (machine coordinates: X is the radius, Ø300); R67 = 1 (X).
fn lathe_config(radius_input: RadiusInputConfig) -> Config {
    let mut cfg = tests::test_config();
    cfg.axes = vec![AxisConfig::new('X'), AxisConfig::new('Z')];
    cfg.axes[0].home_mm = 150.0;
    cfg.axes[1].home_mm = 100.0;
    cfg.kr.radius_input = radius_input;
    tests::save_lathe_constants(&cfg, false);
    cfg
}

fn lathe(radius_input: RadiusInputConfig) -> (Harness, tests::Recording) {
    let bus = sim::SimBus::new(sim::SimDriveParams::default(), &[150.0, 100.0]);
    let (bus, record) = tests::RecordingBus::new(bus);
    let h = Harness::new(
        lathe_config(radius_input),
        Box::new(bus),
        SimClock::seeded(17, 0, 0),
    )
    .unwrap();
    (h, record)
}

/// What the stages produce for a program: programmed and tool-centre motion blocks.
#[derive(Default)]
struct Stages {
    programmed: Vec<Block>,
    compensated: Vec<Block>,
    errors: Vec<String>,
}

impl Observer for Stages {
    fn programmed(&mut self, b: &Block, _: &kernel::program::Modal) {
        if matches!(b.kind, BlockKind::Motion { .. }) {
            self.programmed.push(*b);
        }
    }
    fn compensated(&mut self, c: &CompBlock) {
        if matches!(c.block.kind, BlockKind::Motion { .. }) {
            self.compensated.push(c.block);
        }
    }
    fn segment(&mut self, _: &Segment) -> Flow {
        Flow::Go
    }
    fn diagnostic(&mut self, d: kernel::diag::Diagnostic) -> Flow {
        if d.is_error() {
            self.errors.push(format!("{d:?}"));
        }
        Flow::Go
    }
}

/// Interprets, compensates and plans `text` with the machine setup the daemon builds.
fn stages(h: &Harness, text: &str) -> Stages {
    let setup = h.machine_setup().unwrap();
    let mut s = Stages::default();
    pipeline::run(text, &setup, Options::default(), &mut s);
    assert!(s.errors.is_empty(), "{:?}", s.errors);
    s
}

/// Start, end and (arcs) centre of a motion block.
fn points(b: &Block) -> Vec<[f64; 2]> {
    let BlockKind::Motion { start, end, path } = b.kind else {
        panic!("not a motion: {b:?}");
    };
    let mut p = vec![[start[0], start[1]], [end[0], end[1]]];
    if let Path::Arc { center, .. } = path {
        p.push([center[0], center[1]]);
    }
    p
}

fn assert_same_blocks(a: &[Block], b: &[Block], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: block counts");
    for (x, y) in a.iter().zip(b) {
        assert_eq!(x.n, y.n, "{what}");
        assert_eq!(
            std::mem::discriminant(&x.kind),
            std::mem::discriminant(&y.kind)
        );
        for (p, q) in points(x).iter().zip(points(y).iter()) {
            for k in 0..2 {
                assert!(
                    (p[k] - q[k]).abs() <= TOL_MM,
                    "{what} N{:?}: {p:?} vs {q:?}",
                    x.n
                );
            }
        }
    }
}

/// Runs `text` to its end; the setpoints of every tick.
fn run(h: &mut Harness, record: &tests::Recording, text: &str) -> Vec<[f64; hal::MAX_AXES]> {
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    record.lock().unwrap().clear();
    let end = h.run_program(text, MAX_TICKS).unwrap();
    assert!(matches!(end, JobEnd::Finished), "{end:?}");
    record.lock().unwrap().clone()
}

/// Acceptance: the profile in diameter mode equals the profile in radius mode with X halved —
/// through interpretation, compensation (tool nose R0.8) and the run, within 1 µm.
#[test]
fn diameter_profile_equals_radius_profile_with_x_halved() {
    let (mut hd, rec_d) = lathe(RadiusInputConfig::Diameter);
    let (mut hr, rec_r) = lathe(RadiusInputConfig::Radius);
    let d = stages(&hd, PROFILE_DIAMETER);
    let r = stages(&hr, PROFILE_RADIUS);
    assert_eq!(d.programmed.len(), 9);
    assert_same_blocks(&d.programmed, &r.programmed, "programmed");
    assert_same_blocks(&d.compensated, &r.compensated, "tool centre");
    // The taper ends at Ø30 Z-15 plus the length offset (Ø4 → 2 mm radially, Z 1).
    let taper = d.programmed.iter().find(|b| b.n == Some(50)).unwrap();
    assert_eq!(points(taper)[1], [15.0 + 2.0, -15.0 + 1.0]);

    let sd = run(&mut hd, &rec_d, PROFILE_DIAMETER);
    let sr = run(&mut hr, &rec_r, PROFILE_RADIUS);
    assert_eq!(sd.len(), sr.len(), "tick counts");
    assert!(sd.len() > 1000);
    for (i, (p, q)) in sd.iter().zip(&sr).enumerate() {
        assert!(
            (p[0] - q[0]).abs() <= TOL_MM && (p[1] - q[1]).abs() <= TOL_MM,
            "tick {i}: {p:?} vs {q:?}"
        );
    }
    // The run ends where the program does: Ø100 = radius 50 (+2 length offset), Z 5 (+1).
    let last = sd.last().unwrap();
    assert!((last[0] - 52.0).abs() < 1e-9 && (last[1] - 6.0).abs() < 1e-9);
}

/// The case seen in the issue: `N20 G42 D1 G1 X50 Z0` with R = 0.8 and a quarter arc written in
/// diameter. The tool centre runs 0.8 mm radially off the cylinder Ø50 (Ø50 ± 1.6 on the DRO),
/// the arc (Ø50 Z-20 → Ø60 Z-25, I5 = radius 5) is accepted and its tool-centre radius is
/// 5 ± 0.8; the run's setpoints follow.
#[test]
fn g42_tool_nose_is_offset_its_radius_radially_in_diameter_mode() {
    let (mut h, record) = lathe(RadiusInputConfig::Diameter);
    let text = "\
N5 G92 D1 R0=0.8
N10 G0 X100 Z5
N20 G42 D1 G1 X50 Z0 F300
N30 Z-20
N40 G3 X60 Z-25 I5 J0
N50 G1 Z-40
N60 G40 G1 X100 Z5
";
    let s = stages(&h, text);
    let block = |n| {
        s.compensated
            .iter()
            .filter(move |b| b.n == Some(n))
            .map(points)
            .collect::<Vec<_>>()
    };
    // N30: the cylinder Ø50 (radius 25) with the tool centre at radius 25 ± 0.8.
    let n30 = block(30);
    assert_eq!(n30.len(), 1, "{n30:?}");
    let x = n30[0][0][0];
    assert!(
        (x - n30[0][1][0]).abs() < 1e-9,
        "N30 is a cylinder: {n30:?}"
    );
    assert!(((x - 25.0).abs() - 0.8).abs() < 1e-9, "tool centre X {x}");
    // N40: the arc about (r30, z-20), radius 5 ± 0.8 for the tool centre.
    let arcs: Vec<_> = block(40).into_iter().filter(|p| p.len() == 3).collect();
    assert!(!arcs.is_empty());
    for p in &arcs {
        assert_eq!(p[2], [30.0, -20.0]);
        let rad = |q: [f64; 2]| (q[0] - 30.0).hypot(q[1] + 20.0);
        assert!(((rad(p[0]) - 5.0).abs() - 0.8).abs() < 1e-9, "{p:?}");
        assert!(((rad(p[1]) - 5.0).abs() - 0.8).abs() < 1e-9, "{p:?}");
    }
    // The run: along N30 (after its start) the X setpoint is the tool centre radius.
    let points = run(&mut h, &record, text);
    let on_cylinder = points
        .iter()
        .filter(|p| p[1] < -1.0 && p[1] > -19.0 && (p[0] - x).abs() < 1e-9)
        .count();
    assert!(
        on_cylinder > 100,
        "only {on_cylinder} ticks on the cylinder"
    );
    assert!(
        points
            .iter()
            .all(|p| p[1] > -1.0 || p[1] < -19.0 || p[0] <= x + 1e-9)
            || points
                .iter()
                .all(|p| p[1] > -1.0 || p[1] < -19.0 || p[0] >= x - 1e-9),
        "the tool centre crossed the cylinder's equidistant"
    );
}

/// In radius mode (the default) X stays a radius: `X50` is 50 mm from the spindle axis.
#[test]
fn radius_mode_keeps_program_x() {
    let (h, _) = lathe(RadiusInputConfig::Radius);
    let s = stages(&h, "N10 G0 X50 Z5\n");
    assert_eq!(points(&s.programmed[0])[1], [50.0, 5.0]);
    let (h, _) = lathe(RadiusInputConfig::Diameter);
    let s = stages(&h, "N10 G0 X50 Z5\nN20 G91 X-10\n");
    assert_eq!(points(&s.programmed[0])[1], [25.0, 5.0]);
    // Incremental diameter: X-10 is 5 mm radially.
    assert_eq!(points(&s.programmed[1])[1], [20.0, 5.0]);
}

/// The status door: on a diameter axis `commanded_mm` is the radius (machine coordinates) and
/// `display_mm` the diameter the DRO shows (`cncctl status`: `XØ300.000`); Z is unchanged.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn diameter_axis_is_shown_as_a_diameter_in_the_status() {
    use daemon::runtime::controller::Controller;
    let bus = sim::SimBus::new(sim::SimDriveParams::default(), &[150.0, 100.0]);
    let ctl = Controller::start_with_bus(
        lathe_config(RadiusInputConfig::Diameter),
        daemon::runtime::controller::ClockKind::Monotonic,
        Box::new(bus),
    )
    .unwrap();
    tests::wait_state(&ctl, MachineState::Idle).await;
    let api = daemon::runtime::api::ApiState::new(ctl.clone()).unwrap();
    let status = api.status(&ctl.snapshot());
    let (x, z) = (&status.axes[0], &status.axes[1]);
    assert!(x.diameter && !z.diameter);
    assert_eq!((x.commanded_mm, x.display_mm), (150.0, 300.0));
    assert_eq!((z.commanded_mm, z.display_mm), (100.0, 100.0));
    ctl.shutdown();
}
