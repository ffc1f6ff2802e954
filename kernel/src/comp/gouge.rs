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

use std::f64::consts::PI;

use crate::block::{ArcDir, Block, BlockKind, Path, Plane};
use crate::diag::{DiagCode, Diagnostic};

use super::geom::{Geo, V2};

/// Elements of one run kept for the check (≈ 70 bytes each, twice: contour and tool). A run
/// longer than this is checked up to here and an information message says so: memory stays
/// bounded while a program of any length streams through the daemon.
pub const MAX_CHECKED_ELEMENTS: usize = 200_000;

/// Tool centres closer than the radius by less than this are not a gouge, mm (numerical
/// noise of intersections is ~1e-9 mm; SPEC §4.4's perpendicular point adds its own error).
pub const GOUGE_TOLERANCE_MM: f64 = 0.001;

/// Every gouge message starts with this, for the machinist reading a list of warnings
/// (programs and clients tell gouges apart by the code [`DiagCode::Gouge`]).
pub const MESSAGE_PREFIX: &str = "gouge:";

/// Whether `d` is a gouge found by this check.
pub fn is_gouge(d: &Diagnostic) -> bool {
    d.code == DiagCode::Gouge
}

/// A line segment or a circular arc in the compensation plane. Arcs keep their end points and
/// end directions, so measuring needs no trigonometry (the check's inner loop).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    Seg { a: V2, b: V2 },
    Arc(ArcShape),
}

/// A circular arc: centre, radius, end points, direction and whether it is longer than a
/// half circle (all that measuring needs; no angles).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ArcShape {
    c: V2,
    r: f64,
    p0: V2,
    p1: V2,
    ccw: bool,
    major: bool,
}

fn dist(a: V2, b: V2) -> f64 {
    let d = a - b;
    d.dot(d).sqrt()
}

fn unit(v: V2) -> Option<V2> {
    let l = v.dot(v).sqrt();
    (l > 1e-12).then(|| v * (1.0 / l))
}

impl ArcShape {
    /// The arc about `c` of radius `r` from angle `a0` (rad) sweeping `sweep`.
    pub fn new(c: V2, r: f64, a0: f64, sweep: f64) -> ArcShape {
        ArcShape {
            c,
            r,
            p0: c + V2::from_angle(a0) * r,
            p1: c + V2::from_angle(a0 + sweep) * r,
            ccw: sweep > 0.0,
            major: sweep.abs() > PI,
        }
    }

    /// The arc about `c` from `a` in direction `ccw`, ending in the direction of `b` (an end
    /// point off the circle, within R55, is projected onto it); `major`: longer than a half
    /// circle.
    fn from_points(c: V2, a: V2, b: V2, ccw: bool, major: bool) -> ArcShape {
        let r = dist(a, c);
        let p1 = match unit(b - c) {
            Some(u) if dist(a, b) > 1e-12 => c + u * r,
            _ => a,
        };
        ArcShape {
            c,
            r,
            p0: a,
            p1,
            ccw,
            major,
        }
    }

    /// Whether direction `v` (from the centre) lies within the sweep.
    fn contains(&self, v: V2) -> bool {
        // Signs of cross products: the end directions need no normalising.
        let (u0, u1) = (self.p0 - self.c, self.p1 - self.c);
        let s = if self.ccw { 1.0 } else { -1.0 };
        if !self.major {
            s * u0.cross(v) >= 0.0 && s * v.cross(u1) >= 0.0
        } else {
            // Outside the complementary arc (shorter than a half circle).
            !(s * u1.cross(v) > 0.0 && s * v.cross(u0) > 0.0)
        }
    }

    fn dist_point(&self, p: V2) -> f64 {
        let v = p - self.c;
        let d = v.dot(v).sqrt();
        if d > 0.0 && self.contains(v) {
            (d - self.r).abs()
        } else {
            dist(p, self.p0).min(dist(p, self.p1))
        }
    }

    /// The points of the arc in direction ±`u` from its centre.
    fn along(&self, u: V2) -> [Option<V2>; 2] {
        let pick = |d: V2| self.contains(d).then(|| self.c + d * self.r);
        [pick(u), pick(-u)]
    }
}

impl Shape {
    fn of_geo(g: &Geo) -> Shape {
        match *g {
            Geo::Line { a, b } => Shape::Seg { a, b },
            Geo::Arc {
                a, c, sweep_rad, ..
            } => Shape::Arc(ArcShape::from_points(
                c,
                a,
                g.end(),
                sweep_rad > 0.0,
                sweep_rad.abs() > PI,
            )),
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
                let ccw = dir == ArcDir::Ccw;
                // Longer than a half circle when the end lies behind the start as seen in
                // the direction of motion (output arcs are halved above 180°, so rarely).
                let cross = (a - c).cross(e - c);
                let major = if ccw { cross < 0.0 } else { cross > 0.0 };
                Shape::Arc(ArcShape::from_points(c, a, e, ccw, major))
            }
            _ => Shape::Seg { a, b: e },
        })
    }

    fn ends(&self) -> [V2; 2] {
        match self {
            Shape::Seg { a, b } => [*a, *b],
            Shape::Arc(k) => [k.p0, k.p1],
        }
    }

    /// Axis-aligned bounding box (min, max): end points and the extreme points of the circle
    /// that lie within an arc.
    fn bbox(&self) -> (V2, V2) {
        let [a, b] = self.ends();
        let mut lo = V2::new(a.x.min(b.x), a.y.min(b.y));
        let mut hi = V2::new(a.x.max(b.x), a.y.max(b.y));
        if let Shape::Arc(k) = self {
            for d in [
                V2::new(1.0, 0.0),
                V2::new(-1.0, 0.0),
                V2::new(0.0, 1.0),
                V2::new(0.0, -1.0),
            ] {
                if k.contains(d) {
                    let p = k.c + d * k.r;
                    lo = V2::new(lo.x.min(p.x), lo.y.min(p.y));
                    hi = V2::new(hi.x.max(p.x), hi.y.max(p.y));
                }
            }
        }
        (lo, hi)
    }

    /// Distance from a point.
    pub fn dist_point(&self, p: V2) -> f64 {
        match self {
            Shape::Seg { a, b } => {
                let d = *b - *a;
                let l2 = d.dot(d);
                if l2 == 0.0 {
                    return dist(p, *a);
                }
                let t = ((p - *a).dot(d) / l2).clamp(0.0, 1.0);
                dist(p, *a + d * t)
            }
            Shape::Arc(k) => k.dist_point(p),
        }
    }

    /// Points of `self` where the distance to `other` can be smallest besides its end points:
    /// the foot of a circle centre on a segment; the points of an arc on the line through
    /// both centres, or towards a segment's foot.
    fn interior_candidates(&self, other: &Shape) -> [Option<V2>; 2] {
        match (self, other) {
            (Shape::Seg { a, b }, Shape::Arc(k)) => [foot(*a, *b, k.c), None],
            (Shape::Arc(k), Shape::Arc(k2)) => match unit(k2.c - k.c) {
                Some(u) => k.along(u),
                // Concentric arcs: the end points decide.
                None => [None, None],
            },
            (Shape::Arc(k), Shape::Seg { a, b }) => {
                // A foot on the centre: every arc point is as far from it; the ends decide.
                match foot(*a, *b, k.c).and_then(|f| unit(f - k.c)) {
                    Some(u) => k.along(u),
                    None => [None, None],
                }
            }
            (Shape::Seg { .. }, Shape::Seg { .. }) => [None, None],
        }
    }

    /// Whether the two shapes cross or touch.
    fn crosses(&self, other: &Shape) -> bool {
        match (self, other) {
            (Shape::Seg { a, b }, Shape::Seg { a: c, b: d }) => {
                let o = |p: V2, q: V2, r: V2| (q - p).cross(r - p);
                o(*a, *b, *c) * o(*a, *b, *d) < 0.0 && o(*c, *d, *a) * o(*c, *d, *b) < 0.0
            }
            (Shape::Seg { a, b }, Shape::Arc(k)) | (Shape::Arc(k), Shape::Seg { a, b }) => {
                let (a, d) = (*a, *b - *a);
                let l2 = d.dot(d);
                if l2 == 0.0 {
                    return false;
                }
                // |a + t d − c|² = r²
                let w = a - k.c;
                let (qb, qc) = (w.dot(d) / l2, (w.dot(w) - k.r * k.r) / l2);
                let disc = qb * qb - qc;
                if disc < 0.0 {
                    return false;
                }
                let h = disc.sqrt();
                [-qb - h, -qb + h]
                    .into_iter()
                    .any(|t| (0.0..=1.0).contains(&t) && k.contains(w + d * t))
            }
            (Shape::Arc(k), Shape::Arc(k2)) => {
                let dv = k2.c - k.c;
                let dd = dv.dot(dv).sqrt();
                if dd == 0.0 || dd > k.r + k2.r || dd < (k.r - k2.r).abs() {
                    return false;
                }
                let e = dv * (1.0 / dd);
                let x = 0.5 * (dd + (k.r - k2.r) * (k.r + k2.r) / dd);
                let h = (k.r * k.r - x * x).max(0.0).sqrt();
                let m = k.c + e * x;
                [m + e.left() * h, m - e.left() * h]
                    .into_iter()
                    .any(|p| k.contains(p - k.c) && k2.contains(p - k2.c))
            }
        }
    }

    /// Smallest distance between two shapes (0 when they cross).
    pub fn dist(&self, other: &Shape) -> f64 {
        if self.crosses(other) {
            return 0.0;
        }
        let mut d = f64::INFINITY;
        let mine = self.interior_candidates(other);
        for p in self.ends().into_iter().chain(mine.into_iter().flatten()) {
            d = d.min(other.dist_point(p));
        }
        let theirs = other.interior_candidates(self);
        for p in other.ends().into_iter().chain(theirs.into_iter().flatten()) {
            d = d.min(self.dist_point(p));
        }
        d
    }
}

/// The foot of `p` on segment a–b, if it falls within the segment.
fn foot(a: V2, b: V2, p: V2) -> Option<V2> {
    let d = b - a;
    let l2 = d.dot(d);
    let t = if l2 > 0.0 { (p - a).dot(d) / l2 } else { -1.0 };
    (0.0..=1.0).contains(&t).then(|| a + d * t)
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

/// A tool-centre piece. It is measured against its own contour element too: an arc's
/// equidistant joined within the arc-end tolerance (`arc_end_tolerance_mm`) is a circle of
/// another radius, up to that tolerance closer to its own element (a fuzz finding: 8 µm).
#[derive(Clone, Copy, Debug)]
struct Piece {
    shape: Shape,
    src: Source,
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
    contour: Chunked<(Shape, Source)>,
    tool: Chunked<Piece>,
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
            && let Some(shape) = Shape::of_block(out, self.plane)
        {
            self.tool.push(Piece {
                shape,
                src: Source::of(out),
            });
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
        self.contour = Chunked::default();
        self.tool = Chunked::default();
        (found, self.skipped_from.take())
    }
}

/// A growing list in fixed chunks: long runs never copy what they hold (no reallocation).
#[derive(Debug)]
struct Chunked<T> {
    chunks: Vec<Vec<T>>,
    len: usize,
}

const CHUNK: usize = 1024;

impl<T> Default for Chunked<T> {
    fn default() -> Self {
        Chunked {
            chunks: Vec::new(),
            len: 0,
        }
    }
}

impl<T> Chunked<T> {
    fn push(&mut self, v: T) {
        if self.len.is_multiple_of(CHUNK) {
            self.chunks.push(Vec::with_capacity(CHUNK));
        }
        self.chunks.last_mut().expect("a chunk").push(v);
        self.len += 1;
    }
    fn len(&self) -> usize {
        self.len
    }
    fn is_empty(&self) -> bool {
        self.len == 0
    }
    fn clear(&mut self) {
        self.chunks.clear();
        self.len = 0;
    }
    fn get(&self, i: usize) -> &T {
        &self.chunks[i / CHUNK][i % CHUNK]
    }
    fn iter(&self) -> impl Iterator<Item = &T> {
        self.chunks.iter().flatten()
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
    fn new(boxes: &[(V2, V2)]) -> Grid {
        let n = boxes.len().max(1);
        let mut lo = V2::new(f64::INFINITY, f64::INFINITY);
        let mut hi = V2::new(f64::NEG_INFINITY, f64::NEG_INFINITY);
        let mut mean = 0.0;
        for (a, b) in boxes {
            lo = V2::new(lo.x.min(a.x), lo.y.min(a.y));
            hi = V2::new(hi.x.max(b.x), hi.y.max(b.y));
            mean += (b.x - a.x).max(b.y - a.y) / n as f64;
        }
        let (w, h) = ((hi.x - lo.x).max(0.0), (hi.y - lo.y).max(0.0));
        // About one element per cell, never cells smaller than the elements themselves, and
        // at most 4 n cells however thin the contour.
        let mut cell = ((w * h) / n as f64).sqrt().max(mean).max(1e-6);
        // Counted in f64: no overflow whatever the coordinates.
        let cells = |c: f64| ((w / c).floor() + 1.0) * ((h / c).floor() + 1.0);
        while cells(cell) > (4 * n + 16) as f64 {
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
        for b in boxes {
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
        let idx = |v: f64, o: f64, n: usize| (((v - o) / cell).max(0.0) as usize).min(n - 1);
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
fn find(contour: &Chunked<(Shape, Source)>, tool: &Chunked<Piece>, min_mm: f64) -> Vec<Gouge> {
    if contour.is_empty() || tool.is_empty() || min_mm <= 0.0 {
        return Vec::new();
    }
    let boxes: Vec<(V2, V2)> = contour.iter().map(|(s, _)| s.bbox()).collect();
    let grid = Grid::new(&boxes);
    // Last query that looked at an element: each element is measured once per tool piece.
    let mut seen = vec![u32::MAX; contour.len()];
    let mut out: Vec<Gouge> = Vec::new();
    for (q, piece) in tool.iter().enumerate() {
        let (shape, src) = (&piece.shape, &piece.src);
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
                let (other, _) = contour.get(i);
                let d = shape.dist(other);
                if d < min_mm && worst.is_none_or(|(w, _)| d < w) {
                    worst = Some((d, i));
                }
            }
        });
        if let Some((d, i)) = worst {
            let g = Gouge {
                tool: *src,
                contour: contour.get(i).1,
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
        let arc = |cx, cy, r, a0, sweep| Shape::Arc(ArcShape::new(V2::new(cx, cy), r, a0, sweep));
        let up = arc(5.0, 5.0, 2.0, 0.0, PI);
        assert!((s.dist(&up) - 5.0).abs() < 1e-12, "{}", s.dist(&up));
        let down = arc(5.0, 5.0, 2.0, 0.0, -PI);
        assert!((s.dist(&down) - 3.0).abs() < 1e-12);
        // An arc about a point of the segment, turned away from it: its ends decide.
        let about_end = arc(10.0, 0.0, 2.0, -PI / 2.0, PI / 2.0);
        assert!((s.dist(&about_end) - 2.0).abs() < 1e-12);
        // Two arcs facing each other along the centre line.
        let left = arc(0.0, 0.0, 1.0, -0.5, 1.0);
        let right = arc(5.0, 0.0, 1.0, PI - 0.5, 1.0);
        assert!((left.dist(&right) - 3.0).abs() < 1e-12);
        let crossing = arc(1.5, 0.0, 1.0, PI - 0.8, 1.6);
        let left = arc(0.0, 0.0, 1.0, -0.8, 1.6);
        assert_eq!(left.dist(&crossing), 0.0);
        // Three quarters of a circle about the origin, open towards +x: the gap decides.
        let big = arc(0.0, 0.0, 1.0, PI / 4.0, 1.5 * PI);
        assert!(
            (big.dist_point(V2::new(3.0, 0.0)) - V2::new(3.0, 0.0).dist(V2::from_angle(PI / 4.0)))
                .abs()
                < 1e-12
        );
        assert!((big.dist_point(V2::new(-3.0, 0.0)) - 2.0).abs() < 1e-12);
        let (lo, hi) = big.bbox();
        assert!((lo.x + 1.0).abs() < 1e-12 && (hi.x - 0.5f64.sqrt()).abs() < 1e-12);
        assert!((lo.y + 1.0).abs() < 1e-12 && (hi.y - 1.0).abs() < 1e-12);
    }

    #[test]
    fn grid_finds_far_away_gouges_only() {
        let src = |seq| Source {
            seq,
            n: Some(seq * 10),
            line: seq,
        };
        let mut contour = Chunked::default();
        for k in 0..100 {
            contour.push((seg(k as f64, 0.0, k as f64 + 1.0, 0.0), src(k)));
        }
        // Tool pieces 1 mm above the contour, one dipping to 0.25 mm at element 70.
        let mut tool: Vec<_> = (0..100)
            .map(|k| Piece {
                shape: seg(k as f64, 1.0, k as f64 + 1.0, 1.0),
                src: src(200 + k),
            })
            .collect();
        tool[70].shape = seg(70.0, 1.0, 70.5, 0.25);
        let mut pieces = Chunked::default();
        tool.into_iter().for_each(|p| pieces.push(p));
        let g = find(&contour, &pieces, 1.0 - 1e-3);
        assert_eq!(g.len(), 1);
        assert_eq!(g[0].tool.seq, 270);
        assert!(matches!(g[0].contour.seq, 70));
        assert!((g[0].depth_mm - (0.75 - 1e-3)).abs() < 1e-9);
    }
}
