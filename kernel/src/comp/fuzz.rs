//! Fuzzing entry of the compensator (issue #18): bytes → a random open or closed contour of
//! lines and arcs, a side, a radius and random corner settings (every R339 mode, R397, R764,
//! R765, R234). Must never panic or produce a non-finite position, and the gouge invariant
//! holds: wherever the tool centre comes closer than the radius to the contour (measured here
//! by dense samples, independently of [`super::gouge`]), a gouge message names that block.
//! Used by `fuzz/fuzz_targets/comp.rs` (cargo-fuzz, nightly) and by the proptest
//! `kernel/tests/comp_fuzz.rs` on stable.

use std::f64::consts::{PI, TAU};

use crate::block::{ArcDir, Block, BlockKind, Comp, Continuity, Feed, Path, Plane, Spindle};
use crate::units::AxesMm;

use super::config::{CompConfig, CornerMode};
use super::geom::V2;
use super::{Role, compensate_all_traced, gouge};

/// Reads the fuzzer's bytes as numbers; zeros once they run out.
struct Bytes<'a>(&'a [u8]);

impl Bytes<'_> {
    fn u8(&mut self) -> u8 {
        match self.0.split_first() {
            Some((b, rest)) => {
                self.0 = rest;
                *b
            }
            None => 0,
        }
    }
    /// A number in `lo..=hi`.
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        let v = u16::from_le_bytes([self.u8(), self.u8()]) as f64 / u16::MAX as f64;
        lo + (hi - lo) * v
    }
    fn flag(&mut self) -> bool {
        self.u8() & 1 == 1
    }
}

fn settings(b: &mut Bytes) -> CompConfig {
    let mut c = CompConfig {
        corner_mode: [
            CornerMode::Intersection,
            CornerMode::ArcAboveLimit,
            CornerMode::ArcAboveLimitOrMissing,
            CornerMode::ArcIfMissing,
        ][(b.u8() % 4) as usize],
        arc_insertion_limit_deg: b.range(0.0, 120.0),
        report_inserted_arcs: b.flag(),
        continuity_limit_deg: if b.flag() { b.range(0.0, 2.0) } else { 0.0 },
        ..CompConfig::default()
    };
    let bits = b.u8();
    c.check.check = bits & 1 == 0;
    c.check.warn = c.check.check && bits & 2 == 0;
    c.check.optimise_3_blocks = c.check.check && bits & 4 != 0;
    c.check.optimise_4_blocks = c.check.optimise_3_blocks && bits & 8 != 0;
    c.check.complementary_arc_to_line = bits & 16 != 0;
    c.check.arc_without_intersection_to_line = bits & 32 != 0;
    c.exit.optimise = bits & 64 != 0;
    c.exit.report = bits & 64 != 0;
    c.position.report = bits & 128 != 0;
    c.position.optimise = bits & 128 != 0 && b.flag();
    c
}

/// Builds canonical blocks like the interpreter: absolute positions, G17, modal comp.
struct Builder {
    blocks: Vec<Block>,
    pos: V2,
}

impl Builder {
    fn push(&mut self, to: V2, path: Path, comp: Comp) {
        let seq = self.blocks.len() as u32;
        let at = |p: V2| AxesMm([p.x, p.y, 0.0, 0.0, 0.0, 0.0]);
        self.blocks.push(Block {
            seq,
            n: Some((seq + 1) * 10),
            line: seq + 1,
            kind: BlockKind::Motion {
                start: at(self.pos),
                end: at(to),
                path,
            },
            feed: Feed::MmPerMin(1000.0),
            plane: Plane::G17,
            comp,
            continuity: Continuity::G98,
            dyn_set: 1,
            spindle: Spindle::default(),
            m: [None; 4],
        });
        self.pos = to;
    }

    fn arc(&mut self, to: V2, c: V2, ccw: bool, comp: Comp) {
        let dir = if ccw { ArcDir::Ccw } else { ArcDir::Cw };
        let center = AxesMm([c.x, c.y, 0.0, 0.0, 0.0, 0.0]);
        let path = Path::Arc {
            dir,
            center,
            plane: Plane::G17,
        };
        self.push(to, path, comp);
    }
}

/// A turtle walk of lines and arcs (open), or a polygon with bulging edges (closed).
fn contour(b: &mut Bytes, comp: Comp) -> Vec<Block> {
    let mut k = Builder {
        blocks: Vec::new(),
        pos: V2::new(-40.0, -40.0),
    };
    k.push(V2::new(0.0, 0.0), Path::Line, comp);
    let n = 1 + (b.u8() % 12) as usize;
    if b.flag() {
        let pts: Vec<V2> = (0..n.max(3))
            .map(|i| V2::from_angle(TAU * i as f64 / n.max(3) as f64) * b.range(20.0, 60.0))
            .collect();
        k.push(pts[0], Path::Line, comp);
        for i in 0..pts.len() {
            let (a, e) = (pts[i], pts[(i + 1) % pts.len()]);
            let bulge = b.range(-0.45, 0.45);
            if b.flag() && bulge.abs() > 0.02 {
                let (chord, mid) = (e - a, (a + e) * 0.5);
                let h = bulge * chord.len();
                let rho = (chord.len().powi(2) / 4.0 + h * h) / (2.0 * h.abs());
                let centre = mid - chord.unit().left() * ((rho - h.abs()) * h.signum());
                k.arc(e, centre, h < 0.0, comp);
            } else {
                k.push(e, Path::Line, comp);
            }
        }
    } else {
        let mut heading = 0.0f64;
        for _ in 0..n {
            heading += if b.flag() {
                0.0
            } else {
                b.range(-PI * 0.9, PI * 0.9)
            };
            let len = b.range(0.5, 40.0);
            if b.flag() {
                let rho = b.range(2.0, 50.0);
                let ccw = b.flag();
                let t = V2::from_angle(heading);
                let c = k.pos + if ccw { t.left() } else { -t.left() } * rho;
                let sweep = (len / rho).min(1.5 * PI);
                let a0 = (k.pos - c).angle() + if ccw { sweep } else { -sweep };
                heading += if ccw { sweep } else { -sweep };
                k.arc(c + V2::from_angle(a0) * rho, c, ccw, comp);
            } else {
                let to = k.pos + V2::from_angle(heading) * len;
                k.push(to, Path::Line, comp);
            }
        }
    }
    let out = k.pos + V2::new(30.0, -30.0);
    k.push(out, Path::Line, Comp::Off);
    k.blocks
}

/// Distance from `q` to a programmed line or arc of the plane.
fn dist_to(q: V2, b: &Block) -> f64 {
    let Some((s, e, path)) = b.motion() else {
        return f64::INFINITY;
    };
    let (a, z) = (V2::of(&s, Plane::G17), V2::of(&e, Plane::G17));
    let seg = |a: V2, z: V2| {
        let d = z - a;
        let t = if d.dot(d) > 0.0 {
            ((q - a).dot(d) / d.dot(d)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        q.dist(a + d * t)
    };
    match path {
        Path::Arc { dir, center, .. } => {
            let c = V2::of(&center, Plane::G17);
            let sign = if dir == ArcDir::Ccw { 1.0 } else { -1.0 };
            let mut sweep = (sign * ((z - c).angle() - (a - c).angle())).rem_euclid(TAU);
            if a.dist(z) < 1e-9 {
                sweep = TAU;
            }
            let t = (sign * ((q - c).angle() - (a - c).angle())).rem_euclid(TAU);
            if t <= sweep {
                (q.dist(c) - a.dist(c)).abs()
            } else {
                q.dist(a).min(q.dist(z))
            }
        }
        _ => seg(a, z),
    }
}

/// A box around a programmed element (an arc: around its whole circle), so that the check
/// measures a sample only against the elements that may be near it: the distance to the box
/// is at most the distance to the element.
#[derive(Clone, Copy)]
struct Bounds {
    lo: V2,
    hi: V2,
}

impl Bounds {
    fn of(b: &Block) -> Bounds {
        let Some((s, e, path)) = b.motion() else {
            let far = V2::new(f64::INFINITY, f64::INFINITY);
            return Bounds { lo: far, hi: far };
        };
        let (a, z) = (V2::of(&s, Plane::G17), V2::of(&e, Plane::G17));
        match path {
            Path::Arc { center, .. } => {
                let c = V2::of(&center, Plane::G17);
                let rho = a.dist(c).max(z.dist(c));
                Bounds {
                    lo: V2::new(c.x - rho, c.y - rho),
                    hi: V2::new(c.x + rho, c.y + rho),
                }
            }
            _ => Bounds {
                lo: V2::new(a.x.min(z.x), a.y.min(z.y)),
                hi: V2::new(a.x.max(z.x), a.y.max(z.y)),
            },
        }
    }

    /// Distance from `q` to the box (0 inside).
    fn dist(self, q: V2) -> f64 {
        let dx = (self.lo.x - q.x).max(q.x - self.hi.x).max(0.0);
        let dy = (self.lo.y - q.y).max(q.y - self.hi.y).max(0.0);
        dx.hypot(dy)
    }
}

/// Points along an output motion, `step` apart.
fn samples(b: &Block, step: f64) -> Vec<V2> {
    let Some((s, e, path)) = b.motion() else {
        return Vec::new();
    };
    let (a, z) = (V2::of(&s, Plane::G17), V2::of(&e, Plane::G17));
    match path {
        Path::Arc { dir, center, .. } => {
            let c = V2::of(&center, Plane::G17);
            let sign = if dir == ArcDir::Ccw { 1.0 } else { -1.0 };
            let sweep = sign * (sign * ((z - c).angle() - (a - c).angle())).rem_euclid(TAU);
            let rho = a.dist(c);
            let n = ((sweep.abs() * rho / step).ceil() as usize).clamp(1, 100_000);
            let a0 = (a - c).angle();
            (0..=n)
                .map(|i| c + V2::from_angle(a0 + sweep * i as f64 / n as f64) * rho)
                .collect()
        }
        _ => {
            let n = ((a.dist(z) / step).ceil() as usize).clamp(1, 100_000);
            (0..=n)
                .map(|i| a + (z - a) * (i as f64 / n as f64))
                .collect()
        }
    }
}

/// See the module documentation. Panics when an invariant fails.
pub fn fuzz_entry(data: &[u8]) {
    let mut b = Bytes(data);
    let cfg = settings(&mut b);
    let r = b.range(0.1, 20.0);
    let d = 1 + b.u8() % 99;
    let comp = if b.flag() {
        Comp::Left { d, radius_mm: r }
    } else {
        Comp::Right { d, radius_mm: r }
    };
    let blocks = contour(&mut b, comp);
    let (out, diags) = compensate_all_traced(&blocks, &cfg);
    for o in &out {
        if let Some((s, e, path)) = o.block.motion() {
            let centre_ok = match path {
                Path::Arc { center, .. } => center.0.iter().all(|v| v.is_finite()),
                _ => true,
            };
            assert!(
                s.0.iter().chain(e.0.iter()).all(|v| v.is_finite()) && centre_ok,
                "non-finite output {o:?}"
            );
        }
    }
    if diags.iter().any(|d| d.is_error()) {
        return;
    }
    // Contour: the compensated elements after the start block, before the cancel.
    let contour: Vec<&Block> = blocks[1..blocks.len() - 1].iter().collect();
    let tol = cfg.gouge_tolerance_mm(r);
    let named: Vec<Option<u32>> = diags
        .iter()
        .filter(|d| gouge::is_gouge(d))
        .map(|d| d.block)
        .collect();
    let step = (r / 20.0).clamp(0.01, 0.2);
    let bounds: Vec<Bounds> = contour.iter().map(|c| Bounds::of(c)).collect();
    for o in &out {
        if !matches!(
            o.role,
            Role::Equidistant | Role::EquidistantChord | Role::CornerArc | Role::Collapsed
        ) || named.contains(&o.block.n)
        {
            continue;
        }
        // Elements whose box is r − tol away or more cannot be too close to the sample.
        let worst = samples(&o.block, step)
            .into_iter()
            .flat_map(|q| {
                contour
                    .iter()
                    .zip(&bounds)
                    .filter(move |(_, bx)| bx.dist(q) < r - tol)
                    .map(move |(c, _)| dist_to(q, c))
            })
            .fold(f64::INFINITY, f64::min);
        assert!(
            worst >= r - tol,
            "tool centre of N{:?} comes {:.4} mm closer than r = {r} to the contour and no gouge message names it: {diags:?}",
            o.block.n,
            r - worst
        );
    }
}
