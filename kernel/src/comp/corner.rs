//! The junction of two compensated elements: intersection of the equidistants, point on the
//! perpendicular, or an inserted arc (SPEC §4.3 R339, §4.4 R234, §4.5 R765).

use std::f64::consts::PI;

use super::config::{CompConfig, CornerMode};
use super::geom::{EPS_MM, Geo, V2, intersect, turn_angle};

/// Tangents closer than this are "exactly tangent" (rad): SPEC §4.4 R234 = 0 still skips the
/// intersection there, where it is undefined (parallel lines) or a double root.
pub const TANGENT_RAD: f64 = 1e-10;

/// How the tool centre passes a junction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Junction {
    /// Both equidistants end/start at one point: their intersection, or (tangent or below
    /// R234) the point on the perpendicular at the junction.
    Point { at: V2, intersection: bool },
    /// An arc of tool radius about the programmed corner, from the end of the first
    /// equidistant to the start of the second; `sweep_rad` signed, positive counter-clockwise.
    Arc {
        corner: V2,
        from: V2,
        to: V2,
        sweep_rad: f64,
    },
}

/// A resolved junction and what the position test (R765) saw there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Resolved {
    pub junction: Junction,
    /// Distance of the intersection from the programmed corner when it exceeds the R765 limit.
    pub far_mm: Option<f64>,
    /// R765 d8 replaced a far intersection by an arc.
    pub position_optimised: bool,
}

/// The equidistants of two elements do not meet: "NENALEZEN PRUSEČÍK EKVIDISTANT".
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NoIntersection;

/// Resolves the junction between `g1` and `g2`, both compensated at signed offset `s_mm`
/// (positive = left). Pure: no state changes, so the caller can try alternatives (R397 d8).
pub fn resolve(
    g1: &Geo,
    g2: &Geo,
    s_mm: f64,
    cfg: &CompConfig,
) -> Result<Resolved, NoIntersection> {
    let p = g1.end();
    let r = s_mm.abs();
    let t1 = g1.end_tangent();
    let t2 = g2.start_tangent();
    let theta = turn_angle(t1, t2);
    let e1 = g1.offset_end(s_mm);
    let s2 = g2.offset_start(s_mm);
    let point = |at, intersection| Resolved {
        junction: Junction::Point { at, intersection },
        far_mm: None,
        position_optimised: false,
    };
    if r <= EPS_MM {
        return Ok(point(p, false));
    }
    // SPEC §4.4: near-tangent junction → point on the perpendicular (mean normal), no
    // ill-conditioned intersection. Its distance error is r·(1 − cos(α/2)).
    let limit = cfg.continuity_limit_deg.to_radians().max(TANGENT_RAD);
    if theta.abs() <= limit {
        let n = (t1.left() + t2.left()).unit();
        return Ok(point(p + n * s_mm, false));
    }
    // Outside corner: the tool is on the outer side of the turn (the material angle > 180°).
    // A full reversal always has the tool going round the end point.
    let reversal = theta.abs() >= PI - 1e-9;
    let outside = reversal || s_mm * theta < 0.0;
    let sweep = if reversal { -s_mm.signum() * PI } else { theta };
    let arc = |position_optimised| Resolved {
        junction: Junction::Arc {
            corner: p,
            from: e1,
            to: s2,
            sweep_rad: sweep,
        },
        far_mm: None,
        position_optimised,
    };
    let arc_by_angle = matches!(
        cfg.corner_mode,
        CornerMode::ArcAboveLimit | CornerMode::ArcAboveLimitOrMissing
    ) && outside
        && theta.abs().to_degrees() > cfg.arc_insertion_limit_deg;
    if arc_by_angle {
        return Ok(arc(false));
    }
    let arc_if_missing = matches!(
        cfg.corner_mode,
        CornerMode::ArcAboveLimitOrMissing | CornerMode::ArcIfMissing
    );
    // The root nearest the midpoint of the two perpendicular points: the same as "nearest the
    // programmed corner" at real corners, and robust near tangency where the two roots of two
    // large circles are both about r from the corner.
    let near = (e1 + s2) * 0.5;
    match intersect(&g1.support(s_mm), &g2.support(s_mm), near) {
        Some(x) => {
            let limit_mm = cfg.position.percent / 100.0 * r;
            let dist = x.dist(p);
            let far = (cfg.position.report || cfg.position.optimise) && dist > limit_mm;
            if far && cfg.position.optimise && outside {
                let mut res = arc(true);
                res.far_mm = Some(dist);
                return Ok(res);
            }
            let mut res = point(x, true);
            res.far_mm = far.then_some(dist);
            Ok(res)
        }
        None if arc_if_missing => Ok(arc(false)),
        None => Err(NoIntersection),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(ax: f64, ay: f64, bx: f64, by: f64) -> Geo {
        Geo::Line {
            a: V2::new(ax, ay),
            b: V2::new(bx, by),
        }
    }

    // SPEC §4.3 8.R339 = 0: inside and outside corners of two lines meet at the intersection.
    #[test]
    fn right_angle_corners_intersect() {
        let cfg = CompConfig::default();
        let g1 = line(0.0, 0.0, 10.0, 0.0);
        let g2 = line(10.0, 0.0, 10.0, 10.0);
        // Left turn with the tool left: inside corner.
        let r = resolve(&g1, &g2, 2.0, &cfg).unwrap();
        assert_eq!(
            r.junction,
            Junction::Point {
                at: V2::new(8.0, 2.0),
                intersection: true
            }
        );
        // Tool right: outside corner.
        let r = resolve(&g1, &g2, -2.0, &cfg).unwrap();
        let Junction::Point { at, .. } = r.junction else {
            panic!("{r:?}")
        };
        assert!(at.dist(V2::new(12.0, -2.0)) < 1e-12);
    }

    // SPEC §4.3 8.R339 = 1: arc at outside corners above the limit, intersection below.
    #[test]
    fn arc_inserted_above_limit_only_outside() {
        let cfg = CompConfig {
            corner_mode: CornerMode::ArcAboveLimit,
            arc_insertion_limit_deg: 45.0,
            ..CompConfig::default()
        };
        let g1 = line(0.0, 0.0, 10.0, 0.0);
        let g2 = line(10.0, 0.0, 10.0, 10.0);
        let r = resolve(&g1, &g2, -2.0, &cfg).unwrap();
        assert!(
            matches!(r.junction, Junction::Arc { sweep_rad, .. } if (sweep_rad - PI / 2.0).abs() < 1e-12)
        );
        let r = resolve(&g1, &g2, 2.0, &cfg).unwrap();
        assert!(matches!(r.junction, Junction::Point { .. }));
        // 30° turn is below the 45° limit: intersection.
        let g3 = line(10.0, 0.0, 20.0, 10.0 * (30f64).to_radians().tan());
        let r = resolve(&g1, &g3, -2.0, &cfg).unwrap();
        assert!(matches!(r.junction, Junction::Point { .. }));
    }

    // SPEC §4.3: a reversal has no intersection: error in mode 0, an arc in mode 2 and 4.
    #[test]
    fn reversal_has_no_intersection() {
        let g1 = line(0.0, 0.0, 10.0, 0.0);
        let g2 = line(10.0, 0.0, 0.0, 0.0);
        assert_eq!(
            resolve(&g1, &g2, 1.0, &CompConfig::default()),
            Err(NoIntersection)
        );
        for mode in [CornerMode::ArcAboveLimitOrMissing, CornerMode::ArcIfMissing] {
            let cfg = CompConfig {
                corner_mode: mode,
                arc_insertion_limit_deg: 179.9,
                ..CompConfig::default()
            };
            let r = resolve(&g1, &g2, 1.0, &cfg).unwrap();
            assert!(
                matches!(r.junction, Junction::Arc { sweep_rad, .. } if (sweep_rad + PI).abs() < 1e-12)
            );
        }
    }

    // SPEC §4.5 R765: a far intersection is reported, and with d8 replaced by an arc.
    #[test]
    fn position_test_reports_and_optimises() {
        let mut cfg = CompConfig::default();
        cfg.position.report = true;
        let g1 = line(0.0, 0.0, 10.0, 0.0);
        // 160° turn to the right; tool left → outside, intersection r/cos(80°) = 5.76 r away.
        let a = (-160f64).to_radians();
        let g2 = line(10.0, 0.0, 10.0 + 10.0 * a.cos(), 10.0 * a.sin());
        let r = resolve(&g1, &g2, 1.0, &cfg).unwrap();
        assert!(r.far_mm.unwrap() > 3.0 && matches!(r.junction, Junction::Point { .. }));
        cfg.position.optimise = true;
        let r = resolve(&g1, &g2, 1.0, &cfg).unwrap();
        assert!(r.position_optimised && matches!(r.junction, Junction::Arc { .. }));
    }
}
