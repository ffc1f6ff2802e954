//! Shared helpers of the `comp_*` tests: a builder of canonical blocks (the interpreter's
//! output) and an independent checker of the tool-centre path.
#![allow(dead_code)]

use std::collections::HashMap;

use kernel::block::{ArcDir, Block, BlockKind, Comp, Continuity, Feed, Path, Plane, Spindle};
use kernel::comp::geom::V2;
use kernel::comp::{CompBlock, CompConfig, Role, compensate_all_traced};
use kernel::units::AxesMm;
use kernel::{Diagnostic, Severity};

/// Builds canonical blocks as the interpreter would: absolute positions, modal comp/plane.
pub struct Prog {
    pub blocks: Vec<Block>,
    pub pos: AxesMm,
    pub comp: Comp,
    pub plane: Plane,
}

impl Prog {
    pub fn new(u: f64, v: f64) -> Self {
        Self::in_plane(Plane::G17, u, v)
    }

    pub fn in_plane(plane: Plane, u: f64, v: f64) -> Self {
        let mut pos = AxesMm::ZERO;
        V2::new(u, v).put(&mut pos, plane);
        Prog {
            blocks: Vec::new(),
            pos,
            comp: Comp::Off,
            plane,
        }
    }

    fn block(&mut self, kind: BlockKind) -> &mut Self {
        let seq = self.blocks.len() as u32;
        self.blocks.push(Block {
            seq,
            n: Some((seq + 1) * 10),
            line: seq + 1,
            kind,
            feed: Feed::MmPerMin(1000.0),
            plane: self.plane,
            comp: self.comp,
            continuity: Continuity::G98,
            dyn_set: 1,
            spindle: Spindle::default(),
            m: [None; 4],
        });
        self
    }

    /// The N number of the block built last.
    pub fn last_n(&self) -> Option<u32> {
        self.blocks.last().and_then(|b| b.n)
    }

    pub fn g41(&mut self, d: u8, radius_mm: f64) -> &mut Self {
        self.comp = Comp::Left { d, radius_mm };
        self
    }
    pub fn g42(&mut self, d: u8, radius_mm: f64) -> &mut Self {
        self.comp = Comp::Right { d, radius_mm };
        self
    }
    pub fn g40(&mut self) -> &mut Self {
        self.comp = Comp::Off;
        self
    }
    pub fn plane(&mut self, p: Plane) -> &mut Self {
        self.plane = p;
        self
    }

    fn to(&mut self, u: f64, v: f64, path: Path) -> &mut Self {
        let start = self.pos;
        let mut end = start;
        V2::new(u, v).put(&mut end, self.plane);
        self.pos = end;
        self.block(BlockKind::Motion { start, end, path })
    }

    /// G1 to (u, v) in the plane's axes.
    pub fn line(&mut self, u: f64, v: f64) -> &mut Self {
        self.to(u, v, Path::Line)
    }
    pub fn rapid(&mut self, u: f64, v: f64) -> &mut Self {
        self.to(u, v, Path::Rapid)
    }
    /// G2 (`cw`) or G3 to (u, v) about the absolute centre (cu, cv).
    pub fn arc(&mut self, cw: bool, u: f64, v: f64, cu: f64, cv: f64) -> &mut Self {
        let mut center = self.pos;
        V2::new(cu, cv).put(&mut center, self.plane);
        let dir = if cw { ArcDir::Cw } else { ArcDir::Ccw };
        let plane = self.plane;
        self.to(u, v, Path::Arc { dir, center, plane })
    }
    /// Motion of axis 4 (never in a compensation plane) or of the third axis of G17.
    pub fn z(&mut self, z: f64) -> &mut Self {
        let start = self.pos;
        let mut end = start;
        end[2] = z;
        self.pos = end;
        self.block(BlockKind::Motion {
            start,
            end,
            path: Path::Line,
        })
    }
    pub fn tech(&mut self) -> &mut Self {
        self.block(BlockKind::Technology)
    }

    pub fn run(&self, cfg: &CompConfig) -> (Vec<CompBlock>, Vec<Diagnostic>) {
        compensate_all_traced(&self.blocks, cfg)
    }
}

pub fn errors(d: &[Diagnostic]) -> Vec<&Diagnostic> {
    d.iter().filter(|d| d.severity == Severity::Error).collect()
}

pub fn with_severity(d: &[Diagnostic], s: Severity) -> Vec<&Diagnostic> {
    d.iter().filter(|d| d.severity == s).collect()
}

/// Plane start, end of an output motion.
pub fn ends(b: &Block, plane: Plane) -> (V2, V2) {
    let (s, e, _) = b.motion().expect("motion");
    (V2::of(&s, plane), V2::of(&e, plane))
}

/// Output motions only (no technology blocks), with roles.
pub fn motions(out: &[CompBlock]) -> Vec<CompBlock> {
    out.iter()
        .filter(|c| c.block.motion().is_some())
        .copied()
        .collect()
}

pub fn close(a: V2, b: V2, tol: f64) -> bool {
    a.dist(b) <= tol
}

pub fn assert_close(a: V2, b: V2, tol: f64) {
    assert!(a.dist(b) <= tol, "{a:?} != {b:?} (tol {tol})");
}

/// Unit tangent of an output motion at its start (`at_end = false`) or end.
pub fn tangent(b: &Block, plane: Plane, at_end: bool) -> V2 {
    let (s, e, path) = b.motion().expect("motion");
    let (s, e) = (V2::of(&s, plane), V2::of(&e, plane));
    match path {
        Path::Arc { dir, center, .. } => {
            let c = V2::of(&center, plane);
            let p = if at_end { e } else { s };
            let t = (p - c).unit().left();
            if dir == ArcDir::Ccw { t } else { -t }
        }
        _ => (e - s).unit(),
    }
}

/// Independent check of a compensated path against its programmed blocks (SPEC §4.3):
/// continuity, every equidistant piece at exactly |r| on the right side and running
/// forwards, every inserted arc centred on the programmed corner with radius |r| and tangent
/// to both neighbours. Returns how many pieces and corner arcs were checked.
pub fn check_path(
    input: &[Block],
    out: &[CompBlock],
    plane: Plane,
    tol: f64,
) -> Result<(usize, usize), String> {
    let src: HashMap<u32, &Block> = input.iter().map(|b| (b.seq, b)).collect();
    let mv = motions(out);
    let mut pieces = 0;
    let mut arcs = 0;
    for w in mv.windows(2) {
        let (_, e0, _) = w[0].block.motion().unwrap();
        let (s1, _, _) = w[1].block.motion().unwrap();
        if (e0 - s1).max_abs(6) > 1e-9 {
            return Err(format!("gap between {:?} and {:?}", w[0], w[1]));
        }
    }
    for (i, c) in mv.iter().enumerate() {
        let (s, e, path) = c.block.motion().unwrap();
        for p in [s, e] {
            if p.0.iter().any(|v| !v.is_finite()) {
                return Err(format!("non-finite output {c:?}"));
            }
        }
        let (ps, pe) = (V2::of(&s, plane), V2::of(&e, plane));
        let r = c.offset_mm;
        match c.role {
            Role::Equidistant => {
                pieces += 1;
                let b = src[&c.block.seq];
                let (bs, be, bpath) = b.motion().unwrap();
                let (a, bb) = (V2::of(&bs, plane), V2::of(&be, plane));
                match bpath {
                    Path::Arc { dir, center, .. } => {
                        let cc = V2::of(&center, plane);
                        let rho = a.dist(cc);
                        let want = if dir == ArcDir::Ccw { rho - r } else { rho + r };
                        for q in [ps, pe] {
                            if (q.dist(cc) - want).abs() > tol {
                                return Err(format!(
                                    "arc piece of seq {} at {:?}: distance {} from centre, want {want}",
                                    b.seq,
                                    q,
                                    q.dist(cc)
                                ));
                            }
                        }
                        let Path::Arc {
                            dir: odir,
                            center: oc,
                            ..
                        } = path
                        else {
                            // A piece shorter than 1e-9 mm may be written as a line.
                            if ps.dist(pe) > 1e-6 {
                                return Err(format!("arc seq {} came out as a line", b.seq));
                            }
                            continue;
                        };
                        if odir != dir || !close(V2::of(&oc, plane), cc, 1e-9) {
                            return Err(format!(
                                "arc piece of seq {} changed centre/direction",
                                b.seq
                            ));
                        }
                    }
                    _ => {
                        let d = (bb - a).unit();
                        for q in [ps, pe] {
                            let off = d.cross(q - a);
                            if (off - r).abs() > tol {
                                return Err(format!(
                                    "line piece of seq {} at {q:?}: offset {off}, want {r}",
                                    b.seq
                                ));
                            }
                        }
                        if (pe - ps).dot(d) < -1e-9 {
                            return Err(format!("line piece of seq {} runs backwards", b.seq));
                        }
                    }
                }
            }
            Role::CornerArc => {
                arcs += 1;
                let b = src[&c.block.seq];
                let corner = V2::of(&b.motion().unwrap().0, plane);
                let Path::Arc { center, .. } = path else {
                    return Err("corner arc is not an arc".into());
                };
                if !close(V2::of(&center, plane), corner, 1e-9) {
                    return Err(format!(
                        "corner arc of seq {} not centred on the corner",
                        b.seq
                    ));
                }
                for q in [ps, pe] {
                    if (q.dist(corner) - r.abs()).abs() > tol {
                        return Err(format!("corner arc of seq {} radius != |r|", b.seq));
                    }
                }
                // Neighbours moving in the plane (bridged Z moves stand between).
                let moves = |c: &CompBlock| {
                    let (a, b) = ends(&c.block, plane);
                    a.dist(b) > 1e-9
                };
                let Some(before) = mv[..i].iter().rev().find(|c| moves(c)) else {
                    return Err("corner arc without a motion before it".into());
                };
                let Some(after) = mv[i + 1..].iter().find(|c| moves(c)) else {
                    return Err("corner arc without a motion after it".into());
                };
                let t_in = tangent(&before.block, plane, true);
                let t_out = tangent(&after.block, plane, false);
                if tangent(&c.block, plane, false).dot(t_in) < 1.0 - 1e-9
                    || tangent(&c.block, plane, true).dot(t_out) < 1.0 - 1e-9
                {
                    return Err(format!("corner arc of seq {} not tangent", b.seq));
                }
            }
            _ => {}
        }
    }
    Ok((pieces, arcs))
}

/// Continuity and finiteness only (for contours where loops are allowed).
pub fn check_continuous(out: &[CompBlock]) -> Result<(), String> {
    let mv = motions(out);
    for c in &mv {
        let (s, e, _) = c.block.motion().unwrap();
        if s.0.iter().chain(e.0.iter()).any(|v| !v.is_finite()) {
            return Err(format!("non-finite output {c:?}"));
        }
    }
    for w in mv.windows(2) {
        let (_, e0, _) = w[0].block.motion().unwrap();
        let (s1, _, _) = w[1].block.motion().unwrap();
        if (e0 - s1).max_abs(6) > 1e-9 {
            return Err(format!("gap between {:?} and {:?}", w[0], w[1]));
        }
    }
    Ok(())
}
