//! Gouge check over a whole compensation run (issue #18, docs/compensation.md decision 19).
//!
//! The junction rules (SPEC §4.3–§4.5) only look at neighbours. This check looks at the whole
//! run: wherever the tool centre comes closer than the tool radius (minus a tolerance) to any
//! programmed element of the compensated contour, the tool cuts into the part there. The
//! programmed elements of the run and the tool-centre pieces (equidistants, inserted arcs,
//! collapsed elements) are collected while the run streams; when the run ends they are
//! checked against each other through a uniform grid over the contour, so the cost is about
//! linear in the number of elements (each tool piece meets the few elements near it).
//!
//! Start and cancel moves are not checked: they leave the equidistant by definition (SPEC
//! §4.2) and are programmed by the machinist as such. The check works in the compensation
//! plane: a run that cuts different contours at different depths is seen from above.

use std::f64::consts::TAU;

use crate::block::{ArcDir, Block, BlockKind, Path, Plane};
use crate::diag::Diagnostic;

use super::geom::{Geo, V2};

/// Elements of one run kept for the check (≈ 70 bytes each, twice: contour and tool). A run
/// longer than this is checked up to here and an information message says so: memory stays
/// bounded while a program of any length streams through the daemon.
pub const MAX_CHECKED_ELEMENTS: usize = 200_000;

/// Tool centres closer than the radius by less than this are not a gouge, mm (numerical
/// noise of intersections is ~1e-9 mm; SPEC §4.4's perpendicular point adds its own error).
pub const GOUGE_TOLERANCE_MM: f64 = 0.001;

/// Every gouge message starts with this (tests and clients tell gouges from other warnings).
pub const MESSAGE_PREFIX: &str = "gouge:";

/// Whether `d` is a gouge found by this check.
pub fn is_gouge(d: &Diagnostic) -> bool {
    d.message.starts_with(MESSAGE_PREFIX)
}

/// A line segment or a circular arc in the compensation plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    Seg {
        a: V2,
        b: V2,
    },
    /// Centre, radius, start angle and signed sweep (positive counter-clockwise).
    Arc {
        c: V2,
        r: f64,
        a0: f64,
        sweep: f64,
    },
}

impl Shape {
    fn of_geo(g: &Geo) -> Shape {
        match *g {
            Geo::Line { a, b } => Shape::Seg { a, b },
            Geo::Arc {
                a, c, sweep_rad, ..
            } => Shape::Arc {
                c,
                r: a.dist(c),
                a0: (a - c).angle(),
                sweep: sweep_rad,
            },
        }
    }

    /// The plane shape of an output motion (`None` for blocks without motion).
    fn of_block(b: &Block, plane: Plane) -> Option<Shape> {
        let BlockKind::Motion { start, end, path } = b.kind else {
            return None;
        };
        let (a, e) = (V2::of(&start, plane), V2::of(&end, plane));
        Some(match path {
            Path::Arc { dir, center, .. } => {
                let c = V2::of(&center, plane);
                let a0 = (a - c).angle();
                let mut sweep = ((e - c).angle() - a0).rem_euclid(TAU);
                if dir == ArcDir::Cw && sweep > 0.0 {
                    sweep -= TAU;
                }
                Shape::Arc {
                    c,
                    r: a.dist(c),
                    a0,
                    sweep,
                }
            }
            _ => Shape::Seg { a, b: e },
        })
    }

    fn ends(&self) -> [V2; 2] {
        match *self {
            Shape::Seg { a, b } => [a, b],
            Shape::Arc { c, r, a0, sweep } => [
                c + V2::from_angle(a0) * r,
                c + V2::from_angle(a0 + sweep) * r,
            ],
        }
    }

    /// Axis-aligned bounding box (min, max).
    fn bbox(&self) -> (V2, V2) {
        match *self {
            Shape::Seg { a, b } => (
                V2::new(a.x.min(b.x), a.y.min(b.y)),
                V2::new(a.x.max(b.x), a.y.max(b.y)),
            ),
            // The circle's box: cheap and only ever too large.
            Shape::Arc { c, r, .. } => (c - V2::new(r, r), c + V2::new(r, r)),
        }
    }

    /// Whether the direction of `p` from the centre lies within the arc.
    fn arc_contains_angle(c: V2, a0: f64, sweep: f64, p: V2) -> bool {
        let t = ((p - c).angle() - a0) * sweep.signum();
        t.rem_euclid(TAU) <= sweep.abs() + 1e-12
    }

    /// Distance from a point.
    pub fn dist_point(&self, p: V2) -> f64 {
        match *self {
            Shape::Seg { a, b } => {
                let d = b - a;
                let l2 = d.dot(d);
                if l2 == 0.0 {
                    return p.dist(a);
                }
                let t = ((p - a).dot(d) / l2).clamp(0.0, 1.0);
                p.dist(a + d * t)
            }
            Shape::Arc { c, r, a0, sweep } => {
                if p.dist(c) > 0.0 && Shape::arc_contains_angle(c, a0, sweep, p) {
                    (p.dist(c) - r).abs()
                } else {
                    let [s, e] = self.ends();
                    p.dist(s).min(p.dist(e))
                }
            }
        }
    }

    /// Points of `self` where the distance to another shape can be smallest besides its end
    /// points: the foot of a circle centre on a segment, the points of an arc on the line
    /// through both centres (or towards a segment's foot).
    fn interior_candidates(&self, other: &Shape) -> [Option<V2>; 2] {
        match (*self, *other) {
            (Shape::Seg { a, b }, Shape::Arc { c, .. }) => {
                let d = b - a;
                let l2 = d.dot(d);
                let t = if l2 > 0.0 { (c - a).dot(d) / l2 } else { -1.0 };
                [(0.0..=1.0).contains(&t).then(|| a + d * t), None]
            }
            (Shape::Arc { c, r, a0, sweep }, Shape::Arc { c: c2, .. }) => {
                // Concentric arcs: the end points are the candidates.
                if c2.dist(c) <= 1e-12 {
                    return [None, None];
                }
                let u = (c2 - c).unit();
                let pick = |p: V2| Shape::arc_contains_angle(c, a0, sweep, p).then_some(p);
                [pick(c + u * r), pick(c - u * r)]
            }
            (Shape::Arc { c, r, a0, sweep }, Shape::Seg { a, b }) => {
                let foot = Shape::Seg { a, b }.interior_candidates(self)[0];
                // A foot on the centre: every arc point is as far from it; the ends decide.
                let u = foot.filter(|f| f.dist(c) > 1e-12).map(|f| (f - c).unit());
                let pick = |p: V2| Shape::arc_contains_angle(c, a0, sweep, p).then_some(p);
                match u {
                    Some(u) => [pick(c + u * r), pick(c - u * r)],
                    None => [None, None],
                }
            }
            (Shape::Seg { .. }, Shape::Seg { .. }) => [None, None],
        }
    }

    /// Whether the two shapes cross or touch.
    fn crosses(&self, other: &Shape) -> bool {
        match (*self, *other) {
            (Shape::Seg { a, b }, Shape::Seg { a: c, b: d }) => {
                let o = |p: V2, q: V2, r: V2| (q - p).cross(r - p);
                let (d1, d2) = (o(a, b, c), o(a, b, d));
                let (d3, d4) = (o(c, d, a), o(c, d, b));
                d1 * d2 < 0.0 && d3 * d4 < 0.0
            }
            (Shape::Seg { a, b }, Shape::Arc { c, r, a0, sweep })
            | (Shape::Arc { c, r, a0, sweep }, Shape::Seg { a, b }) => {
                let d = b - a;
                let l2 = d.dot(d);
                if l2 == 0.0 {
                    return false;
                }
                // |a + t d − c|² = r²
                let w = a - c;
                let (qb, qc) = (w.dot(d) / l2, (w.dot(w) - r * r) / l2);
                let disc = qb * qb - qc;
                if disc < 0.0 {
                    return false;
                }
                let h = disc.sqrt();
                [-qb - h, -qb + h].into_iter().any(|t| {
                    (0.0..=1.0).contains(&t) && Shape::arc_contains_angle(c, a0, sweep, a + d * t)
                })
            }
            (
                Shape::Arc { c, r, a0, sweep },
                Shape::Arc {
                    c: c2,
                    r: r2,
                    a0: b0,
                    sweep: sw2,
                },
            ) => {
                let dv = c2 - c;
                let dd = dv.len();
                if dd == 0.0 || dd > r + r2 || dd < (r - r2).abs() {
                    return false;
                }
                let e = dv * (1.0 / dd);
                let x = 0.5 * (dd + (r - r2) * (r + r2) / dd);
                let h = (r * r - x * x).max(0.0).sqrt();
                let m = c + e * x;
                [m + e.left() * h, m - e.left() * h].into_iter().any(|p| {
                    Shape::arc_contains_angle(c, a0, sweep, p)
                        && Shape::arc_contains_angle(c2, b0, sw2, p)
                })
            }
        }
    }

    /// Smallest distance between two shapes (0 when they cross).
    pub fn dist(&self, other: &Shape) -> f64 {
        if self.crosses(other) {
            return 0.0;
        }
        let mut d = f64::INFINITY;
        for p in self
            .ends()
            .into_iter()
            .chain(self.interior_candidates(other).into_iter().flatten())
        {
            d = d.min(other.dist_point(p));
        }
        for p in other
            .ends()
            .into_iter()
            .chain(other.interior_candidates(self).into_iter().flatten())
        {
            d = d.min(self.dist_point(p));
        }
        d
    }
}

/// Where a tool-centre piece or a contour element comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Source {
    pub seq: u32,
    pub n: Option<u32>,
    pub line: u32,
}

impl Source {
    pub fn of(b: &Block) -> Source {
        Source {
            seq: b.seq,
            n: b.n,
            line: b.line,
        }
    }
}

/// A gouge: the tool centre of `tool` comes `depth_mm` closer than the radius to `contour`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gouge {
    pub tool: Source,
    pub contour: Source,
    pub depth_mm: f64,
}

/// Collects one run and checks it when it ends.
#[derive(Debug, Default)]
pub struct Check {
    active: bool,
    plane: Plane,
    radius_mm: f64,
    tolerance_mm: f64,
    contour: Vec<(Shape, Source)>,
    tool: Vec<(Shape, Source)>,
    /// Elements not kept because the run was longer than [`MAX_CHECKED_ELEMENTS`].
    skipped_from: Option<Source>,
}

impl Check {
    /// A run with tool radius `radius_mm` starts in `plane`.
    pub fn begin(&mut self, plane: Plane, radius_mm: f64, tolerance_mm: f64) {
        self.active = radius_mm > 0.0;
        self.plane = plane;
        self.radius_mm = radius_mm;
        self.tolerance_mm = tolerance_mm;
        self.contour.clear();
        self.tool.clear();
        self.skipped_from = None;
    }

    fn room(&mut self, src: &Block) -> bool {
        if self.contour.len() < MAX_CHECKED_ELEMENTS && self.tool.len() < 2 * MAX_CHECKED_ELEMENTS {
            return true;
        }
        self.skipped_from.get_or_insert(Source::of(src));
        false
    }

    /// A programmed element of the compensated contour.
    pub fn contour(&mut self, geo: &Geo, src: &Block) {
        if self.active && self.room(src) {
            self.contour.push((Shape::of_geo(geo), Source::of(src)));
        }
    }

    /// A tool-centre motion on (or collapsed onto) the equidistant.
    pub fn tool(&mut self, out: &Block) {
        if self.active
            && self.room(out)
            && let Some(s) = Shape::of_block(out, self.plane)
        {
            self.tool.push((s, Source::of(out)));
        }
    }

    /// The run ended: every gouge (the deepest per tool block, in program order) and the
    /// block from which on the run was too long to be checked.
    pub fn finish(&mut self) -> (Vec<Gouge>, Option<Source>) {
        if !self.active {
            return (Vec::new(), None);
        }
        self.active = false;
        let found = find(
            &self.contour,
            &self.tool,
            self.radius_mm - self.tolerance_mm,
        );
        self.contour = Vec::new();
        self.tool = Vec::new();
        (found, self.skipped_from.take())
    }
}

/// A uniform grid over the contour elements: each cell lists the elements whose box meets it
/// (compressed rows: one index array, no allocation per cell).
struct Grid {
    origin: V2,
    cell: f64,
    nx: usize,
    ny: usize,
    start: Vec<u32>,
    items: Vec<u32>,
}

impl Grid {
    fn new(shapes: &[(Shape, Source)]) -> Grid {
        let n = shapes.len().max(1);
        let boxes: Vec<(V2, V2)> = shapes.iter().map(|(s, _)| s.bbox()).collect();
        let mut lo = V2::new(f64::INFINITY, f64::INFINITY);
        let mut hi = V2::new(f64::NEG_INFINITY, f64::NEG_INFINITY);
        let mut mean = 0.0;
        for (a, b) in &boxes {
            lo = V2::new(lo.x.min(a.x), lo.y.min(a.y));
            hi = V2::new(hi.x.max(b.x), hi.y.max(b.y));
            mean += (b.x - a.x).max(b.y - a.y) / n as f64;
        }
        let (w, h) = ((hi.x - lo.x).max(0.0), (hi.y - lo.y).max(0.0));
        // About one element per cell, never cells smaller than the elements themselves, and
        // at most 4 n cells however thin the contour.
        let mut cell = ((w * h) / n as f64).sqrt().max(mean).max(1e-6);
        while ((w / cell) as usize + 1) * ((h / cell) as usize + 1) > 4 * n + 16 {
            cell *= 1.5;
        }
        let (nx, ny) = ((w / cell) as usize + 1, (h / cell) as usize + 1);
        let mut g = Grid {
            origin: lo,
            cell,
            nx,
            ny,
            start: vec![0; nx * ny + 1],
            items: Vec::new(),
        };
        let mut counts = vec![0u32; nx * ny];
        for b in &boxes {
            g.for_cells(*b, |k| counts[k] += 1);
        }
        let mut acc = 0u32;
        for (k, c) in counts.iter().enumerate() {
            g.start[k] = acc;
            acc += c;
        }
        g.start[nx * ny] = acc;
        g.items = vec![0; acc as usize];
        let mut fill = g.start.clone();
        for (i, b) in boxes.iter().enumerate() {
            let (items, start) = (&mut g.items, &mut fill);
            Grid::cells(g.origin, g.cell, g.nx, g.ny, *b, |k| {
                items[start[k] as usize] = i as u32;
                start[k] += 1;
            });
        }
        g
    }

    fn cells(origin: V2, cell: f64, nx: usize, ny: usize, b: (V2, V2), mut f: impl FnMut(usize)) {
        let idx =
            |v: f64, o: f64, n: usize| (((v - o) / cell).floor().max(0.0) as usize).min(n - 1);
        let (x0, x1) = (idx(b.0.x, origin.x, nx), idx(b.1.x, origin.x, nx));
        let (y0, y1) = (idx(b.0.y, origin.y, ny), idx(b.1.y, origin.y, ny));
        for y in y0..=y1 {
            for x in x0..=x1 {
                f(y * nx + x);
            }
        }
    }

    fn for_cells(&self, b: (V2, V2), f: impl FnMut(usize)) {
        Grid::cells(self.origin, self.cell, self.nx, self.ny, b, f);
    }
}

/// Every tool piece closer than `min_mm` to a contour element, the deepest per tool block.
fn find(contour: &[(Shape, Source)], tool: &[(Shape, Source)], min_mm: f64) -> Vec<Gouge> {
    if contour.is_empty() || tool.is_empty() || min_mm <= 0.0 {
        return Vec::new();
    }
    let grid = Grid::new(contour);
    let boxes: Vec<(V2, V2)> = contour.iter().map(|(s, _)| s.bbox()).collect();
    // Last query that looked at an element: each element is measured once per tool piece.
    let mut seen = vec![u32::MAX; contour.len()];
    let mut out: Vec<Gouge> = Vec::new();
    for (q, (shape, src)) in tool.iter().enumerate() {
        let (a, b) = shape.bbox();
        let m = V2::new(min_mm, min_mm);
        let (a, b) = (a - m, b + m);
        let mut worst: Option<(f64, usize)> = None;
        grid.for_cells((a, b), |k| {
            for &i in &grid.items[grid.start[k] as usize..grid.start[k + 1] as usize] {
                let i = i as usize;
                if seen[i] == q as u32 {
                    continue;
                }
                seen[i] = q as u32;
                let (ea, eb) = boxes[i];
                if ea.x > b.x || ea.y > b.y || eb.x < a.x || eb.y < a.y {
                    continue;
                }
                let d = shape.dist(&contour[i].0);
                if d < min_mm && worst.is_none_or(|(w, _)| d < w) {
                    worst = Some((d, i));
                }
            }
        });
        if let Some((d, i)) = worst {
            let g = Gouge {
                tool: *src,
                contour: contour[i].1,
                depth_mm: min_mm - d,
            };
            match out.last_mut() {
                Some(last) if last.tool.seq == src.seq => {
                    if g.depth_mm > last.depth_mm {
                        *last = g;
                    }
                }
                _ => out.push(g),
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn seg(ax: f64, ay: f64, bx: f64, by: f64) -> Shape {
        Shape::Seg {
            a: V2::new(ax, ay),
            b: V2::new(bx, by),
        }
    }

    #[test]
    fn distances_between_lines_and_arcs() {
        let s = seg(0.0, 0.0, 10.0, 0.0);
        assert!((s.dist(&seg(0.0, 3.0, 10.0, 5.0)) - 3.0).abs() < 1e-12);
        assert_eq!(s.dist(&seg(5.0, -1.0, 5.0, 1.0)), 0.0);
        // Upper half circle of radius 2 about (5, 5): nearest point (5, 3).
        let up = Shape::Arc {
            c: V2::new(5.0, 5.0),
            r: 2.0,
            a0: 0.0,
            sweep: PI,
        };
        assert!((s.dist(&up) - 5.0).abs() < 1e-12, "{}", s.dist(&up));
        let down = Shape::Arc {
            c: V2::new(5.0, 5.0),
            r: 2.0,
            a0: 0.0,
            sweep: -PI,
        };
        assert!((s.dist(&down) - 3.0).abs() < 1e-12);
        // An arc about a point of the segment, turned away from it: its ends decide.
        let about_end = Shape::Arc {
            c: V2::new(10.0, 0.0),
            r: 2.0,
            a0: -PI / 2.0,
            sweep: PI / 2.0,
        };
        assert!((s.dist(&about_end) - 2.0).abs() < 1e-12);
        // Two arcs facing each other along the centre line.
        let left = Shape::Arc {
            c: V2::new(0.0, 0.0),
            r: 1.0,
            a0: -0.5,
            sweep: 1.0,
        };
        let right = Shape::Arc {
            c: V2::new(5.0, 0.0),
            r: 1.0,
            a0: PI - 0.5,
            sweep: 1.0,
        };
        assert!((left.dist(&right) - 3.0).abs() < 1e-12);
        let crossing = Shape::Arc {
            c: V2::new(1.5, 0.0),
            r: 1.0,
            a0: PI - 0.8,
            sweep: 1.6,
        };
        let left = Shape::Arc {
            c: V2::new(0.0, 0.0),
            r: 1.0,
            a0: -0.8,
            sweep: 1.6,
        };
        assert_eq!(left.dist(&crossing), 0.0);
    }

    #[test]
    fn grid_finds_far_away_gouges_only() {
        let src = |seq| Source {
            seq,
            n: Some(seq * 10),
            line: seq,
        };
        let contour: Vec<_> = (0..100)
            .map(|k| (seg(k as f64, 0.0, k as f64 + 1.0, 0.0), src(k)))
            .collect();
        // Tool pieces 1 mm above the contour, one dipping to 0.25 mm at element 70.
        let mut tool: Vec<_> = (0..100)
            .map(|k| (seg(k as f64, 1.0, k as f64 + 1.0, 1.0), src(200 + k)))
            .collect();
        tool[70].0 = seg(70.0, 1.0, 70.5, 0.25);
        let g = find(&contour, &tool, 1.0 - 1e-3);
        assert_eq!(g.len(), 1);
        assert_eq!(g[0].tool.seq, 270);
        assert!(matches!(g[0].contour.seq, 70));
        assert!((g[0].depth_mm - (0.75 - 1e-3)).abs() < 1e-9);
    }
}
