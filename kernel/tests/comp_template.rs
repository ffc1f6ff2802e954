//! The MIKROPROG template example (SPEC §4, seed 002 "MIKROPROG" guide): 10 mm cutter, start
//! X-30 Y0, G41 round the outside of the template. `programs/mikroprog_template.nc` goes
//! through the real parser and the compensator; the tool-centre path is checked point by
//! point (mode R339 = 1: the guide says arcs are always inserted) and by the independent
//! path checker (mode R339 = 0, intersections).

mod comp_common;

use comp_common::*;
use kernel::block::{Block, Plane};
use kernel::comp::geom::V2;
use kernel::comp::{CompConfig, CornerMode, Role, compensate_all_traced};
use kernel::constants::Constants;
use kernel::program::{Setup, compile};
use kernel::{DiagCode, Severity};

fn template_blocks() -> Vec<Block> {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../programs/mikroprog_template.nc"
    ))
    .expect("template program");
    let mut setup = Setup::new(&['X', 'Y', 'Z']);
    setup.start[0] = -30.0;
    let c = compile(&text, &setup);
    assert!(!c.has_errors(), "{:?}", c.diagnostics);
    c.blocks
}

fn p(x: f64, y: f64) -> V2 {
    V2::new(x, y)
}

#[test]
fn template_with_inserted_arcs_follows_the_expected_tool_centre_path() {
    let blocks = template_blocks();
    let cfg = CompConfig {
        corner_mode: CornerMode::ArcAboveLimit,
        arc_insertion_limit_deg: 0.0,
        ..CompConfig::default()
    };
    let (out, diags) = compensate_all_traced(&blocks, &cfg);
    assert!(errors(&diags).is_empty(), "{diags:?}");
    let (pieces, arcs) = check_path(&blocks, &out, Plane::G17, 1e-9).unwrap();
    assert_eq!((pieces, arcs), (7, 3));
    let mv = motions(&out);
    // Direction of N100 and its left normal, for the corner points at (55,10) and (80,0).
    let d = (p(80.0, 0.0) - p(55.0, 10.0)).unit();
    let n = d.left() * 5.0;
    let expected: Vec<(Option<u32>, Role, V2, V2)> = vec![
        (Some(40), Role::StartMove, p(-30.0, 0.0), p(-5.0, 0.0)),
        (Some(50), Role::Equidistant, p(-5.0, 0.0), p(-5.0, 20.0)),
        (Some(60), Role::Equidistant, p(-5.0, 20.0), p(20.0, 45.0)),
        (Some(70), Role::Equidistant, p(20.0, 45.0), p(40.0, 45.0)),
        (Some(80), Role::CornerArc, p(40.0, 45.0), p(45.0, 40.0)),
        (Some(80), Role::Equidistant, p(45.0, 40.0), p(45.0, 25.0)),
        (Some(90), Role::Equidistant, p(45.0, 25.0), p(55.0, 15.0)),
        (Some(100), Role::CornerArc, p(55.0, 15.0), p(55.0, 10.0) + n),
        (
            Some(100),
            Role::Equidistant,
            p(55.0, 10.0) + n,
            p(80.0, 0.0) + n,
        ),
        (Some(110), Role::CornerArc, p(80.0, 0.0) + n, p(80.0, -5.0)),
        (Some(110), Role::Equidistant, p(80.0, -5.0), p(0.0, -5.0)),
        (Some(120), Role::Passthrough, p(0.0, -5.0), p(-10.0, 0.0)),
        (Some(130), Role::Passthrough, p(-10.0, 0.0), p(-30.0, 0.0)),
    ];
    assert_eq!(mv.len(), expected.len(), "{mv:#?}");
    for (got, (n, role, s, e)) in mv.iter().zip(expected) {
        assert_eq!((got.block.n, got.role), (n, role));
        let (gs, ge) = ends(&got.block, Plane::G17);
        assert_close(gs, s, 1e-9);
        assert_close(ge, e, 1e-9);
    }
    // Every block of the program is still there, in order (technology blocks included).
    let seqs: Vec<u32> = out.iter().map(|c| c.block.seq).collect();
    assert!(seqs.windows(2).all(|w| w[0] <= w[1]));
    assert_eq!(seqs.first(), Some(&0));
    assert_eq!(seqs.last(), Some(&(blocks.len() as u32 - 1)));
}

#[test]
fn template_with_intersections_and_machine_constants() {
    let blocks = template_blocks();
    let mut c = Constants::new();
    c.set(95, 10000.0);
    c.set(765, 11000.0); // R765: report and optimise beyond 300 %
    let cfg = CompConfig::from_constants(&c);
    let (out, diags) = compensate_all_traced(&blocks, &cfg);
    assert!(errors(&diags).is_empty(), "{diags:?}");
    check_path(&blocks, &out, Plane::G17, 1e-9).unwrap();
    let mv = motions(&out);
    // N70 → N80: outside 90° corner, intersection of the equidistants at (45, 45).
    let n70 = mv.iter().find(|c| c.block.n == Some(70)).unwrap();
    assert_close(ends(&n70.block, Plane::G17).1, p(45.0, 45.0), 1e-9);
    // N100 → N110 turns by 158°: the intersection lies 26 mm from the corner, beyond 300 %
    // of the radius, so R765 reports it and inserts an arc instead.
    let warn = with_severity(&diags, Severity::Warning);
    assert!(
        warn.iter()
            .any(|d| d.block == Some(110) && d.code == DiagCode::CornerFarFromEquidistant),
        "{diags:?}"
    );
    assert!(
        mv.iter()
            .any(|c| c.role == Role::CornerArc && c.block.n == Some(110))
    );
}

// SPEC §4.1 + §4.2 through the parser: the radius comes from the offset table entry selected
// by D; a negative radius swaps the side; G0 cancels and the last rapid restarts.
#[test]
fn parsed_program_with_table_radius_and_rapid_restart() {
    use kernel::offsets::OffsetEntry;
    let text = "N10 G17 D7\nN20 G42\nN30 G1 X0 Y0 F500\nN40 X20\nN50 Y20\n\
                N60 G0 X40\nN70 G0 Y0\nN80 G1 X60\nN90 G40 G1 X70\n";
    let mut setup = Setup::new(&['X', 'Y', 'Z']);
    setup.start[0] = -10.0;
    setup.start[1] = -10.0;
    setup
        .offsets
        .set_entry(
            7,
            OffsetEntry {
                radius_mm: -2.0,
                length_mm: [0.0; 4],
            },
        )
        .unwrap();
    let c = compile(text, &setup);
    assert!(!c.has_errors(), "{:?}", c.diagnostics);
    let (out, diags) = compensate_all_traced(&c.blocks, &CompConfig::default());
    assert!(errors(&diags).is_empty(), "{diags:?}");
    check_path(&c.blocks, &out, Plane::G17, 1e-9).unwrap();
    let mv = motions(&out);
    let find = |n: u32| mv.iter().find(|c| c.block.n == Some(n)).unwrap();
    // G42 with radius -2 = left by 2: N40 (+X) runs at y = +2, the inside corner at (18, 2).
    assert_eq!(find(40).offset_mm, 2.0);
    assert_close(ends(&find(40).block, Plane::G17).1, p(18.0, 2.0), 1e-12);
    // N50 ends on its perpendicular before the rapid; N60 goes to its programmed point.
    assert_close(ends(&find(50).block, Plane::G17).1, p(18.0, 20.0), 1e-12);
    assert_eq!(find(60).role, Role::Passthrough);
    assert_close(ends(&find(60).block, Plane::G17).1, p(40.0, 20.0), 0.0);
    // N70, the last rapid, restarts: perpendicular of N80 (+X, left) at (40, 0).
    assert_eq!(find(70).role, Role::StartMove);
    assert_close(ends(&find(70).block, Plane::G17).1, p(40.0, 2.0), 1e-12);
    assert_close(ends(&find(80).block, Plane::G17).1, p(60.0, 2.0), 1e-12);
}

// The template end to end in the kernel: parser → compensator → planner. Every tool-centre
// block is accepted by the planner, the planned path is continuous, follows the tool-centre
// path (point check at mid-segment for arcs) and ends back at X-30 Y0.
#[test]
fn template_runs_through_the_planner() {
    use kernel::plan::{Planner, PlannerConfig};
    let blocks = template_blocks();
    let cfg = CompConfig {
        corner_mode: CornerMode::ArcAboveLimit,
        ..CompConfig::default()
    };
    let mut comp = kernel::comp::Compensator::new(cfg);
    let mut planner = Planner::new(PlannerConfig::uniform(3, 100.0, 1000.0), 1);
    let mut segs = Vec::new();
    let mut tool_blocks = Vec::new();
    let feed = |b: Block, planner: &mut Planner, segs: &mut Vec<_>| {
        planner.push(&b).unwrap();
        while let Some(s) = planner.poll() {
            segs.push(s);
        }
    };
    for b in &blocks {
        comp.push(b).unwrap();
        while let Some(o) = comp.poll() {
            tool_blocks.push(o);
            feed(o, &mut planner, &mut segs);
        }
    }
    comp.finish();
    while let Some(o) = comp.poll() {
        tool_blocks.push(o);
        feed(o, &mut planner, &mut segs);
    }
    planner.finish();
    while let Some(s) = planner.poll() {
        segs.push(s);
    }
    assert!(comp.take_diagnostics().is_empty());
    assert!(!segs.is_empty());
    for w in segs.windows(2) {
        assert!((w[0].path.end() - w[1].path.start()).max_abs(3) < 1e-9);
    }
    let last = segs.last().unwrap().path.end();
    assert_close(V2::of(&last, Plane::G17), p(-30.0, 0.0), 1e-9);
    // Arc segments keep the compensated radii: N60 radius 25 about (20,20), N90 10 about (55,25).
    for (n, c, r) in [(60, p(20.0, 20.0), 25.0), (90, p(55.0, 25.0), 10.0)] {
        let s = segs.iter().find(|s| s.n == Some(n)).unwrap();
        let mid = V2::of(&s.path.point_at(0.5), Plane::G17);
        assert!((mid.dist(c) - r).abs() < 1e-9, "N{n}: {}", mid.dist(c));
    }
}
