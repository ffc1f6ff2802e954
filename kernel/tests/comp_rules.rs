//! One test per rule of SPEC §4 (radius compensation), on hand-built canonical blocks.

mod comp_common;

use comp_common::*;
use kernel::block::{BlockKind, Path, Plane};
use kernel::comp::geom::V2;
use kernel::comp::{CompConfig, Compensator, CornerMode, MAX_BRIDGED, Role};
use kernel::constants::Constants;
use kernel::{DiagCode, Severity};

fn p(x: f64, y: f64) -> V2 {
    V2::new(x, y)
}

fn cfg() -> CompConfig {
    CompConfig::default()
}

/// Plane end points of the output pieces of the block with N number `n`, by role.
fn piece(out: &[kernel::comp::CompBlock], n: u32, role: Role) -> (V2, V2) {
    let c = out
        .iter()
        .find(|c| c.block.n == Some(n) && c.role == role)
        .unwrap_or_else(|| panic!("no {role:?} for N{n} in {out:#?}"));
    ends(&c.block, Plane::G17)
}

// ---- §4.1 side, plane, lifetime -------------------------------------------------------------

// §4.1: G41 left, G42 right, a negative radius swaps the sides.
#[test]
fn side_follows_g41_g42_and_the_sign_of_the_radius() {
    for (left, r, want_y) in [
        (true, 2.0, 2.0),
        (false, 2.0, -2.0),
        (true, -2.0, -2.0),
        (false, -2.0, 2.0),
    ] {
        let mut pr = Prog::new(-10.0, 0.0);
        if left {
            pr.g41(1, r);
        } else {
            pr.g42(1, r);
        }
        pr.line(0.0, 0.0).line(20.0, 0.0).g40().line(30.0, 0.0);
        let (out, d) = pr.run(&cfg());
        assert!(errors(&d).is_empty());
        let (s, e) = piece(&out, 20, Role::Equidistant);
        assert_close(s, p(0.0, want_y), 1e-12);
        assert_close(e, p(20.0, want_y), 1e-12);
    }
}

// §4.1: the compensation works in the selected plane G17/G18/G19 and leaves the third axis.
#[test]
fn every_plane_offsets_its_own_axes() {
    for plane in [Plane::G17, Plane::G18, Plane::G19] {
        let mut pr = Prog::in_plane(plane, -10.0, 0.0);
        pr.g41(1, 2.0)
            .line(0.0, 0.0)
            .line(20.0, 0.0)
            .arc(false, 30.0, 10.0, 20.0, 10.0)
            .line(30.0, 20.0)
            .g40()
            .line(40.0, 20.0);
        let (out, d) = pr.run(&cfg());
        assert!(errors(&d).is_empty(), "{d:?}");
        check_path(&pr.blocks, &out, plane, 1e-9).unwrap();
        let (a, b) = plane.axes();
        let third = 3 - a - b;
        for c in motions(&out) {
            let (s, e, _) = c.block.motion().unwrap();
            assert_eq!((s[third], e[third]), (0.0, 0.0), "{plane:?}");
        }
        let arc = out.iter().find(|c| c.block.n == Some(30)).unwrap();
        let (_, e, path) = arc.block.motion().unwrap();
        // G3 with the tool left: towards the centre, radius 10 - 2.
        assert!(matches!(path, Path::Arc { .. }));
        assert_close(V2::of(&e, plane), p(28.0, 10.0), 1e-9);
    }
}

// §4.1: changing the plane while compensation is active is an error; nothing changes.
#[test]
fn plane_change_while_active_is_an_error() {
    let mut pr = Prog::new(-10.0, 0.0);
    pr.g41(1, 2.0).line(0.0, 0.0).line(10.0, 0.0);
    pr.plane(Plane::G18).tech();
    let mut c = Compensator::new(cfg());
    for b in &pr.blocks[..2] {
        c.push(b).unwrap();
    }
    let held = c.held_blocks();
    let e = c.push(&pr.blocks[2]).unwrap_err();
    assert!(e.is_error() && e.block == Some(30) && e.code == DiagCode::PlaneChangeUnderComp);
    assert_eq!(c.held_blocks(), held);
    assert!(c.is_active());
}

// §4.1: the tool must be selected (D) before G41/G42; 8.R95 = 0 refuses G41/G42.
#[test]
fn no_tool_or_not_enabled_is_an_error() {
    let mut pr = Prog::new(-10.0, 0.0);
    pr.g41(0, 2.0).line(0.0, 0.0);
    let (_, d) = pr.run(&cfg());
    assert_eq!(errors(&d)[0].code, DiagCode::CompWithoutTool);
    assert_eq!(errors(&d)[0].block, Some(10));
    let mut c = Constants::new();
    c.set(95, 0.0);
    let mut pr = Prog::new(-10.0, 0.0);
    pr.g41(1, 2.0).line(0.0, 0.0);
    let (_, d) = pr.run(&CompConfig::from_constants(&c));
    assert_eq!(errors(&d)[0].code, DiagCode::CompDisabled);
}

// §4.1: up to 200 blocks without motion in the plane are bridged; the 201st is an error.
#[test]
fn bridging_200_blocks_and_refusing_201() {
    let build = |n: usize| {
        let mut pr = Prog::new(-10.0, 0.0);
        pr.g41(1, 2.0).line(0.0, 0.0).line(10.0, 0.0);
        for k in 0..n {
            if k % 2 == 0 {
                pr.z(-(k as f64));
            } else {
                pr.tech();
            }
        }
        pr.line(10.0, 10.0).g40().line(20.0, 10.0);
        pr
    };
    let pr = build(MAX_BRIDGED);
    let (out, d) = pr.run(&cfg());
    assert!(errors(&d).is_empty(), "{d:?}");
    check_path(&pr.blocks, &out, Plane::G17, 1e-9).unwrap();
    // The contour continues as if the bridged blocks were not there: the inside corner at
    // (10, 0) is the intersection (8, 2), and the Z moves happen there.
    assert_close(piece(&out, 20, Role::Equidistant).1, p(8.0, 2.0), 1e-12);
    let bridged: Vec<_> = out.iter().filter(|c| c.role == Role::Bridged).collect();
    assert_eq!(bridged.len(), MAX_BRIDGED);
    for c in bridged {
        if let Some((s, e, _)) = c.block.motion() {
            assert_close(V2::of(&s, Plane::G17), p(8.0, 2.0), 1e-12);
            assert_close(V2::of(&e, Plane::G17), p(8.0, 2.0), 1e-12);
        }
    }
    let pr = build(MAX_BRIDGED + 1);
    let (_, d) = pr.run(&cfg());
    let e = errors(&d);
    assert_eq!(e.len(), 1);
    assert_eq!(e[0].block, pr.blocks[2 + MAX_BRIDGED].n);
    assert_eq!(e[0].code, DiagCode::CompTooManyBridged);
}

// §4.1: compensation is modal until program end: the last element ends on its perpendicular.
#[test]
fn program_end_ends_on_the_perpendicular() {
    let mut pr = Prog::new(-10.0, 0.0);
    pr.g41(1, 2.0)
        .line(0.0, 0.0)
        .line(10.0, 0.0)
        .line(10.0, 10.0);
    let (out, d) = pr.run(&cfg());
    assert!(errors(&d).is_empty());
    assert_close(piece(&out, 30, Role::Equidistant).1, p(8.0, 10.0), 1e-12);
}

// ---- §4.2 start and cancel ------------------------------------------------------------------

// §4.2: start in a linear block, to the perpendicular of the next block (a line).
#[test]
fn start_moves_to_the_perpendicular_of_the_next_line() {
    let mut pr = Prog::new(-30.0, 0.0);
    pr.g42(1, 5.0).line(0.0, 0.0).line(10.0, 10.0);
    let (out, _) = pr.run(&cfg());
    let (s, e) = piece(&out, 10, Role::StartMove);
    assert_close(s, p(-30.0, 0.0), 0.0);
    let n = p(1.0, 1.0).unit().left() * -5.0;
    assert_close(e, n, 1e-12);
}

// §4.2: when the next block is an arc, to the perpendicular to its tangent.
#[test]
fn start_moves_to_the_perpendicular_of_the_next_arc() {
    let mut pr = Prog::new(-30.0, 0.0);
    pr.g41(1, 2.0)
        .line(0.0, 0.0)
        .arc(true, 20.0, 0.0, 10.0, 0.0)
        .g40()
        .line(30.0, 0.0);
    let (out, d) = pr.run(&cfg());
    assert!(errors(&d).is_empty());
    // G2 from (0,0) about (10,0): tangent +Y, left is -X, radius 12.
    assert_close(piece(&out, 10, Role::StartMove).1, p(-2.0, 0.0), 1e-12);
    assert_close(piece(&out, 20, Role::Equidistant).1, p(22.0, 0.0), 1e-12);
}

// §4.2: never start or cancel on an arc.
#[test]
fn start_or_cancel_on_an_arc_is_an_error() {
    let mut pr = Prog::new(-10.0, 0.0);
    pr.g41(1, 2.0).arc(true, 10.0, 0.0, 0.0, 0.0);
    let (_, d) = pr.run(&cfg());
    assert_eq!(errors(&d)[0].code, DiagCode::CompChangeOnArc);
    let mut pr = Prog::new(-10.0, 0.0);
    pr.g41(1, 2.0)
        .line(0.0, 0.0)
        .line(10.0, 0.0)
        .g40()
        .arc(true, 20.0, 0.0, 15.0, 0.0);
    let (_, d) = pr.run(&cfg());
    assert_eq!(errors(&d)[0].block, Some(30));
    assert_eq!(errors(&d)[0].code, DiagCode::CompChangeOnArc);
}

// §4.2: cancel: the last compensated end point is on the perpendicular at the programmed end,
// the G40 block then moves to its programmed end point.
#[test]
fn cancel_ends_on_the_perpendicular_then_goes_to_the_programmed_point() {
    let mut pr = Prog::new(-10.0, 0.0);
    pr.g41(1, 2.0)
        .line(0.0, 0.0)
        .line(10.0, 0.0)
        .arc(false, 20.0, 10.0, 10.0, 10.0)
        .g40()
        .line(30.0, 10.0);
    let (out, d) = pr.run(&cfg());
    assert!(errors(&d).is_empty());
    // G3 about (10,10) radius 10, tool left = inside, radius 8; end on the perpendicular.
    assert_close(piece(&out, 30, Role::Equidistant).1, p(18.0, 10.0), 1e-12);
    let (s, e) = piece(&out, 40, Role::Passthrough);
    assert_close(s, p(18.0, 10.0), 1e-12);
    assert_close(e, p(30.0, 10.0), 0.0);
}

// §4.2: G40 without motion in the plane needs 7.R339 = 1; then the position is reconciled at
// the next motion in the plane.
#[test]
fn g40_without_motion_needs_7_r339() {
    let mut pr = Prog::new(-10.0, 0.0);
    pr.g41(1, 2.0).line(0.0, 0.0).line(10.0, 0.0);
    pr.g40().tech().z(5.0).line(20.0, 0.0);
    let (_, d) = pr.run(&cfg());
    assert_eq!(errors(&d)[0].block, Some(30));
    assert_eq!(errors(&d)[0].code, DiagCode::G40WithoutMotion);

    let mut c = Constants::new();
    c.set(95, 10000.0);
    c.set(339, 1000.0); // decade 7 = 1
    let cfg = CompConfig::from_constants(&c);
    assert!(cfg.g40_without_motion);
    let (out, d) = pr.run(&cfg);
    assert!(errors(&d).is_empty(), "{d:?}");
    assert_close(piece(&out, 20, Role::Equidistant).1, p(10.0, 2.0), 1e-12);
    // The Z move stays where the tool is, the next motion in the plane reconciles.
    let (s, e) = piece(&out, 40, Role::Passthrough);
    assert_close(s, p(10.0, 2.0), 1e-12);
    assert_close(e, p(10.0, 2.0), 1e-12);
    let (s, e) = piece(&out, 50, Role::Passthrough);
    assert_close(s, p(10.0, 2.0), 1e-12);
    assert_close(e, p(20.0, 0.0), 0.0);
}

// §4.2: G0 cancels; the rapid that ends the rapid motion starts the compensation again.
#[test]
fn rapid_cancels_and_restarts() {
    let mut pr = Prog::new(-10.0, 0.0);
    pr.g41(1, 2.0)
        .line(0.0, 0.0)
        .line(10.0, 0.0)
        .rapid(10.0, 20.0)
        .rapid(30.0, 20.0)
        .line(30.0, 40.0)
        .g40()
        .line(40.0, 40.0);
    let (out, d) = pr.run(&cfg());
    assert!(errors(&d).is_empty(), "{d:?}");
    check_path(&pr.blocks, &out, Plane::G17, 1e-9).unwrap();
    // The block before the rapid ends on its perpendicular.
    assert_close(piece(&out, 20, Role::Equidistant).1, p(10.0, 2.0), 1e-12);
    // First rapid: uncompensated to its programmed end; the last rapid restarts.
    let first = out.iter().find(|c| c.block.n == Some(30)).unwrap();
    assert_eq!(first.block.motion().unwrap().2, Path::Rapid);
    assert_close(ends(&first.block, Plane::G17).1, p(10.0, 20.0), 0.0);
    let last = out.iter().find(|c| c.block.n == Some(40)).unwrap();
    assert_eq!(
        (last.role, last.block.motion().unwrap().2),
        (Role::StartMove, Path::Rapid)
    );
    assert_close(ends(&last.block, Plane::G17).1, p(28.0, 20.0), 1e-12);
    assert_close(piece(&out, 50, Role::Equidistant).0, p(28.0, 20.0), 1e-12);
}

// §4.2: G41 ↔ G42 directly only with 6.R397 = 1; the change happens like a start.
#[test]
fn side_change_needs_6_r397() {
    let mut pr = Prog::new(-10.0, 0.0);
    pr.g41(1, 2.0).line(0.0, 0.0).line(10.0, 0.0);
    pr.g42(1, 2.0)
        .line(20.0, 0.0)
        .line(30.0, 0.0)
        .g40()
        .line(40.0, 0.0);
    let (_, d) = pr.run(&cfg());
    assert_eq!(errors(&d)[0].block, Some(30));
    let mut c = cfg();
    c.check.allow_side_change = true;
    let (out, d) = pr.run(&c);
    assert!(errors(&d).is_empty());
    assert_close(piece(&out, 20, Role::Equidistant).1, p(10.0, 2.0), 1e-12);
    let (s, e) = piece(&out, 30, Role::StartMove);
    assert_close(s, p(10.0, 2.0), 1e-12);
    assert_close(e, p(20.0, -2.0), 1e-12);
    assert_close(piece(&out, 40, Role::Equidistant).1, p(30.0, -2.0), 1e-12);
}

// ---- §4.3 corners ---------------------------------------------------------------------------

// §4.3: at a line–arc corner the intersection is the true intersection of the offset line and
// the offset circle, not of the tangent extensions.
#[test]
fn line_arc_corner_is_the_true_intersection() {
    let mut pr = Prog::new(-10.0, 0.0);
    // Line +X to (10,0), then G3 about (10,10) — the arc starts going -X... choose a corner:
    // arc about (20,0) from (10,0) clockwise (tangent +Y): a 90° left turn, tool left =
    // inside corner.
    pr.g41(1, 2.0)
        .line(0.0, 0.0)
        .line(10.0, 0.0)
        .arc(true, 30.0, 0.0, 20.0, 0.0)
        .g40()
        .line(40.0, 0.0);
    let (out, d) = pr.run(&cfg());
    assert!(errors(&d).is_empty());
    check_path(&pr.blocks, &out, Plane::G17, 1e-9).unwrap();
    // Offset line y = 2, offset circle about (20,0) radius 12: x = 20 - sqrt(144 - 4).
    let want = p(20.0 - 140f64.sqrt(), 2.0);
    assert_close(piece(&out, 20, Role::Equidistant).1, want, 1e-12);
    // The tangent extension would give (8, 2): millimetres away.
    assert!(want.dist(p(8.0, 2.0)) > 0.1);
}

// §4.3 8.R339 = 1: arcs at outside corners above the angle limit only.
#[test]
fn mode_1_inserts_arcs_above_the_limit() {
    let mut pr = Prog::new(-10.0, 0.0);
    // Tool right, left turns are outside corners: 90° then 10°, then a right turn (inside).
    pr.g42(1, 2.0)
        .line(0.0, 0.0)
        .line(10.0, 0.0)
        .line(10.0, 10.0);
    let p1 = p(10.0, 10.0) + V2::from_angle(100f64.to_radians()) * 10.0;
    let p2 = p1 + V2::from_angle(80f64.to_radians()) * 10.0;
    pr.line(p1.x, p1.y)
        .line(p2.x, p2.y)
        .g40()
        .line(p2.x, p2.y + 10.0);
    let mut c = Constants::new();
    c.set(95, 10000.0);
    c.set(339, 10005.0); // mode 1, limit 5°
    let (out, d) = pr.run(&CompConfig::from_constants(&c));
    assert!(errors(&d).is_empty(), "{d:?}");
    check_path(&pr.blocks, &out, Plane::G17, 1e-9).unwrap();
    let arcs: Vec<_> = out.iter().filter(|c| c.role == Role::CornerArc).collect();
    assert_eq!(arcs.len(), 2, "{out:#?}");
    assert_eq!((arcs[0].block.n, arcs[1].block.n), (Some(30), Some(40)));
    c.set(339, 10015.0); // limit 15°: the 10° corner takes the intersection
    let (out, _) = pr.run(&CompConfig::from_constants(&c));
    assert_eq!(out.iter().filter(|c| c.role == Role::CornerArc).count(), 1);
    // R339 negative: an information message per inserted arc.
    c.set(339, -10005.0);
    let (_, d) = pr.run(&CompConfig::from_constants(&c));
    let infos = with_severity(&d, Severity::Info);
    assert_eq!(infos.len(), 2);
    assert_eq!(infos[0].block, Some(30));
}

/// Manual Fig. 5: after an inside arc (G3, tool left) a line turning 120° away has no
/// intersection of the equidistants (radius 10, tool 3).
fn fig5() -> Prog {
    let mut pr = Prog::new(-10.0, -10.0);
    pr.g41(1, 3.0)
        .line(0.0, -10.0)
        .arc(false, 10.0, 0.0, 0.0, 0.0);
    let d = V2::from_angle((-30f64).to_radians()) * 20.0;
    pr.line(10.0 + d.x, d.y).g40().line(40.0, -20.0);
    pr
}

// §4.3 8.R339 = 0: no intersection → error "NENALEZEN PRUSEČÍK EKVIDISTANT" with the block.
#[test]
fn missing_intersection_is_an_error_in_mode_0() {
    let (_, d) = fig5().run(&cfg());
    let e = errors(&d);
    assert_eq!(e.len(), 1);
    assert_eq!(e[0].block, Some(30));
    assert_eq!(e[0].code, DiagCode::NoIntersection);
    // SPEC §4.3 names the manual's message: the machinist knows it from the old control.
    assert!(e[0].message.contains("NENALEZEN PRUSEČÍK EKVIDISTANT"));
    assert!(
        e[0].message.contains("N20"),
        "names the other block: {}",
        e[0].message
    );
}

// §4.3 8.R339 = 2 and 4: an arc where no intersection exists.
#[test]
fn modes_2_and_4_insert_an_arc_where_no_intersection_exists() {
    for mode in [CornerMode::ArcAboveLimitOrMissing, CornerMode::ArcIfMissing] {
        let c = CompConfig {
            corner_mode: mode,
            arc_insertion_limit_deg: 170.0,
            ..cfg()
        };
        let pr = fig5();
        let (out, d) = pr.run(&c);
        assert!(errors(&d).is_empty(), "{d:?}");
        check_path(&pr.blocks, &out, Plane::G17, 1e-9).unwrap();
        assert_eq!(out.iter().filter(|c| c.role == Role::CornerArc).count(), 1);
    }
}

// §4.5 R397 d8: an arc without intersection is replaced by its chord.
#[test]
fn d8_replaces_the_arc_without_intersection_by_a_line() {
    let mut c = cfg();
    c.check.arc_without_intersection_to_line = true;
    let pr = fig5();
    let (out, d) = pr.run(&c);
    assert!(errors(&d).is_empty(), "{d:?}");
    let w = with_severity(&d, Severity::Warning);
    assert!(
        w.iter()
            .any(|d| d.block == Some(20) && d.code == DiagCode::NoIntersection)
    );
    let chord = out.iter().find(|c| c.block.n == Some(20)).unwrap();
    assert_eq!(chord.role, Role::EquidistantChord);
    assert_eq!(chord.block.motion().unwrap().2, Path::Line);
}

// ---- §4.4 R234 ------------------------------------------------------------------------------

/// Two arcs of radius 10,000 mm meeting at `angle_deg`: an S-bend (centres on both sides)
/// or both clockwise (centres close together).
fn huge_arcs(angle_deg: f64, s_bend: bool) -> Prog {
    let r = 10_000.0;
    let mut pr = Prog::new(-10.0, 0.0);
    pr.g41(1, 5.0).line(0.0, 0.0);
    // First arc: clockwise about (0, -r) from (0,0) by 0.1 rad.
    let c1 = p(0.0, -r);
    let e1 = c1 + V2::from_angle(PI_2 - 0.1) * r;
    pr.arc(true, e1.x, e1.y, c1.x, c1.y);
    // Tangent at e1 (clockwise), turned by the angle, then a G3 arc of the same radius.
    let t = (e1 - c1).unit().left() * -1.0;
    let t2 = V2::from_angle(t.angle() + angle_deg.to_radians());
    let (c2, turn) = if s_bend {
        (e1 + t2.left() * r, 0.1)
    } else {
        (e1 - t2.left() * r, -0.1)
    };
    let e2 = c2 + V2::from_angle((e1 - c2).angle() + turn) * r;
    pr.arc(!s_bend, e2.x, e2.y, c2.x, c2.y).g40();
    let end = e2 + V2::from_angle(t2.angle() + turn) * 10.0;
    pr.line(end.x, end.y);
    pr
}
const PI_2: f64 = std::f64::consts::FRAC_PI_2;

// §4.4 acceptance: arcs of 10,000 mm meeting at 0.001° give a finite, sane point, with and
// without R234.
#[test]
fn near_tangent_huge_arcs_are_sane() {
    for (r234, s_bend) in [(0.0, true), (0.8, true), (0.0, false), (0.8, false)] {
        let pr = huge_arcs(0.001, s_bend);
        let c = CompConfig {
            continuity_limit_deg: r234,
            ..cfg()
        };
        let (out, d) = pr.run(&c);
        assert!(errors(&d).is_empty(), "{d:?}");
        let BlockKind::Motion { end: corner, .. } = pr.blocks[1].kind else {
            unreachable!()
        };
        let corner = V2::of(&corner, Plane::G17);
        let (_, e) = piece(&out, 20, Role::Equidistant);
        assert!(e.is_finite());
        // Sane: about one tool radius from the programmed junction.
        assert!(
            (e.dist(corner) - 5.0).abs() < 1e-3,
            "R234 {r234}: {}",
            e.dist(corner)
        );
        assert_close(piece(&out, 30, Role::Equidistant).0, e, 1e-9);
        for c in motions(&out) {
            let (s, e, _) = c.block.motion().unwrap();
            assert!(s.0.iter().chain(e.0.iter()).all(|v| v.is_finite()));
        }
    }
}

// §4.4: below the R234 limit, the point on the perpendicular (mean normal) is used, not the
// intersection; above it the intersection.
#[test]
fn r234_uses_the_perpendicular_point_below_the_limit() {
    let mut pr = Prog::new(-10.0, 0.0);
    let a = 0.5f64.to_radians();
    pr.g41(1, 2.0)
        .line(0.0, 0.0)
        .line(10.0, 0.0)
        .line(10.0 + 10.0 * a.cos(), 10.0 * a.sin())
        .g40()
        .line(30.0, 0.0);
    let c = CompConfig {
        continuity_limit_deg: 0.8,
        ..cfg()
    };
    let (out, _) = pr.run(&c);
    let n = (p(0.0, 1.0) + V2::from_angle(a).left()).unit() * 2.0;
    assert_close(
        piece(&out, 20, Role::Equidistant).1,
        p(10.0, 0.0) + n,
        1e-12,
    );
    let (out, _) = pr.run(&cfg());
    // Inside corner: y = 2 meets the rotated offset line at x = 10 - 2·tan(a/2).
    assert_close(
        piece(&out, 20, Role::Equidistant).1,
        p(10.0 - 2.0 * (a / 2.0).tan(), 2.0),
        1e-12,
    );
}

// ---- §4.5 R397 check and optimisation, R764, R765 -------------------------------------------

/// A short block B between two inside corners: its equidistant runs backwards (a loop).
/// A (+X to (20,0)), B (+Y 1 mm), C (direction (-1,1)), tool left radius 5.
fn loop3() -> Prog {
    let mut pr = Prog::new(-10.0, 0.0);
    pr.g41(1, 5.0)
        .line(0.0, 0.0)
        .line(20.0, 0.0)
        .line(20.0, 1.0)
        .line(0.0, 21.0)
        .g40()
        .line(-10.0, 31.0);
    pr
}

// §4.5: the check warns with the block number; d2 = 1 suppresses; d1 = 1 switches it off.
#[test]
fn r397_check_warns_about_a_backward_equidistant() {
    let pr = loop3();
    let (out, all) = pr.run(&cfg());
    assert!(errors(&all).is_empty());
    // The loop cuts into A: the whole-run check names it, whatever R397 says (decision 19).
    assert!(gouges(&all).iter().any(|g| g.block == Some(30)), "{all:?}");
    let d = without_gouges(&all);
    let w = with_severity(&d, Severity::Warning);
    assert_eq!(w.len(), 1, "{d:?}");
    assert_eq!(w[0].block, Some(30));
    assert_eq!(w[0].code, DiagCode::EquidistantBackward);
    // SPEC §4 names the manual's message.
    assert!(w[0].message.contains("Chyba v zadání ekvidistanty"));
    // Without optimisation the loop is cut as computed: B runs backwards from y=5 to y<0.
    let (s, e) = piece(&out, 30, Role::Equidistant);
    assert!(e.y < s.y);
    let mut c = Constants::new();
    c.set(95, 10000.0);
    c.set(397, 0.010); // d2
    assert!(without_gouges(&pr.run(&CompConfig::from_constants(&c)).1).is_empty());
    c.set(397, 0.001); // d1
    let (_, d) = pr.run(&CompConfig::from_constants(&c));
    assert!(without_gouges(&d).is_empty());
    assert!(!gouges(&d).is_empty());
}

// §4.5 d3: the 3-block optimisation intersects A and C directly; B's equidistant is removed.
#[test]
fn three_block_optimisation_removes_the_loop() {
    let pr = loop3();
    let mut c = Constants::new();
    c.set(95, 10000.0);
    c.set(397, 0.100); // d3, check on, warnings on
    let (out, d) = pr.run(&CompConfig::from_constants(&c));
    assert!(errors(&d).is_empty());
    assert!(
        d.iter()
            .any(|d| d.severity == Severity::Info && d.code == DiagCode::LoopRemoved3Blocks)
    );
    // A' (y = 5) meets C' (through (20,1) + 5·(-1,-1)/√2, direction (-1,1)) at x = 21 - 5·√2 - 4.
    let x = p(16.0 - 5.0 * 2f64.sqrt(), 5.0);
    assert_close(piece(&out, 20, Role::Equidistant).1, x, 1e-9);
    assert!(
        out.iter()
            .any(|c| c.block.n == Some(30) && c.role == Role::Collapsed)
    );
    assert_close(piece(&out, 40, Role::Equidistant).0, x, 1e-9);
    // No piece runs backwards any more: the checker accepts the path.
    check_path(&pr.blocks, &out, Plane::G17, 1e-9).unwrap();
}

/// Two short blocks B (+Y 1) and C (-X 1): A'∩C' does not exist (parallel), so the 3-block
/// optimisation cannot help; the 4-block one joins A and D.
fn loop4() -> Prog {
    let mut pr = Prog::new(-10.0, 0.0);
    pr.g41(1, 5.0)
        .line(0.0, 0.0)
        .line(20.0, 0.0)
        .line(20.0, 1.0)
        .line(19.0, 1.0)
        .line(-1.0, 21.0)
        .g40()
        .line(-11.0, 31.0);
    pr
}

// §4.5 d4: the 4-block optimisation.
#[test]
fn four_block_optimisation_removes_a_double_loop() {
    let pr = loop4();
    let mut c = Constants::new();
    c.set(95, 10000.0);
    c.set(397, 0.110); // d3 + d2: no warnings
    let (out, d) = pr.run(&CompConfig::from_constants(&c));
    assert!(with_severity(&without_gouges(&d), Severity::Warning).is_empty());
    assert!(!gouges(&d).is_empty());
    // d3 alone cannot fix it: a backward piece stays.
    let e = check_path(&pr.blocks, &out, Plane::G17, 1e-9).unwrap_err();
    assert_eq!(e.code(), "path_backwards", "{e}");
    c.set(397, 1.110); // + d4
    let (out, d) = pr.run(&CompConfig::from_constants(&c));
    assert!(
        d.iter().any(|d| d.code == DiagCode::LoopRemoved4Blocks),
        "{d:?}"
    );
    check_path(&pr.blocks, &out, Plane::G17, 1e-9).unwrap();
    // A' (y = 5) meets D' (through (19,1) + 5·(-1,-1)/√2, direction (-1,1)).
    let x = p(15.0 - 5.0 * 2f64.sqrt(), 5.0);
    assert_close(piece(&out, 20, Role::Equidistant).1, x, 1e-9);
    for n in [30, 40] {
        assert!(
            out.iter()
                .any(|c| c.block.n == Some(n) && c.role == Role::Collapsed)
        );
    }
}

// §4.5 d7: an arc whose end point is off its circle is replaced by a line.
#[test]
fn d7_replaces_an_arc_off_its_circle() {
    let mut pr = Prog::new(-10.0, 0.0);
    pr.g41(1, 1.0)
        .line(0.0, 0.0)
        .arc(false, 20.0, 1.0, 10.0, 0.0) // end 0.05 mm off the circle of radius 10
        .g40()
        .line(30.0, 0.0);
    let (out, _) = pr.run(&cfg());
    assert!(matches!(
        out.iter()
            .find(|c| c.block.n == Some(20))
            .unwrap()
            .block
            .motion()
            .unwrap()
            .2,
        Path::Arc { .. }
    ));
    let mut c = cfg();
    c.check.arc_off_circle_to_line = true;
    let (out, d) = pr.run(&c);
    assert!(
        d.iter()
            .any(|d| d.block == Some(20) && d.code == DiagCode::ArcReplacedByLine)
    );
    let b = out.iter().find(|c| c.block.n == Some(20)).unwrap();
    assert_eq!(
        (b.role, b.block.motion().unwrap().2),
        (Role::EquidistantChord, Path::Line)
    );
}

// §4.5 R764: the last working block before a rapid, short, whose equidistant runs backwards:
// reported (d7) and optimised (d8): the backward move is left out.
#[test]
fn r764_exit_optimisation() {
    let mut pr = Prog::new(-10.0, 0.0);
    pr.g41(1, 5.0)
        .line(0.0, 0.0)
        .line(20.0, 0.0)
        .line(20.0, 2.0) // 2 mm < 150 % of 5 mm
        .rapid(20.0, 50.0);
    let (out, _) = pr.run(&cfg());
    let (s, e) = piece(&out, 30, Role::Equidistant);
    assert_close(s, p(15.0, 5.0), 1e-12);
    assert_close(e, p(15.0, 2.0), 1e-12); // backwards
    let mut c = Constants::new();
    c.set(95, 10000.0);
    c.set(764, 1000.0); // d7: report only
    let (_, d) = pr.run(&CompConfig::from_constants(&c));
    assert!(
        d.iter()
            .any(|d| d.severity == Severity::Warning && d.code == DiagCode::ExitBackward)
    );
    c.set(764, 11000.0); // d8 + d7
    let (out, d) = pr.run(&CompConfig::from_constants(&c));
    assert!(
        d.iter()
            .any(|d| d.severity == Severity::Info && d.code == DiagCode::ExitOptimised)
    );
    assert!(
        out.iter()
            .any(|c| c.block.n == Some(30) && c.role == Role::Collapsed)
    );
    let rapid = out.iter().find(|c| c.block.n == Some(40)).unwrap();
    assert_close(ends(&rapid.block, Plane::G17).0, p(15.0, 5.0), 1e-12);
    // 1 mm percentage: 2 mm is not shorter than 20 % of 5 mm, nothing happens.
    c.set(764, 11000.020);
    let (out, d) = pr.run(&CompConfig::from_constants(&c));
    assert!(without_gouges(&d).is_empty());
    // The backward move stays, and it cuts into N20.
    assert!(gouges(&d).iter().any(|g| g.block == Some(30)));
    assert_close(piece(&out, 30, Role::Equidistant).1, p(15.0, 2.0), 1e-12);
}

// §4.5 R765: report the equidistant farther than the percentage of the radius.
#[test]
fn r765_position_test() {
    let mut pr = Prog::new(-10.0, 0.0);
    let a = (-165f64).to_radians();
    pr.g41(1, 1.0)
        .line(0.0, 0.0)
        .line(20.0, 0.0)
        .line(20.0 + 20.0 * a.cos(), 20.0 * a.sin())
        .g40()
        .line(0.0, -20.0);
    let mut c = Constants::new();
    c.set(95, 10000.0);
    let (_, d) = pr.run(&CompConfig::from_constants(&c));
    assert!(d.is_empty());
    c.set(765, 1000.0); // report
    let (out, d) = pr.run(&CompConfig::from_constants(&c));
    let w = with_severity(&d, Severity::Warning);
    assert_eq!(w.len(), 1);
    assert_eq!(w[0].block, Some(30));
    assert!(out.iter().all(|c| c.role != Role::CornerArc));
    c.set(765, 10000.0); // optimise silently: arc instead
    let (out, d) = pr.run(&CompConfig::from_constants(&c));
    assert!(d.is_empty());
    assert_eq!(out.iter().filter(|c| c.role == Role::CornerArc).count(), 1);
    check_path(&pr.blocks, &out, Plane::G17, 1e-9).unwrap();
}

// ---- Output traceability and the streaming seam -----------------------------------------

// Output blocks keep seq/n/line of their source; inserted arcs carry the block they lead into.
#[test]
fn output_is_traceable_and_streams_with_bounded_look_ahead() {
    let mut pr = Prog::new(-10.0, 0.0);
    pr.g42(1, 1.0).line(0.0, 0.0);
    for k in 0..50 {
        let y = if k % 2 == 0 { 10.0 } else { 0.0 };
        pr.line(10.0 * (k + 1) as f64, y);
    }
    pr.g40().line(600.0, 0.0);
    let c = CompConfig {
        corner_mode: CornerMode::ArcAboveLimit,
        ..cfg()
    };
    let mut comp = Compensator::new(c);
    let mut out = Vec::new();
    let mut max_held = 0;
    for b in &pr.blocks {
        comp.push(b).unwrap();
        max_held = max_held.max(comp.held_blocks());
        while let Some(o) = comp.poll_traced() {
            out.push(o);
        }
    }
    comp.finish();
    while let Some(o) = comp.poll_traced() {
        out.push(o);
    }
    assert!(max_held <= kernel::comp::WINDOW + 1);
    check_path(&pr.blocks, &out, Plane::G17, 1e-9).unwrap();
    for o in &out {
        let src = &pr.blocks[o.block.seq as usize];
        assert_eq!((o.block.n, o.block.line), (src.n, src.line));
    }
}

/// A short concave G3 arc (radius 8.5748, 12.3°, tool 5 on its inside) between two inside
/// corners: its equidistant runs backwards (found by a search, see docs/compensation.md).
fn short_concave_arc() -> Prog {
    let (rho, sweep, turn1, turn2) = (8.5748, 0.214675, 1.18565, -0.93455);
    let mut pr = Prog::new(-40.0, 0.0);
    pr.g41(1, 5.0).line(-20.0, 0.0).line(0.0, 0.0);
    let c = V2::from_angle(turn1).left() * rho;
    let e = c + V2::from_angle((-c).angle() + sweep) * rho;
    pr.arc(false, e.x, e.y, c.x, c.y);
    let f = e + V2::from_angle(turn1 + sweep + turn2) * 30.0;
    pr.line(f.x, f.y).g40().line(f.x + 1.0, f.y + 1.0);
    pr
}

// §4.5 d5: without it the backward arc is cut as a short arc in the reverse direction (never
// the complementary, almost full circle); with d5 it is replaced by its chord.
#[test]
fn d5_replaces_a_backward_arc_by_its_chord() {
    let pr = short_concave_arc();
    let (out, d) = pr.run(&cfg());
    assert!(
        d.iter()
            .any(|d| d.block == Some(30) && d.code == DiagCode::EquidistantBackward)
    );
    let arc = out.iter().find(|c| c.block.n == Some(30)).unwrap();
    let (s, e, path) = arc.block.motion().unwrap();
    let Path::Arc { dir, center, .. } = path else {
        panic!("{arc:?}")
    };
    assert_eq!(
        dir,
        kernel::block::ArcDir::Cw,
        "reversed, not the complementary arc"
    );
    let c = V2::of(&center, Plane::G17);
    let span = kernel::comp::geom::wrap_pi(
        (V2::of(&e, Plane::G17) - c).angle() - (V2::of(&s, Plane::G17) - c).angle(),
    );
    assert!(span < 0.0 && span > -1.0, "{span}");
    let mut c5 = cfg();
    c5.check.complementary_arc_to_line = true;
    let (out, d) = pr.run(&c5);
    assert!(
        d.iter()
            .any(|d| d.block == Some(30) && d.code == DiagCode::EquidistantArcBackward),
        "{d:?}"
    );
    let b = out.iter().find(|c| c.block.n == Some(30)).unwrap();
    assert_eq!(
        (b.role, b.block.motion().unwrap().2),
        (Role::EquidistantChord, Path::Line)
    );
    check_path(&pr.blocks, &out, Plane::G17, 1e-9).unwrap();
}

// §4.3 (equidistant of an arc is the concentric circle ρ ∓ r): a slot end whose radius equals
// the tool radius collapses to its centre; a smaller inside radius is an error.
#[test]
fn inside_arc_equal_to_or_smaller_than_the_tool() {
    let slot = |r: f64| {
        let mut pr = Prog::new(-10.0, -5.0);
        pr.g41(1, r)
            .line(0.0, -5.0)
            .line(10.0, -5.0)
            .arc(false, 10.0, 5.0, 10.0, 0.0)
            .line(0.0, 5.0)
            .g40()
            .line(-10.0, 5.0);
        pr
    };
    let pr = slot(5.0);
    let (out, d) = pr.run(&cfg());
    assert!(errors(&d).is_empty(), "{d:?}");
    check_path(&pr.blocks, &out, Plane::G17, 1e-9).unwrap();
    assert_close(piece(&out, 20, Role::Equidistant).1, p(10.0, 0.0), 1e-12);
    assert!(
        out.iter()
            .any(|c| c.block.n == Some(30) && c.role == Role::Collapsed)
    );
    assert_close(piece(&out, 40, Role::Equidistant).0, p(10.0, 0.0), 1e-12);
    let (_, d) = slot(5.5).run(&cfg());
    let e = errors(&d);
    assert_eq!(e[0].block, Some(30));
    assert_eq!(e[0].code, DiagCode::ToolLargerThanArc);
}

// §4.3: a full circle (start = end) is compensated as a full circle, written as two halves;
// a helix keeps its linear motion of the third axis.
#[test]
fn full_circle_and_helix() {
    let mut pr = Prog::new(-20.0, 0.0);
    pr.g42(1, 2.0).line(-10.0, 0.0).line(0.0, 0.0);
    // Full G3 circle about (0,10), tangent to the line; the third axis goes down by 4 mm.
    let start = pr.pos;
    let mut end = start;
    end[2] = -4.0;
    let mut center = start;
    center[1] = 10.0;
    pr.pos = end;
    let last = pr.blocks.last().copied().unwrap();
    pr.blocks.push(kernel::block::Block {
        seq: last.seq + 1,
        n: Some(30),
        line: last.line + 1,
        kind: BlockKind::Motion {
            start,
            end,
            path: Path::Arc {
                dir: kernel::block::ArcDir::Ccw,
                center,
                plane: Plane::G17,
            },
        },
        ..last
    });
    pr.line(10.0, 0.0).g40().line(20.0, 0.0);
    let (out, d) = pr.run(&cfg());
    assert!(errors(&d).is_empty(), "{d:?}");
    check_path(&pr.blocks, &out, Plane::G17, 1e-9).unwrap();
    let halves: Vec<_> = out.iter().filter(|c| c.block.n == Some(30)).collect();
    assert_eq!(halves.len(), 2);
    let (s0, e0, _) = halves[0].block.motion().unwrap();
    let (s1, e1, _) = halves[1].block.motion().unwrap();
    // Tool right of a G3 circle: outside, radius 12, through (0,-2) and (0,22).
    assert_close(V2::of(&s0, Plane::G17), p(0.0, -2.0), 1e-12);
    assert_close(V2::of(&e0, Plane::G17), p(0.0, 22.0), 1e-9);
    assert_close(V2::of(&e1, Plane::G17), p(0.0, -2.0), 1e-9);
    assert_eq!((s0[2], e0[2], s1[2], e1[2]), (0.0, -2.0, -2.0, -4.0));
}

// Messages wait for `take_diagnostics`, at most MAX_PENDING_DIAGNOSTICS of them; the rest is
// counted so memory stays bounded when nobody collects them.
#[test]
fn pending_messages_are_bounded() {
    use kernel::comp::MAX_PENDING_DIAGNOSTICS;
    let mut pr = Prog::new(-10.0, 0.0);
    pr.g42(1, 1.0).line(0.0, 0.0);
    let n = 2 * MAX_PENDING_DIAGNOSTICS + 600; // half the corners are outside
    for k in 0..n {
        let y = if k % 2 == 0 { 10.0 } else { 0.0 };
        pr.line(10.0 * (k + 1) as f64, y);
    }
    let c = CompConfig {
        corner_mode: CornerMode::ArcAboveLimit,
        report_inserted_arcs: true,
        ..cfg()
    };
    let mut comp = Compensator::new(c);
    let mut arcs = 0;
    for b in &pr.blocks {
        comp.push(b).unwrap();
        while let Some(o) = comp.poll_traced() {
            arcs += usize::from(o.role == Role::CornerArc);
        }
    }
    comp.finish();
    while let Some(o) = comp.poll_traced() {
        arcs += usize::from(o.role == Role::CornerArc);
    }
    let d = comp.take_diagnostics();
    assert_eq!(d.len(), MAX_PENDING_DIAGNOSTICS + 1);
    let more = arcs - MAX_PENDING_DIAGNOSTICS;
    assert!(
        d.last()
            .unwrap()
            .message
            .starts_with(&format!("{more} more"))
    );
    // compensate_all collects as it goes and loses nothing.
    let (_, all) = pr.run(&c);
    assert_eq!(all.len(), arcs);
}
