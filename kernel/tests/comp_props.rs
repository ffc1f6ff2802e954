//! Property tests of radius compensation (SPEC §4.3): random valid contours, open and closed,
//! lines and arcs, tool radius below the smallest concave radius, in every corner mode.
//! Every equidistant piece lies at exactly |r| (1e-6 mm) on the correct side and runs
//! forwards, the path is continuous, inserted arcs are centred on the corner and tangent to
//! both neighbours. And a fuzzer: random, also invalid, block sequences never panic and never
//! produce a NaN.

mod comp_common;

use std::f64::consts::{PI, TAU};

use comp_common::*;
use kernel::Severity;
use kernel::block::{ArcDir, Block, BlockKind, Comp, Continuity, Feed, Path, Plane, Spindle};
use kernel::comp::geom::V2;
use kernel::comp::{CompConfig, Compensator, CornerMode, compensate_all};
use kernel::units::AxesMm;
use proptest::prelude::*;

/// One element of a turtle-walk contour: the turn before it (radians, 0 = tangent) and either
/// a line of `len` or an arc of `len` about a radius `rho` (sign = direction).
#[derive(Clone, Debug)]
struct Step {
    turn: f64,
    len: f64,
    arc_rho: Option<f64>,
}

fn step() -> impl Strategy<Value = Step> {
    (
        prop_oneof![Just(0.0), -120.0f64..120.0],
        20.0f64..60.0,
        prop_oneof![Just(None), (10.0f64..80.0, any::<bool>()).prop_map(Some)],
    )
        .prop_map(|(turn_deg, len, arc)| {
            let turn = if turn_deg == 0.0 || turn_deg.abs() >= 2.0 {
                turn_deg.to_radians()
            } else {
                2f64.to_radians().copysign(turn_deg)
            };
            Step {
                turn,
                len,
                arc_rho: arc.map(|(rho, ccw)| if ccw { rho } else { -rho }),
            }
        })
}

fn corner_cfg() -> impl Strategy<Value = CompConfig> {
    (0usize..4, 0.0f64..90.0, any::<bool>()).prop_map(|(m, limit, sign)| CompConfig {
        corner_mode: [
            CornerMode::Intersection,
            CornerMode::ArcAboveLimit,
            CornerMode::ArcAboveLimitOrMissing,
            CornerMode::ArcIfMissing,
        ][m],
        arc_insertion_limit_deg: limit,
        report_inserted_arcs: sign,
        ..CompConfig::default()
    })
}

/// Builds the open contour in `plane`: lead-in line, the steps (with a Z move after those
/// whose length has an odd first decimal when `bridge`), lead-out line.
fn open_contour(steps: &[Step], r: f64, left: bool, plane: Plane, bridge: bool) -> Prog {
    let mut p = Prog::in_plane(plane, 0.0, -30.0);
    p.line(0.0, 0.0); // positioning, uncompensated
    if left {
        p.g41(1, r);
    } else {
        p.g42(1, r);
    }
    // Start block: perpendicular approach from below.
    p.line(0.0, 10.0);
    let mut at = V2::new(0.0, 10.0);
    let mut heading = PI / 2.0;
    for s in steps {
        heading += s.turn;
        match s.arc_rho {
            None => {
                at = at + V2::from_angle(heading) * s.len;
                p.line(at.x, at.y);
            }
            Some(rho) => {
                let ccw = rho > 0.0;
                let rho = rho.abs();
                let sweep = (s.len / rho).min(1.5 * PI);
                let t = V2::from_angle(heading);
                let c = if ccw {
                    at + t.left() * rho
                } else {
                    at - t.left() * rho
                };
                let a0 = (at - c).angle();
                let a1 = if ccw { a0 + sweep } else { a0 - sweep };
                at = c + V2::from_angle(a1) * rho;
                heading += if ccw { sweep } else { -sweep };
                p.arc(!ccw, at.x, at.y, c.x, c.y);
            }
        }
        if bridge && (s.len * 10.0) as i64 % 2 == 1 {
            if plane == Plane::G17 {
                p.z(-s.len);
            } else {
                p.tech();
            }
        }
    }
    p.g40();
    let t = V2::from_angle(heading);
    let out = at + t * 15.0;
    p.line(out.x, out.y);
    p
}

fn check(p: &Prog, cfg: &CompConfig, expect_pieces: usize) -> Result<(), TestCaseError> {
    check_in(p, cfg, expect_pieces, Plane::G17)
}

fn check_in(
    p: &Prog,
    cfg: &CompConfig,
    expect_pieces: usize,
    plane: Plane,
) -> Result<(), TestCaseError> {
    let (out, diags) = p.run(cfg);
    prop_assert!(errors(&diags).is_empty(), "{:?}", diags);
    // Random contours may come back close to themselves (or close at an inside corner where
    // the start and cancel perpendiculars cut into the neighbour): real gouges, each named.
    prop_assert!(
        with_severity(&diags, Severity::Warning)
            .iter()
            .all(|d| kernel::comp::gouge::is_gouge(d)),
        "{:?}",
        diags
    );
    let r = out.iter().map(|c| c.offset_mm.abs()).fold(0.0, f64::max);
    gouge_invariant(&p.blocks, &out, &diags, r, cfg.gouge_tolerance_mm(r), plane)
        .map_err(|e| TestCaseError::fail(e.to_string()))?;
    let (pieces, arcs) =
        check_path(&p.blocks, &out, plane, 1e-6).map_err(|e| TestCaseError::fail(e.to_string()))?;
    // Every programmed element appears (an arc over 180° as two halves).
    prop_assert!(pieces >= expect_pieces, "{pieces} < {expect_pieces}");
    let infos = with_severity(&diags, Severity::Info).len();
    if cfg.report_inserted_arcs {
        prop_assert_eq!(infos, arcs);
    }
    if cfg.corner_mode == CornerMode::Intersection {
        prop_assert_eq!(arcs, 0);
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn open_contours_lie_on_the_equidistant(
        steps in prop::collection::vec(step(), 1..14),
        r in 0.2f64..2.0,
        left in any::<bool>(),
        cfg in corner_cfg(),
        plane in prop_oneof![Just(Plane::G17), Just(Plane::G18), Just(Plane::G19)],
        bridge in any::<bool>(),
    ) {
        let p = open_contour(&steps, r, left, plane, bridge);
        check_in(&p, &cfg, steps.len(), plane)?;
    }

    // Tools far too large for the details (loops, missing intersections) with any settings:
    // never a panic; either an error with a block number, or a continuous, finite path.
    #[test]
    fn tight_contours_stay_continuous_with_any_settings(
        steps in prop::collection::vec(step(), 1..14),
        r in 2.0f64..30.0,
        left in any::<bool>(),
        cfg in any_cfg(),
    ) {
        let p = open_contour(&steps, r, left, Plane::G17, true);
        let (out, diags) = p.run(&cfg);
        let errs = errors(&diags);
        if errs.is_empty() {
            check_continuous(&out).map_err(|e| TestCaseError::fail(e.to_string()))?;
        } else {
            for e in errs {
                prop_assert!(e.block.is_some());
            }
        }
    }

    #[test]
    fn closed_contours_lie_on_the_equidistant(
        n in 5usize..9,
        radius in 40.0f64..100.0,
        jitter in prop::collection::vec((-0.15f64..0.15, -0.1f64..0.1, -0.1f64..0.1, any::<bool>()), 9),
        r in 0.2f64..2.0,
        left in any::<bool>(),
        ccw in any::<bool>(),
        cfg in corner_cfg(),
    ) {
        // A convex polygon, some edges bulging out or in as arcs (sagitta up to chord/10).
        let pts: Vec<V2> = (0..n)
            .map(|k| {
                let (ja, jr, _, _) = jitter[k];
                let a = TAU * (k as f64 + ja) / n as f64;
                let a = if ccw { a } else { -a };
                V2::from_angle(a) * (radius * (1.0 + jr))
            })
            .collect();
        let v0 = pts[0];
        let mut p = Prog::new(v0.x * 1.5, v0.y * 1.5);
        if left { p.g41(1, r); } else { p.g42(1, r); }
        p.line(v0.x, v0.y);
        for k in 0..n {
            let a = pts[k];
            let b = pts[(k + 1) % n];
            let (_, _, bulge, as_arc) = jitter[k];
            if as_arc && bulge.abs() > 0.01 {
                let chord = b - a;
                let c_len = chord.len();
                let h = bulge * c_len; // sagitta, positive bulges to the left
                let rho = (c_len * c_len / 4.0 + h * h) / (2.0 * h.abs());
                let mid = (a + b) * 0.5;
                // Centre on the side opposite the bulge.
                let n_left = chord.unit().left();
                let centre = mid - n_left * ((rho - h.abs()) * h.signum());
                // Bulging left from a→b is a clockwise arc... seen from the centre on the right.
                let cw = h > 0.0;
                p.arc(cw, b.x, b.y, centre.x, centre.y);
            } else {
                p.line(b.x, b.y);
            }
        }
        p.g40();
        p.line(v0.x * 1.5, v0.y * 1.5);
        check(&p, &cfg, n)?;
    }
}

// ---- Fuzzing: random, also invalid, sequences -------------------------------------------

#[derive(Clone, Debug)]
enum Op {
    Line(f64, f64),
    Rapid(f64, f64),
    Arc(bool, f64, f64, f64, f64),
    Z(f64),
    Tech,
    Dwell,
    Jump(f64, f64),
    Nan,
}

fn op() -> impl Strategy<Value = Op> {
    let c = || prop_oneof![-50.0f64..50.0, Just(0.0), Just(10.0), Just(1e4), Just(1e-7)];
    prop_oneof![
        4 => (c(), c()).prop_map(|(x, y)| Op::Line(x, y)),
        1 => (c(), c()).prop_map(|(x, y)| Op::Rapid(x, y)),
        3 => (any::<bool>(), c(), c(), c(), c()).prop_map(|(cw, x, y, i, j)| Op::Arc(cw, x, y, i, j)),
        1 => c().prop_map(Op::Z),
        1 => Just(Op::Tech),
        1 => Just(Op::Dwell),
        1 => (c(), c()).prop_map(|(x, y)| Op::Jump(x, y)),
        1 => Just(Op::Nan),
    ]
}

fn comp() -> impl Strategy<Value = Comp> {
    prop_oneof![
        2 => Just(Comp::Off),
        3 => (0u8..3, prop_oneof![-20.0f64..20.0, Just(0.0), Just(5.0)])
            .prop_map(|(d, radius_mm)| Comp::Left { d, radius_mm }),
        3 => (0u8..3, prop_oneof![-20.0f64..20.0, Just(0.0), Just(5.0)])
            .prop_map(|(d, radius_mm)| Comp::Right { d, radius_mm }),
    ]
}

fn any_cfg() -> impl Strategy<Value = CompConfig> {
    (corner_cfg(), any::<[bool; 12]>(), 0.0f64..5.0).prop_map(|(mut c, f, r234)| {
        c.g40_without_motion = f[0];
        c.continuity_limit_deg = r234;
        c.check.check = f[1];
        c.check.warn = f[2];
        c.check.optimise_3_blocks = f[3];
        c.check.optimise_4_blocks = f[4];
        c.check.complementary_arc_to_line = f[5];
        c.check.allow_side_change = f[6];
        c.check.arc_off_circle_to_line = f[7];
        c.check.arc_without_intersection_to_line = f[8];
        c.exit.optimise = f[9];
        c.exit.report = f[10];
        c.position.optimise = f[11];
        c.position.report = f[11];
        c
    })
}

/// The block kind `op` makes from `start` in `plane`, and its end point.
fn op_kind(op: &Op, start: AxesMm, plane: Plane) -> (BlockKind, AxesMm) {
    let (a, b) = plane.axes();
    let mut end = start;
    let kind = match *op {
        Op::Line(x, y) | Op::Rapid(x, y) => {
            end[a] = x;
            end[b] = y;
            let path = if matches!(op, Op::Line(..)) {
                Path::Line
            } else {
                Path::Rapid
            };
            BlockKind::Motion { start, end, path }
        }
        Op::Arc(cw, x, y, i, j) => {
            end[a] = x;
            end[b] = y;
            let mut center = start;
            center[a] += i;
            center[b] += j;
            let dir = if cw { ArcDir::Cw } else { ArcDir::Ccw };
            BlockKind::Motion {
                start,
                end,
                path: Path::Arc { dir, center, plane },
            }
        }
        Op::Z(z) => {
            end[3 - a - b] = z;
            BlockKind::Motion {
                start,
                end,
                path: Path::Line,
            }
        }
        Op::Tech => BlockKind::Technology,
        Op::Dwell => BlockKind::Dwell { seconds: 0.5 },
        Op::Jump(x, y) => {
            // Discontinuous input: a start that is not the previous end.
            let mut s = start;
            s[a] = x;
            end[a] = y;
            BlockKind::Motion {
                start: s,
                end,
                path: Path::Line,
            }
        }
        Op::Nan => {
            end[a] = f64::NAN;
            BlockKind::Motion {
                start,
                end,
                path: Path::Line,
            }
        }
    };
    (kind, end)
}

fn fuzz_blocks(ops: &[(Op, Comp, u8)]) -> Vec<Block> {
    let mut pos = AxesMm::ZERO;
    let mut out = Vec::new();
    for (k, (op, comp, plane)) in ops.iter().enumerate() {
        let plane = match plane {
            0 => Plane::G18,
            1 => Plane::G19,
            _ => Plane::G17,
        };
        let start = pos;
        let (kind, end) = op_kind(op, start, plane);
        if !matches!(op, Op::Nan) {
            pos = end;
        }
        out.push(Block {
            seq: k as u32,
            n: Some(k as u32 + 1),
            line: k as u32 + 1,
            kind,
            feed: Feed::MmPerMin(100.0),
            plane,
            comp: *comp,
            continuity: Continuity::G98,
            dyn_set: 1,
            spindle: Spindle::default(),
            m: [None; 4],
        });
    }
    out
}

fn finite_block(b: &Block) -> bool {
    match b.kind {
        BlockKind::Motion { start, end, path } => {
            let ok = |p: &AxesMm| p.0.iter().all(|v| v.is_finite());
            ok(&start)
                && ok(&end)
                && match path {
                    Path::Arc { center, .. } => ok(&center),
                    _ => true,
                }
        }
        _ => true,
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1500))]

    #[test]
    fn fuzz_never_panics_and_never_outputs_nan(
        ops in prop::collection::vec((op(), comp(), prop_oneof![8 => Just(2u8), 1 => Just(0u8), 1 => Just(1u8)]), 0..60),
        cfg in any_cfg(),
    ) {
        let blocks = fuzz_blocks(&ops);
        let mut c = Compensator::new(cfg);
        let mut accepted = Vec::new();
        for b in &blocks {
            let held = c.held_blocks();
            if c.push(b).is_err() {
                // A refused block changes nothing.
                prop_assert_eq!(c.held_blocks(), held);
            } else {
                accepted.push(*b);
            }
            while let Some(o) = c.poll() {
                prop_assert!(finite_block(&o), "{:?}", o);
            }
            prop_assert!(c.held_blocks() <= 5 * (1 + kernel::comp::MAX_BRIDGED));
        }
        c.finish();
        while let Some(o) = c.poll_traced() {
            prop_assert!(finite_block(&o.block), "{:?}", o);
            prop_assert!(o.offset_mm.is_finite());
        }
        for d in c.take_diagnostics() {
            prop_assert!(!d.message.is_empty());
        }
        // Atomic errors: the accepted blocks alone give exactly the same result.
        let (a, da) = compensate_all(&blocks, &cfg);
        let (b, db) = compensate_all(&accepted, &cfg);
        prop_assert!(errors(&db).is_empty(), "{:?}", db);
        let warn = |d: &[kernel::Diagnostic]| -> Vec<kernel::Diagnostic> {
            d.iter().filter(|d| !d.is_error()).cloned().collect()
        };
        prop_assert_eq!(warn(&da), warn(&db));
        prop_assert_eq!(format!("{a:?}"), format!("{b:?}"));
    }
}
