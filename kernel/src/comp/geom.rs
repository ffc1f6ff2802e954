//! Plane geometry of radius compensation: vectors, programmed elements (lines and arcs) in the
//! compensation plane, their equidistants and the intersections of equidistants (SPEC §4.3).
//!
//! Coordinates are the two axes of the plane in `Plane::axes()` order, so "counter-clockwise"
//! here is G3 and "left" is G41 (SPEC §4.1).

use std::f64::consts::{PI, TAU};
use std::ops::{Add, Mul, Neg, Sub};

use crate::block::Plane;
use crate::units::AxesMm;

/// Lengths below this are zero (mm). Coordinates of real machines stay below 1e5 mm, where
/// f64 resolves ~1e-11 mm, so this leaves two orders of margin.
pub const EPS_MM: f64 = 1e-9;

/// A point or vector in the compensation plane, millimetres.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct V2 {
    pub x: f64,
    pub y: f64,
}

impl V2 {
    pub const fn new(x: f64, y: f64) -> Self {
        V2 { x, y }
    }
    /// The plane components of a machine position.
    pub fn of(p: &AxesMm, plane: Plane) -> Self {
        let (a, b) = plane.axes();
        V2::new(p[a], p[b])
    }
    /// Writes the plane components into a machine position.
    pub fn put(self, p: &mut AxesMm, plane: Plane) {
        let (a, b) = plane.axes();
        p[a] = self.x;
        p[b] = self.y;
    }
    pub fn dot(self, o: V2) -> f64 {
        self.x * o.x + self.y * o.y
    }
    pub fn cross(self, o: V2) -> f64 {
        self.x * o.y - self.y * o.x
    }
    pub fn len(self) -> f64 {
        self.x.hypot(self.y)
    }
    /// Rotated +90°: the left normal of a direction.
    pub fn left(self) -> V2 {
        V2::new(-self.y, self.x)
    }
    /// Unit vector, or zero for a zero vector.
    pub fn unit(self) -> V2 {
        let l = self.len();
        if l > 0.0 {
            self * (1.0 / l)
        } else {
            V2::default()
        }
    }
    pub fn angle(self) -> f64 {
        self.y.atan2(self.x)
    }
    pub fn from_angle(a: f64) -> V2 {
        V2::new(a.cos(), a.sin())
    }
    pub fn dist(self, o: V2) -> f64 {
        (self - o).len()
    }
    pub fn is_finite(self) -> bool {
        self.x.is_finite() && self.y.is_finite()
    }
}

impl Add for V2 {
    type Output = V2;
    fn add(self, o: V2) -> V2 {
        V2::new(self.x + o.x, self.y + o.y)
    }
}
impl Sub for V2 {
    type Output = V2;
    fn sub(self, o: V2) -> V2 {
        V2::new(self.x - o.x, self.y - o.y)
    }
}
impl Mul<f64> for V2 {
    type Output = V2;
    fn mul(self, k: f64) -> V2 {
        V2::new(self.x * k, self.y * k)
    }
}
impl Neg for V2 {
    type Output = V2;
    fn neg(self) -> V2 {
        V2::new(-self.x, -self.y)
    }
}

/// Wraps an angle into (-π, π].
pub fn wrap_pi(a: f64) -> f64 {
    let mut w = a % TAU;
    if w <= -PI {
        w += TAU;
    } else if w > PI {
        w -= TAU;
    }
    w
}

/// Signed angle turning direction `t1` into `t2`, in (-π, π] (positive = left turn).
pub fn turn_angle(t1: V2, t2: V2) -> f64 {
    t1.cross(t2).atan2(t1.dot(t2))
}

/// A programmed element of the contour in the compensation plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Geo {
    Line {
        a: V2,
        b: V2,
    },
    /// Arc from `a` to `b` about `c`; `sweep_rad` signed, positive counter-clockwise (G3),
    /// ±2π for a full circle.
    Arc {
        a: V2,
        b: V2,
        c: V2,
        sweep_rad: f64,
    },
}

impl Geo {
    /// Builds an arc; the sweep runs in the programmed direction, a full circle when the end
    /// coincides with the start.
    pub fn arc(a: V2, b: V2, c: V2, ccw: bool) -> Geo {
        let a0 = (a - c).angle();
        let a1 = (b - c).angle();
        let mut sweep = a1 - a0;
        if a.dist(b) <= EPS_MM {
            sweep = if ccw { TAU } else { -TAU };
        } else if ccw {
            while sweep <= 0.0 {
                sweep += TAU;
            }
        } else {
            while sweep >= 0.0 {
                sweep -= TAU;
            }
        }
        Geo::Arc {
            a,
            b,
            c,
            sweep_rad: sweep,
        }
    }

    pub fn start(&self) -> V2 {
        match *self {
            Geo::Line { a, .. } | Geo::Arc { a, .. } => a,
        }
    }
    pub fn end(&self) -> V2 {
        match *self {
            Geo::Line { b, .. } | Geo::Arc { b, .. } => b,
        }
    }
    pub fn is_arc(&self) -> bool {
        matches!(self, Geo::Arc { .. })
    }
    /// Programmed length in the plane, mm.
    pub fn length_mm(&self) -> f64 {
        match *self {
            Geo::Line { a, b } => a.dist(b),
            Geo::Arc {
                a, c, sweep_rad, ..
            } => a.dist(c) * sweep_rad.abs(),
        }
    }
    /// The chord replacing an arc (R397 d5/d7/d8).
    pub fn chord(&self) -> Geo {
        Geo::Line {
            a: self.start(),
            b: self.end(),
        }
    }
    fn tangent_at(&self, p: V2) -> V2 {
        match *self {
            Geo::Line { a, b } => (b - a).unit(),
            Geo::Arc { c, sweep_rad, .. } => {
                let radial = (p - c).unit().left();
                if sweep_rad >= 0.0 { radial } else { -radial }
            }
        }
    }
    /// Unit tangent at the start, in the direction of motion.
    pub fn start_tangent(&self) -> V2 {
        self.tangent_at(self.start())
    }
    /// Unit tangent at the end.
    pub fn end_tangent(&self) -> V2 {
        match *self {
            Geo::Line { .. } => self.start_tangent(),
            Geo::Arc {
                a, c, sweep_rad, ..
            } => {
                // From the start radius and the sweep, so an end point slightly off the circle
                // (within R55) does not tilt the tangent.
                let p = c + V2::from_angle((a - c).angle() + sweep_rad) * a.dist(c);
                self.tangent_at(p)
            }
        }
    }
    /// Radius of the equidistant of an arc at signed offset `s_mm` (positive = left):
    /// left of a G3 arc is towards the centre.
    pub fn offset_radius(&self, s_mm: f64) -> Option<f64> {
        match *self {
            Geo::Line { .. } => None,
            Geo::Arc {
                a, c, sweep_rad, ..
            } => {
                let rho = a.dist(c);
                Some(if sweep_rad >= 0.0 {
                    rho - s_mm
                } else {
                    rho + s_mm
                })
            }
        }
    }
    /// The support of the equidistant at signed offset `s_mm`: an infinite line, a circle, or
    /// a point when the offset radius is zero (tool radius equal to a concave arc radius).
    pub fn support(&self, s_mm: f64) -> Support {
        match *self {
            Geo::Line { a, b } => {
                let d = (b - a).unit();
                Support::Line {
                    p: a + d.left() * s_mm,
                    d,
                }
            }
            Geo::Arc { c, .. } => {
                let r = self.offset_radius(s_mm).unwrap_or(0.0);
                if r.abs() <= EPS_MM {
                    Support::Point(c)
                } else {
                    Support::Circle { c, r }
                }
            }
        }
    }
    /// Equidistant point on the perpendicular at the start.
    pub fn offset_start(&self, s_mm: f64) -> V2 {
        self.start() + self.start_tangent().left() * s_mm
    }
    /// Equidistant point on the perpendicular at the end.
    pub fn offset_end(&self, s_mm: f64) -> V2 {
        match *self {
            Geo::Line { b, .. } => b + self.end_tangent().left() * s_mm,
            Geo::Arc { c, .. } => {
                let r = self.offset_radius(s_mm).unwrap_or(0.0);
                // On the offset circle, in the direction of the programmed end.
                let u = (self.end() - c).unit();
                c + u * r
            }
        }
    }
}

/// Support of an equidistant: what intersections are computed on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Support {
    Line { p: V2, d: V2 },
    Circle { c: V2, r: f64 },
    Point(V2),
}

impl Support {
    /// Signed distance of `q` from the support (0 on it).
    pub fn distance(&self, q: V2) -> f64 {
        match *self {
            Support::Line { p, d } => d.cross(q - p),
            Support::Circle { c, r } => q.dist(c) - r.abs(),
            Support::Point(c) => q.dist(c),
        }
    }
    fn scale(&self) -> f64 {
        match *self {
            Support::Line { p, .. } => p.len(),
            Support::Circle { c, r } => c.len() + r.abs(),
            Support::Point(c) => c.len(),
        }
    }
}

/// Intersection of two supports: the root nearest `near`, or `None` when they do not meet.
/// Grazing contacts that miss only by rounding (~1e-12 of the coordinates) count as a touch.
pub fn intersect(s1: &Support, s2: &Support, near: V2) -> Option<V2> {
    let scale = 1.0 + s1.scale().max(s2.scale()) + near.len();
    let tol = 1e-12 * scale;
    let pick = |p: V2, q: V2| {
        if p.dist(near) <= q.dist(near) { p } else { q }
    };
    let x = match (*s1, *s2) {
        (Support::Line { p: p1, d: d1 }, Support::Line { p: p2, d: d2 }) => {
            let den = d1.cross(d2);
            if den.abs() <= 1e-15 {
                return None;
            }
            let t = (p2 - p1).cross(d2) / den;
            p1 + d1 * t
        }
        (Support::Line { p, d }, Support::Circle { c, r })
        | (Support::Circle { c, r }, Support::Line { p, d }) => {
            let (a, b) = line_circle(p, d, c, r.abs(), tol)?;
            pick(a, b)
        }
        (Support::Circle { c: c1, r: r1 }, Support::Circle { c: c2, r: r2 }) => {
            let (a, b) = circle_circle(c1, r1.abs(), c2, r2.abs(), tol)?;
            pick(a, b)
        }
        (Support::Point(c), other) | (other, Support::Point(c)) => {
            if other.distance(c).abs() <= 1e-7 * scale.max(1.0) {
                c
            } else {
                return None;
            }
        }
    };
    x.is_finite().then_some(x)
}

fn line_circle(p: V2, d: V2, c: V2, r: f64, tol: f64) -> Option<(V2, V2)> {
    let w = p - c;
    let foot = p - d * w.dot(d);
    let dist = d.cross(w).abs();
    // (r - dist)(r + dist) avoids cancelling two large squares.
    let h2 = (r - dist) * (r + dist);
    if h2 < -tol * r.max(1.0) {
        return None;
    }
    let h = h2.max(0.0).sqrt();
    Some((foot + d * h, foot - d * h))
}

fn circle_circle(c1: V2, r1: f64, c2: V2, r2: f64, tol: f64) -> Option<(V2, V2)> {
    let dv = c2 - c1;
    let d = dv.len();
    if d <= EPS_MM * 1e-3 {
        return None;
    }
    let e = dv * (1.0 / d);
    // Distance from c1 to the radical line, written to avoid r1² − r2² cancellation.
    let a = 0.5 * (d + (r1 - r2) * (r1 + r2) / d);
    let h2 = (r1 - a) * (r1 + a);
    if h2 < -tol * r1.max(r2).max(1.0) {
        return None;
    }
    let h = h2.max(0.0).sqrt();
    let m = c1 + e * a;
    Some((m + e.left() * h, m - e.left() * h))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arc_sweep_follows_direction_and_full_circle() {
        let c = V2::new(0.0, 0.0);
        let a = V2::new(1.0, 0.0);
        let b = V2::new(0.0, 1.0);
        let Geo::Arc { sweep_rad: s, .. } = Geo::arc(a, b, c, true) else {
            unreachable!()
        };
        assert!((s - PI / 2.0).abs() < 1e-12);
        let Geo::Arc { sweep_rad: s, .. } = Geo::arc(a, b, c, false) else {
            unreachable!()
        };
        assert!((s + 1.5 * PI).abs() < 1e-12);
        let Geo::Arc { sweep_rad: s, .. } = Geo::arc(a, a, c, false) else {
            unreachable!()
        };
        assert_eq!(s, -TAU);
    }

    #[test]
    fn offset_of_ccw_arc_is_towards_centre_on_the_left() {
        let g = Geo::arc(V2::new(10.0, 0.0), V2::new(0.0, 10.0), V2::default(), true);
        assert_eq!(g.offset_radius(2.0), Some(8.0));
        let p = g.offset_start(2.0);
        assert!((p.x - 8.0).abs() < 1e-12 && p.y.abs() < 1e-12);
    }

    #[test]
    fn circle_circle_near_tangent_is_finite() {
        // Two circles of 10 km crossing at a tiny angle.
        let r = 10_000.0;
        let c1 = V2::new(0.0, -r);
        let c2 = V2::new(0.0, r + 1e-4);
        let x = circle_circle(c1, r, c2, r + 1e-4 * 0.5, 1e-9).map(|(a, _)| a);
        if let Some(x) = x {
            assert!(x.is_finite());
        }
    }

    #[test]
    fn line_line_intersection() {
        let s1 = Support::Line {
            p: V2::new(0.0, 1.0),
            d: V2::new(1.0, 0.0),
        };
        let s2 = Support::Line {
            p: V2::new(5.0, 0.0),
            d: V2::new(0.0, 1.0),
        };
        let x = intersect(&s1, &s2, V2::default()).unwrap();
        assert!((x.x - 5.0).abs() < 1e-12 && (x.y - 1.0).abs() < 1e-12);
    }
}
