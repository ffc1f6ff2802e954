//! Radius compensation through cncd (issue #18): absolute I/J as a configuration setting read
//! by every path from text to motion, and the whole-run gouge check in validate/load.

use std::sync::Arc;

use daemon::runtime::api::preview::preview_data;
use daemon::runtime::clock::SimClock;
use daemon::runtime::config::IjSetting;
use daemon::runtime::controller::{ClockKind, ControlError, Controller};
use daemon::runtime::harness::{Harness, JobEnd};
use daemon::runtime::rt::MachineState;
use kernel::Severity;
use tests::RecordingBus;

fn controller(ij: IjSetting) -> Arc<Controller> {
    let mut cfg = tests::test_config();
    cfg.axes[0].home_mm = -30.0;
    cfg.program.ij = ij;
    let sim = sim::SimBus::new(sim::SimDriveParams::default(), &[-30.0, 0.0, 0.0]);
    Controller::start_with_bus(cfg, ClockKind::Monotonic, Box::new(sim)).unwrap()
}

/// Runs `text` to its end on the daemon's pipeline and RT core in the single-threaded harness
/// (deterministic, virtual time); the distinct setpoints commanded while it ran.
fn run(ij: IjSetting, text: &str) -> Vec<[f64; hal::MAX_AXES]> {
    let mut cfg = tests::test_config();
    cfg.axes[0].home_mm = -30.0;
    cfg.program.ij = ij;
    let sim = sim::SimBus::new(sim::SimDriveParams::default(), &[-30.0, 0.0, 0.0]);
    let (bus, record) = RecordingBus::new(sim);
    let mut h = Harness::new(cfg, Box::new(bus), SimClock::exact()).unwrap();
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    h.step();
    record.lock().unwrap().clear();
    let job = h.start_program(text).unwrap_or_else(|e| panic!("{e:?}"));
    assert_eq!(h.finish_job(job, 10_000_000).unwrap(), JobEnd::Finished);
    let mut pts = record.lock().unwrap().clone();
    pts.dedup();
    pts
}

/// An arc-heavy closed contour (convex and concave arcs, tangent and sharp junctions) as
/// program text, with I J relative to the arc start or absolute.
fn arc_contour(absolute: bool) -> String {
    // (G2 = cw, end x, end y, centre x, centre y); None = line to (x, y).
    let els: [(Option<bool>, f64, f64, f64, f64); 10] = [
        (None, 0.0, 30.0, 0.0, 0.0),
        (Some(true), 20.0, 50.0, 20.0, 30.0), // convex R20, tangent
        (Some(false), 40.0, 70.0, 20.0, 70.0), // concave R20, tangent
        (None, 70.0, 70.0, 0.0, 0.0),         // sharp corner
        (Some(true), 90.0, 50.0, 70.0, 50.0), // convex R20, tangent
        (Some(false), 80.0, 20.0, 91.0, 33.0), // concave R17.03 after a sharp corner
        (Some(true), 60.0, 0.0, 60.0, 20.0),  // convex R20
        (None, 30.0, 0.0, 0.0, 0.0),
        (Some(true), 10.0, 0.0, 20.0, 0.0), // half circle bump
        (None, 0.0, 0.0, 0.0, 0.0),
    ];
    let mut t =
        String::from("N10 G92 D1 R0=4.0\nN20 G17 D1 M3 S1000\nN30 G41\nN40 G1 X0 Y0 F500\n");
    let (mut x, mut y) = (0.0, 0.0);
    for (k, (arc, ex, ey, cx, cy)) in els.iter().enumerate() {
        let n = 50 + 10 * k;
        match arc {
            None => t += &format!("N{n} G1 X{ex} Y{ey}\n"),
            Some(cw) => {
                let g = if *cw { 2 } else { 3 };
                let (i, j) = if absolute {
                    (*cx, *cy)
                } else {
                    (cx - x, cy - y)
                };
                t += &format!("N{n} G{g} X{ex} Y{ey} I{i} J{j}\n");
            }
        }
        (x, y) = (*ex, *ey);
    }
    t += "N200 G40 G1 X-10 Y-10\nN210 G0 X-30 Y0\nN220 M5\n";
    t
}

fn template(absolute: bool) -> String {
    let text = std::fs::read_to_string("../programs/mikroprog_template.nc").unwrap();
    if !absolute {
        return text;
    }
    // The two arcs start at (0,20) and (40,25): their centres are (20,20) and (55,25).
    let abs = text
        .replace("G2 X20 Y40 I20 J0", "G2 X20 Y40 I20 J20")
        .replace("G3 X55 Y10 I15 J0", "G3 X55 Y10 I55 J25");
    assert_ne!(abs, text);
    abs
}

fn same_points(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9)
}

// Issue #18 acceptance: the MIKROPROG template and an arc-heavy contour written with relative
// and with absolute I J give identical tool paths through cncd: the compensated preview (arc
// centres in machine coordinates either way) and the setpoints of the simulated drives.
#[test]
fn absolute_ij_gives_the_same_tool_path_as_relative() {
    let rel = controller(IjSetting::Relative);
    let abs = controller(IjSetting::Absolute);
    for (name, make) in [
        ("template", template as fn(bool) -> String),
        ("arc contour", arc_contour),
    ] {
        let (t_rel, t_abs) = (make(false), make(true));
        let p_rel = preview_data(&rel, &t_rel, "", false).unwrap();
        let p_abs = preview_data(&abs, &t_abs, "", false).unwrap();
        assert!(
            p_rel.compensated.len() >= 10,
            "{name}: {} {:?}",
            p_rel.compensated.len(),
            p_rel.diagnostics
        );
        for (a, b) in [
            (&p_rel.programmed, &p_abs.programmed),
            (&p_rel.compensated, &p_abs.compensated),
        ] {
            assert_eq!(a.len(), b.len(), "{name}");
            for (x, y) in a.iter().zip(b.iter()) {
                assert_eq!((x.seq, x.kind), (y.seq, y.kind), "{name}");
                for (u, v) in [
                    (&x.start_mm, &y.start_mm),
                    (&x.end_mm, &y.end_mm),
                    (&x.center_mm, &y.center_mm),
                ] {
                    assert!(same_points(u, v), "{name} seq {}: {u:?} != {v:?}", x.seq);
                }
            }
        }
        // The other setting reads the same text as different centres: the arcs are refused.
        assert!(
            matches!(
                rel.load_program("x.nc", &t_abs),
                Err(ControlError::InvalidProgram(_))
            ),
            "{name}: absolute centres read as relative must not fit"
        );
        let (s_rel, s_abs) = (
            run(IjSetting::Relative, &t_rel),
            run(IjSetting::Absolute, &t_abs),
        );
        assert!(s_rel.len() > 100, "{name}: {} setpoints", s_rel.len());
        assert_eq!(s_rel.len(), s_abs.len(), "{name}");
        for (a, b) in s_rel.iter().zip(&s_abs) {
            assert!(same_points(a, b), "{name}: {a:?} != {b:?}");
        }
    }
    rel.shutdown();
    abs.shutdown();
}

/// Issue #18's step: r = 20, a step of 8 mm between an inside and an outside corner.
fn step_program() -> &'static str {
    "N10 G92 D1 R0=20.0\nN20 G17 D1\nN30 G41 G1 X0 Y60 F500\nN40 G1 X100\nN50 G1 Y68\n\
     N60 G1 X200\nN70 G40 G1 X230 Y160\n"
}

/// A block 1 mm long between two inside corners, tool radius 5: its equidistant loops
/// backwards into N40 whatever the corner settings.
fn loop_program() -> &'static str {
    "N10 G92 D1 R0=5.0\nN20 G17 D1\nN30 G41 G1 X0 Y0 F500\nN40 G1 X20\nN50 G1 Y1\n\
     N60 G1 X0 Y21\nN70 G40 G1 X-10 Y31\n"
}

fn gouges(d: &[kernel::Diagnostic]) -> Vec<&kernel::Diagnostic> {
    d.iter()
        .filter(|d| kernel::comp::gouge::is_gouge(d))
        .collect()
}

// Through cncd with arcs inserted at outside corners (R339 = 1): the step of issue #18 is
// trimmed (the tool centre leaves the first equidistant at (84, 80), on the inserted arc) and
// loads without a message; before, the tool centre ran 12 mm back along the step unreported.
#[test]
fn the_step_of_the_issue_loads_trimmed_and_silent() {
    let ctl = controller(IjSetting::Relative);
    ctl.set_constants(&[(339, 10005.0)]).unwrap();
    let loaded = ctl.load_program("step.nc", step_program()).unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let pd = preview_data(&ctl, step_program(), "", false).unwrap();
    let ends: Vec<(f64, f64)> = pd
        .compensated
        .iter()
        .map(|e| (e.end_mm[0], e.end_mm[1]))
        .collect();
    assert!(
        ends.iter()
            .any(|&(x, y)| (x - 84.0).abs() < 1e-9 && (y - 80.0).abs() < 1e-9),
        "{ends:?}"
    );
    // No point of the tool path lies below y = 80 left of the step (x < 100).
    assert!(
        !pd.compensated
            .iter()
            .any(|e| e.end_mm[0] < 100.0 && e.end_mm[0] > 0.0 && e.end_mm[1] < 80.0 - 1e-9),
        "{ends:?}"
    );
    ctl.shutdown();
}

// The whole-run gouge check runs in cncd's validate and load: a warning naming both blocks
// and the depth; with 6.R765 = 1 the program is refused.
#[test]
fn gouges_are_reported_by_validate_and_refused_on_request() {
    let ctl = controller(IjSetting::Relative);
    let v = ctl
        .validate_text(loop_program(), ctl.default_dialect())
        .unwrap();
    let g = gouges(&v.diagnostics);
    assert!(!v.has_errors(), "{:?}", v.diagnostics);
    assert!(g.iter().all(|d| d.severity == Severity::Warning));
    // Both blocks are named: the tool block by `block`, the contour block in the message.
    assert!(
        g.iter()
            .any(|d| d.block == Some(50) && d.message.contains("N40")),
        "{:?}",
        v.diagnostics
    );
    let loaded = ctl.load_program("loop.nc", loop_program()).unwrap();
    assert!(!gouges(&loaded.warnings).is_empty());
    // The preview reports it too.
    let pd = preview_data(&ctl, loop_program(), "", false).unwrap();
    assert!(pd.diagnostics.iter().any(|d| d.code == "gouge"));
    ctl.set_constants(&[(765, 100.0)]).unwrap(); // 6.R765 = 1
    assert_eq!(ctl.constants().decade(765, 6), 1);
    match ctl.load_program("loop.nc", loop_program()) {
        Err(ControlError::InvalidProgram(d)) => {
            assert!(
                d.iter()
                    .any(|d| d.is_error() && kernel::comp::gouge::is_gouge(d)),
                "{d:?}"
            )
        }
        Err(e) => panic!("refused for another reason: {e:?}"),
        Ok(_) => panic!("a gouging program must be refused"),
    }
    ctl.shutdown();
}
