//! Probing from a program (docs/language.md, "Probing"): ISO G38.2..G38.5 and CNC836 G31
//! through the one pipeline. The planner hands the probing move over last (at rest before
//! and after), asks the observer where it ended, and the interpreter goes on from there with
//! the result in #5061.. / #5070 (ISO) or R90..R94 (CNC836).

use kernel::block::{Block, BlockKind, Path};
use kernel::comp::CompConfig;
use kernel::machine::MachineSetup;
use kernel::pipeline::{self, Flow, Observer, Options};
use kernel::plan::{PlannerConfig, Segment};
use kernel::probe::ProbeResult;
use kernel::program::{Dialect, Setup};
use kernel::units::AxesMm;
use kernel::{DiagCode, Diagnostic};

fn xyz(x: f64, y: f64, z: f64) -> AxesMm {
    let mut a = AxesMm::ZERO;
    a.0[..3].copy_from_slice(&[x, y, z]);
    a
}

fn setup(dialect: Dialect) -> MachineSetup {
    let mut p = Setup::new(&['X', 'Y', 'Z']);
    p.dialect = dialect;
    p.start = xyz(10.0, 20.0, 50.0);
    MachineSetup::from_stages(
        p,
        CompConfig::default(),
        PlannerConfig::uniform(3, 200.0, 800.0),
    )
}

/// Answers every probing move with `result` and records what came out.
#[derive(Default)]
struct Machine {
    result: Option<ProbeResult>,
    segments: Vec<Segment>,
    /// Segments handed out when each probing move was asked about.
    asked_after: Vec<usize>,
    blocks: Vec<Block>,
    errors: Vec<Diagnostic>,
}

impl Observer for Machine {
    fn segment(&mut self, s: &Segment) -> Flow {
        self.segments.push(*s);
        Flow::Go
    }
    fn programmed(&mut self, b: &Block, _: &kernel::program::Modal) {
        self.blocks.push(*b);
    }
    fn diagnostic(&mut self, d: Diagnostic) -> Flow {
        if d.is_error() {
            self.errors.push(d);
        }
        Flow::Go
    }
    fn probe(&mut self, b: &Block) -> Option<ProbeResult> {
        self.asked_after.push(self.segments.len());
        Some(self.result.unwrap_or(ProbeResult::without_machine_for(b)))
    }
}

fn run(text: &str, dialect: Dialect, result: Option<ProbeResult>) -> Machine {
    let mut m = Machine {
        result,
        ..Machine::default()
    };
    pipeline::run(text, &setup(dialect), Options::default(), &mut m);
    m
}

fn contact(trip_z: f64, stop_z: f64) -> ProbeResult {
    ProbeResult {
        tripped: true,
        trip_mm: xyz(10.0, 20.0, trip_z),
        stop_mm: xyz(10.0, 20.0, stop_z),
    }
}

fn motion_ends(m: &Machine) -> Vec<(Option<u32>, AxesMm, AxesMm)> {
    m.blocks
        .iter()
        .filter_map(|b| b.motion().map(|(s, e, _)| (b.n, s, e)))
        .collect()
}

#[test]
fn iso_g38_2_goes_on_from_where_the_probe_stopped() {
    let text = "N10 G21 G90\nN20 G38.2 Z-30 F300\nN30 G0 Z[#5063 + 5]\n\
                N40 G1 X[#5061 + 1] F500 (#5070 = 1: X11)\nN50 G1 Y[20 + #5070]\nN60 M2\n";
    let m = run(text, Dialect::Iso, Some(contact(-10.002, -10.3)));
    assert!(m.errors.is_empty(), "{:?}", m.errors);
    // The probing move was the last segment handed out when it was asked about, at rest.
    assert_eq!(m.asked_after, [1]);
    let probe = m.segments[0];
    assert!(probe.probe.is_some_and(|p| p.toward && p.must_trip));
    assert_eq!(probe.v_end_mm_s, 0.0);
    let ends = motion_ends(&m);
    // N30 starts where the axes rest and goes to the contact + 5.
    assert_eq!(ends[1].0, Some(30));
    assert_eq!(ends[1].1[2], -10.3);
    assert!((ends[1].2[2] - -5.002).abs() < 1e-9);
    assert_eq!(ends[2].2[0], 11.0);
    assert_eq!(ends[3].2[1], 21.0);
}

#[test]
fn iso_without_a_machine_reads_the_target_as_rs274_does() {
    // G38.3 (no error without contact): #5063 is the target, #5070 = 0.
    let text = "G38.3 Z-30 F300\nG0 Z[#5063 + 5 + #5070]\nM2\n";
    let m = run(text, Dialect::Iso, None);
    assert!(m.errors.is_empty(), "{:?}", m.errors);
    assert_eq!(motion_ends(&m)[1].2[2], -25.0);
    let probe = m.blocks.iter().find_map(|b| match b.kind {
        BlockKind::Motion {
            path: Path::Probe(mv),
            ..
        } => Some(mv),
        _ => None,
    });
    assert!(probe.is_some_and(|p| p.toward && !p.must_trip));
}

#[test]
fn cnc836_g31_writes_r90_to_r94() {
    let text = "N10 G31 Z-30 F300\nN20 G0 ZR92\nN30 G1 X15 F500\nN40 M30\n";
    let m = run(text, Dialect::Cnc836, Some(contact(-10.002, -10.3)));
    assert!(m.errors.is_empty(), "{:?}", m.errors);
    assert_eq!(m.asked_after, [1]);
    let ends = motion_ends(&m);
    assert_eq!(ends[1].1[2], -10.3);
    assert_eq!(ends[1].2[2], -10.002);
    // G31 is not modal: N30 is a G1 again... and the G0 of N20 stays in force before it.
    assert!(matches!(m.blocks[1].motion(), Some((_, _, Path::Rapid))));
}

#[test]
fn probing_where_it_cannot_run_is_refused() {
    let code = |text: &str, d: Dialect| run(text, d, None).errors.first().map(|e| e.code);
    assert_eq!(
        code("G38.2 Z50 F100\n", Dialect::Iso),
        Some(DiagCode::ProbeMoveInvalid)
    );
    assert_eq!(
        code("G93 G38.2 Z0 F100\n", Dialect::Iso),
        Some(DiagCode::ProbeMoveInvalid)
    );
    assert_eq!(
        code("G31 Z0 F100 M3\n", Dialect::Cnc836),
        Some(DiagCode::ProbeMoveInvalid)
    );
    assert_eq!(
        code("G31 F100\n", Dialect::Cnc836),
        Some(DiagCode::ProbeMoveInvalid)
    );
}

#[test]
fn a_restart_may_not_pass_a_probing_move() {
    let text = "N10 G38.2 Z-30 F300\nN20 G0 Z[#5063 + 5]\nN30 G1 X20 F500\nN40 M2\n";
    let mut m = Machine::default();
    let opts = Options {
        from_block: Some(30),
        ..Options::default()
    };
    pipeline::run(text, &setup(Dialect::Iso), opts, &mut m);
    assert_eq!(
        m.errors.first().map(|e| e.code),
        Some(DiagCode::RestartPastProbe)
    );
    let mut m = Machine::default();
    let opts = Options {
        from_block: Some(10),
        ..Options::default()
    };
    pipeline::run(text, &setup(Dialect::Iso), opts, &mut m);
    assert!(m.errors.is_empty(), "{:?}", m.errors);
}
