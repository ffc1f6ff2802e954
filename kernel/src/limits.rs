//! Soft limits (travel limits) per axis, in machine coordinates (issue #15).
//!
//! A program, an MDI block or a jog must never command an axis beyond its configured travel.
//! The check runs on the planned tool-centre path (after offsets and radius compensation,
//! so with the offsets in force), including the bulge of arcs between their end points.
//! An axis without limits (`min`/`max` not configured) is not checked on that side.

use crate::block::Plane;
use crate::diag::{DiagCode, Diagnostic};
use crate::plan::{SegPath, Segment};
use crate::units::{AxesMm, MAX_AXES};

/// Tolerance for a point on a limit: a path ending exactly on the limit is allowed.
const ON_LIMIT_MM: f64 = 1e-6;

/// Travel limits of every axis, machine coordinates (mm or degrees). Infinite = no limit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SoftLimits {
    pub min_mm: [f64; MAX_AXES],
    pub max_mm: [f64; MAX_AXES],
}

impl Default for SoftLimits {
    fn default() -> Self {
        SoftLimits::NONE
    }
}

/// Which limit an axis would pass, by how much, and where.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LimitHit {
    /// Axis index (machine order).
    pub axis: usize,
    /// Axis letter ('?' until [`LimitHit::diagnostic`] names it).
    pub axis_name: char,
    /// Farthest position the path reaches beyond the limit, machine coordinates.
    pub position_mm: f64,
    /// The limit passed.
    pub limit_mm: f64,
    /// True for the upper limit, false for the lower.
    pub upper: bool,
}

impl SoftLimits {
    /// No axis limited.
    pub const NONE: SoftLimits = SoftLimits {
        min_mm: [f64::NEG_INFINITY; MAX_AXES],
        max_mm: [f64::INFINITY; MAX_AXES],
    };

    /// Whether any axis has a limit.
    pub fn any(&self) -> bool {
        self.min_mm.iter().any(|v| v.is_finite()) || self.max_mm.iter().any(|v| v.is_finite())
    }

    /// The first axis whose position lies beyond a limit.
    pub fn check_point(&self, p: &AxesMm, axes: usize) -> Option<LimitHit> {
        self.check_extent(p, p, axes)
    }

    /// The first axis the path leaves its limits on, with the farthest position it reaches.
    pub fn check_path(&self, path: &SegPath, axes: usize) -> Option<LimitHit> {
        let (lo, hi) = extent(path, axes);
        self.check_extent(&lo, &hi, axes)
    }

    fn check_extent(&self, lo: &AxesMm, hi: &AxesMm, axes: usize) -> Option<LimitHit> {
        for axis in 0..axes.min(MAX_AXES) {
            if hi[axis] > self.max_mm[axis] + ON_LIMIT_MM {
                return Some(LimitHit {
                    axis,
                    axis_name: '?',
                    position_mm: hi[axis],
                    limit_mm: self.max_mm[axis],
                    upper: true,
                });
            }
            if lo[axis] < self.min_mm[axis] - ON_LIMIT_MM {
                return Some(LimitHit {
                    axis,
                    axis_name: '?',
                    position_mm: lo[axis],
                    limit_mm: self.min_mm[axis],
                    upper: false,
                });
            }
        }
        None
    }

    /// Distance from `p` to the limit of `axis` in direction `dir` (+1 or -1); infinite when
    /// that side has no limit; never negative.
    pub fn room_mm(&self, p: f64, axis: usize, dir: f64) -> f64 {
        let d = if dir >= 0.0 {
            self.max_mm[axis] - p
        } else {
            p - self.min_mm[axis]
        };
        d.max(0.0)
    }
}

impl LimitHit {
    /// The refusal of a planned segment: block, line, axis, position and limit.
    pub fn diagnostic(&self, seg: &Segment, axis_names: &[char]) -> Diagnostic {
        let name = axis_names.get(self.axis).copied().unwrap_or('?');
        let side = if self.upper { "upper" } else { "lower" };
        let mut d = Diagnostic::error(
            DiagCode::SoftLimit,
            seg.n,
            seg.line,
            0,
            format!(
                "{name} would reach {:.3} (machine coordinates, offsets included), beyond its \
                 {side} soft limit {:.3}",
                self.position_mm, self.limit_mm
            ),
        );
        d.limit = Some(LimitHit {
            axis_name: name,
            ..*self
        });
        d
    }
}

/// Per-axis bounding box of where a path goes: its end point, plus the quadrant points an
/// arc passes. The start point is left out: it is where the previous segment ended (checked
/// there) or where the machine stands, so a move from beyond a limit back inside is allowed.
fn extent(path: &SegPath, _axes: usize) -> (AxesMm, AxesMm) {
    let e = path.end();
    let mut lo = e;
    let mut hi = e;
    if let SegPath::Arc {
        center,
        plane,
        radius_mm,
        start_angle_rad,
        sweep_rad,
        ..
    } = *path
    {
        arc_extent(
            &mut lo,
            &mut hi,
            (center, plane, radius_mm),
            start_angle_rad,
            sweep_rad,
        );
    }
    (lo, hi)
}

/// Widens `lo`/`hi` by the axis extremes (angles k·90°) that the arc sweeps over.
fn arc_extent(
    lo: &mut AxesMm,
    hi: &mut AxesMm,
    (center, plane, r): (AxesMm, Plane, f64),
    a0: f64,
    sweep: f64,
) {
    let (a, b) = plane.axes();
    let (from, to) = if sweep >= 0.0 {
        (a0, a0 + sweep)
    } else {
        (a0 + sweep, a0)
    };
    let quarter = std::f64::consts::FRAC_PI_2;
    let mut k = (from / quarter).ceil();
    while k * quarter <= to {
        let ang = k * quarter;
        let (pa, pb) = (center[a] + r * ang.cos(), center[b] + r * ang.sin());
        lo[a] = lo[a].min(pa);
        hi[a] = hi[a].max(pa);
        lo[b] = lo[b].min(pb);
        hi[b] = hi[b].max(pb);
        k += 1.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::block::ArcDir;

    fn p(x: f64, y: f64) -> AxesMm {
        let mut v = AxesMm::ZERO;
        v[0] = x;
        v[1] = y;
        v
    }

    fn limits() -> SoftLimits {
        let mut l = SoftLimits::NONE;
        l.min_mm[0] = -10.0;
        l.max_mm[0] = 100.0;
        l.max_mm[1] = 50.0;
        l
    }

    #[test]
    fn lines_inside_and_on_the_limit_pass() {
        let path = SegPath::Line {
            start: p(0.0, 0.0),
            end: p(100.0, -1e6),
        };
        assert_eq!(limits().check_path(&path, 3), None, "Y has no lower limit");
    }

    #[test]
    fn a_line_beyond_a_limit_names_axis_position_and_limit() {
        let path = SegPath::Line {
            start: p(0.0, 0.0),
            end: p(-12.5, 0.0),
        };
        let hit = limits().check_path(&path, 3).unwrap();
        assert_eq!(
            (hit.axis, hit.position_mm, hit.limit_mm, hit.upper),
            (0, -12.5, -10.0, false)
        );
    }

    #[test]
    fn an_arc_bulging_over_a_limit_is_caught_between_its_end_points() {
        // Half circles from (0,40) to (0,0) about (0,20): counter-clockwise through X=-20,
        // clockwise through X=+20; both end points are inside every limit.
        let ccw = SegPath::arc(
            p(0.0, 40.0),
            p(0.0, 0.0),
            p(0.0, 20.0),
            Plane::G17,
            ArcDir::Ccw,
        );
        let hit = limits().check_path(&ccw, 3).unwrap();
        assert_eq!((hit.axis, hit.upper), (0, false));
        assert!((hit.position_mm + 20.0).abs() < 1e-9);
        let cw = SegPath::arc(
            p(0.0, 40.0),
            p(0.0, 0.0),
            p(0.0, 20.0),
            Plane::G17,
            ArcDir::Cw,
        );
        assert_eq!(limits().check_path(&cw, 3), None);
        let mut tight = limits();
        tight.max_mm[0] = 15.0;
        assert_eq!(tight.check_path(&cw, 3).map(|h| h.upper), Some(true));
    }

    #[test]
    fn moving_back_inside_from_beyond_a_limit_is_allowed() {
        let back = SegPath::Line {
            start: p(120.0, 0.0),
            end: p(90.0, 0.0),
        };
        assert_eq!(limits().check_path(&back, 3), None);
    }

    #[test]
    fn room_to_the_limit() {
        let l = limits();
        assert_eq!(l.room_mm(90.0, 0, 1.0), 10.0);
        assert_eq!(l.room_mm(90.0, 0, -1.0), 100.0);
        assert_eq!(l.room_mm(120.0, 0, 1.0), 0.0);
        assert!(l.room_mm(0.0, 1, -1.0).is_infinite());
    }
}
