//! The gouge rules of radius compensation (issue #18, SPEC §4.3, §4.5, docs/compensation.md
//! decisions 18 and 19): a short step between an inside and an outside corner with arcs
//! inserted never makes the tool centre run backwards or cut into the contour, and wherever the
//! tool centre does come closer than the radius to the programmed contour a warning names both
//! blocks. Distances here are computed independently of the kernel (dense samples of the tool
//! path against the exact programmed lines and arcs).

mod comp_common;

use comp_common::*;
use kernel::Severity;
use kernel::block::{Block, Path, Plane};
use kernel::comp::geom::V2;
use kernel::comp::{CompBlock, CompConfig, CornerMode, Role};

/// Every equidistant piece runs in the programmed direction.
fn never_backwards(input: &[Block], out: &[CompBlock]) -> Result<(), PathError> {
    for c in motions(out) {
        if c.role != Role::Equidistant {
            continue;
        }
        let (ps, pe) = ends(&c.block, Plane::G17);
        let b = &input[c.block.seq as usize];
        let (s, e, path) = b.motion().unwrap();
        let (a, bb) = (V2::of(&s, Plane::G17), V2::of(&e, Plane::G17));
        match (path, c.block.motion().unwrap().2) {
            (Path::Arc { dir, .. }, Path::Arc { dir: od, .. }) if dir != od => {
                return Err(PathError::ArcReversed(b.seq));
            }
            (Path::Line, _) if (pe - ps).dot(bb - a) < -1e-9 => {
                return Err(PathError::Backwards(b.seq));
            }
            _ => {}
        }
    }
    Ok(())
}

fn arcs_cfg(mode: CornerMode) -> CompConfig {
    CompConfig {
        corner_mode: mode,
        arc_insertion_limit_deg: 5.0,
        ..CompConfig::default()
    }
}

/// The step contour of issue #18: (0,60) → (100,60) → (100,60+h) → (200,60+h), mirrored in
/// Y (`mirror`) and/or run the other way (`reverse`); G41 or G42 with radius `r`. Returns the
/// program and the seq numbers of its contour elements.
fn step_case(h: f64, r: f64, left: bool, mirror: bool, reverse: bool) -> (Prog, Vec<u32>) {
    let m = if mirror { -1.0 } else { 1.0 };
    let mut pts = vec![
        (0.0, 60.0),
        (100.0, 60.0),
        (100.0, 60.0 + h),
        (200.0, 60.0 + h),
    ];
    if reverse {
        pts.reverse();
    }
    let pts: Vec<(f64, f64)> = pts.into_iter().map(|(x, y)| (x, m * y)).collect();
    let mut p = Prog::new(pts[0].0 - 30.0, 0.0);
    if left {
        p.g41(1, r);
    } else {
        p.g42(1, r);
    }
    p.line(pts[0].0, pts[0].1);
    let first = p.blocks.len() as u32;
    for &(x, y) in &pts[1..] {
        p.line(x, y);
    }
    let contour = (first..p.blocks.len() as u32).collect();
    let last = pts[3];
    p.g40().line(last.0 + 30.0, last.1 + m * 100.0);
    (p, contour)
}

// Issue #18 acceptance: steps of 0.1·r … 1.5·r, both sides, R339 modes 1 and 2, mirrored and
// reversed: the tool centre never comes closer than r − 1 µm and never runs backwards, and no
// warning is needed.
#[test]
fn short_step_next_to_an_inserted_arc_never_gouges() {
    let r = 20.0;
    let mut trimmed = 0;
    for mode in [
        CornerMode::ArcAboveLimit,
        CornerMode::ArcAboveLimitOrMissing,
    ] {
        for k in 1..=15 {
            let h = r * k as f64 / 10.0;
            for (left, mirror, reverse) in (0..8).map(|i| (i & 1 == 0, i & 2 != 0, i & 4 != 0)) {
                let (p, contour) = step_case(h, r, left, mirror, reverse);
                let (out, diags) = p.run(&arcs_cfg(mode));
                let what = format!("h={h} left={left} mirror={mirror} reverse={reverse} {mode:?}");
                assert!(errors(&diags).is_empty(), "{what}: {diags:?}");
                assert!(
                    with_severity(&diags, Severity::Warning).is_empty(),
                    "{what}: {diags:?}"
                );
                check_continuous(&out).unwrap();
                never_backwards(&p.blocks, &out).unwrap_or_else(|e| panic!("{what}: {e}"));
                let (d, tool, prog) = clearance(&p.blocks, &out, &contour, Plane::G17);
                assert!(
                    d >= r - 1e-3,
                    "{what}: tool centre of seq {tool} {d:.4} mm from seq {prog}"
                );
                trimmed += out.iter().filter(|c| c.role == Role::Collapsed).count();
            }
        }
    }
    // Steps shorter than r collapse (9 lengths × 8 variants × 2 modes).
    assert_eq!(trimmed, 9 * 8 * 2);
}

// The issue's exact numbers: r = 20, step (100,60) → (100,68), G41: the previous equidistant
// ends on the inserted arc at (84, 80) instead of running back to (80, 68).
#[test]
fn step_of_the_issue_ends_the_previous_equidistant_on_the_arc() {
    let (p, _) = step_case(8.0, 20.0, true, false, false);
    let (out, _) = p.run(&arcs_cfg(CornerMode::ArcAboveLimit));
    let mv = motions(&out);
    let eq: Vec<_> = mv.iter().filter(|c| c.role == Role::Equidistant).collect();
    let (_, end) = ends(&eq[0].block, Plane::G17);
    assert_close(end, V2::new(84.0, 80.0), 1e-9);
    let arc = mv.iter().find(|c| c.role == Role::CornerArc).unwrap();
    let (s, e) = ends(&arc.block, Plane::G17);
    assert_close(s, V2::new(84.0, 80.0), 1e-9);
    assert_close(e, V2::new(100.0, 88.0), 1e-9);
}
