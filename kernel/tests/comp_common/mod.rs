//! Shared helpers of the `comp_*` tests (a module of each, not a test binary of its own: the
//! `plan_common/` pattern): a builder of canonical blocks (the interpreter's
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

/// Gouge warnings (or errors) of the whole-run check.
pub fn gouges(d: &[Diagnostic]) -> Vec<&Diagnostic> {
    d.iter()
        .filter(|d| kernel::comp::gouge::is_gouge(d))
        .collect()
}

/// Everything but the gouge check's messages.
pub fn without_gouges(d: &[Diagnostic]) -> Vec<Diagnostic> {
    d.iter()
        .filter(|d| !kernel::comp::gouge::is_gouge(d))
        .cloned()
        .collect()
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

/// Why a compensated path breaks a rule of SPEC §4 (what [`check_path`] and its friends find).
#[derive(Debug, thiserror::Error)]
pub enum PathError {
    #[error("gap between {before:?} and {after:?}")]
    Gap {
        before: Box<CompBlock>,
        after: Box<CompBlock>,
    },
    #[error("non-finite output {0:?}")]
    NonFinite(Box<CompBlock>),
    #[error("arc piece of seq {seq} at {at:?}: distance {distance} from centre, want {want}")]
    ArcPieceRadius {
        seq: u32,
        at: V2,
        distance: f64,
        want: f64,
    },
    #[error("arc seq {0} came out as a line")]
    ArcBecameLine(u32),
    #[error("arc piece of seq {0} changed centre/direction")]
    ArcPieceMoved(u32),
    #[error("arc piece of seq {0} reversed")]
    ArcReversed(u32),
    #[error("line piece of seq {seq} at {at:?}: offset {offset}, want {want}")]
    LinePieceOffset {
        seq: u32,
        at: V2,
        offset: f64,
        want: f64,
    },
    #[error("line piece of seq {0} runs backwards")]
    Backwards(u32),
    #[error("corner arc is not an arc")]
    CornerArcNotArc,
    #[error("corner arc of seq {0} not centred on the corner")]
    CornerArcOffCentre(u32),
    #[error("corner arc of seq {0} radius != |r|")]
    CornerArcRadius(u32),
    #[error("corner arc without a motion {0} it")]
    CornerArcAlone(&'static str),
    #[error("corner arc of seq {0} not tangent")]
    CornerArcNotTangent(u32),
    #[error(
        "tool centre of seq {seq} is {distance_mm:.4} mm from the contour (r = {r}) and no \
         warning names it: {diags}"
    )]
    UnreportedGouge {
        seq: u32,
        distance_mm: f64,
        r: f64,
        diags: String,
    },
    #[error("gouge warning for {block:?} is not real: {clearances}")]
    FalseGouge {
        block: Option<u32>,
        clearances: String,
    },
}

impl PathError {
    /// Stable code (tests match it; the message may improve).
    pub fn code(&self) -> &'static str {
        match self {
            PathError::Gap { .. } => "path_gap",
            PathError::NonFinite(_) => "path_non_finite",
            PathError::ArcPieceRadius { .. } => "path_arc_piece_radius",
            PathError::ArcBecameLine(_) => "path_arc_became_line",
            PathError::ArcPieceMoved(_) => "path_arc_piece_moved",
            PathError::ArcReversed(_) => "path_arc_reversed",
            PathError::LinePieceOffset { .. } => "path_line_piece_offset",
            PathError::Backwards(_) => "path_backwards",
            PathError::CornerArcNotArc => "path_corner_arc_not_arc",
            PathError::CornerArcOffCentre(_) => "path_corner_arc_off_centre",
            PathError::CornerArcRadius(_) => "path_corner_arc_radius",
            PathError::CornerArcAlone(_) => "path_corner_arc_alone",
            PathError::CornerArcNotTangent(_) => "path_corner_arc_not_tangent",
            PathError::UnreportedGouge { .. } => "path_unreported_gouge",
            PathError::FalseGouge { .. } => "path_false_gouge",
        }
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
) -> Result<(usize, usize), PathError> {
    let src: HashMap<u32, &Block> = input.iter().map(|b| (b.seq, b)).collect();
    let mv = motions(out);
    let mut pieces = 0;
    let mut arcs = 0;
    check_gaps(&mv)?;
    for (i, c) in mv.iter().enumerate() {
        let (s, e, _) = c.block.motion().unwrap();
        for p in [s, e] {
            if p.0.iter().any(|v| !v.is_finite()) {
                return Err(PathError::NonFinite(Box::new(*c)));
            }
        }
        match c.role {
            Role::Equidistant => {
                pieces += 1;
                check_equidistant(c, src[&c.block.seq], plane, tol)?;
            }
            Role::CornerArc => {
                arcs += 1;
                check_corner_arc(&mv, i, src[&c.block.seq], plane, tol)?;
            }
            _ => {}
        }
    }
    Ok((pieces, arcs))
}

/// An equidistant piece `c` of source block `b`: at distance `c.offset_mm` from its path,
/// an arc stays an arc about the same centre, a line does not run backwards.
fn check_equidistant(c: &CompBlock, b: &Block, plane: Plane, tol: f64) -> Result<(), PathError> {
    let (s, e, path) = c.block.motion().unwrap();
    let (ps, pe) = (V2::of(&s, plane), V2::of(&e, plane));
    let r = c.offset_mm;
    let (bs, be, bpath) = b.motion().unwrap();
    let (a, bb) = (V2::of(&bs, plane), V2::of(&be, plane));
    match bpath {
        Path::Arc { dir, center, .. } => {
            let cc = V2::of(&center, plane);
            let rho = a.dist(cc);
            let want = if dir == ArcDir::Ccw { rho - r } else { rho + r };
            for q in [ps, pe] {
                if (q.dist(cc) - want).abs() > tol {
                    return Err(PathError::ArcPieceRadius {
                        seq: b.seq,
                        at: q,
                        distance: q.dist(cc),
                        want,
                    });
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
                    return Err(PathError::ArcBecameLine(b.seq));
                }
                return Ok(());
            };
            if odir != dir || !close(V2::of(&oc, plane), cc, 1e-9) {
                return Err(PathError::ArcPieceMoved(b.seq));
            }
        }
        _ => {
            let d = (bb - a).unit();
            for q in [ps, pe] {
                let off = d.cross(q - a);
                if (off - r).abs() > tol {
                    return Err(PathError::LinePieceOffset {
                        seq: b.seq,
                        at: q,
                        offset: off,
                        want: r,
                    });
                }
            }
            if (pe - ps).dot(d) < -1e-9 {
                return Err(PathError::Backwards(b.seq));
            }
        }
    }
    Ok(())
}

/// The corner arc `mv[i]` inserted at the start of source block `b`: centred on the corner,
/// of radius |offset|, tangent to the motions before and after it.
fn check_corner_arc(
    mv: &[CompBlock],
    i: usize,
    b: &Block,
    plane: Plane,
    tol: f64,
) -> Result<(), PathError> {
    let c = &mv[i];
    let (s, e, path) = c.block.motion().unwrap();
    let (ps, pe) = (V2::of(&s, plane), V2::of(&e, plane));
    let r = c.offset_mm;
    let corner = V2::of(&b.motion().unwrap().0, plane);
    let Path::Arc { center, .. } = path else {
        return Err(PathError::CornerArcNotArc);
    };
    if !close(V2::of(&center, plane), corner, 1e-9) {
        return Err(PathError::CornerArcOffCentre(b.seq));
    }
    for q in [ps, pe] {
        if (q.dist(corner) - r.abs()).abs() > tol {
            return Err(PathError::CornerArcRadius(b.seq));
        }
    }
    // Neighbours moving in the plane (bridged Z moves stand between).
    let moves = |c: &CompBlock| {
        let (a, b) = ends(&c.block, plane);
        a.dist(b) > 1e-9
    };
    let Some(before) = mv[..i].iter().rev().find(|c| moves(c)) else {
        return Err(PathError::CornerArcAlone("before"));
    };
    let Some(after) = mv[i + 1..].iter().find(|c| moves(c)) else {
        return Err(PathError::CornerArcAlone("after"));
    };
    let t_in = tangent(&before.block, plane, true);
    let t_out = tangent(&after.block, plane, false);
    if tangent(&c.block, plane, false).dot(t_in) < 1.0 - 1e-9
        || tangent(&c.block, plane, true).dot(t_out) < 1.0 - 1e-9
    {
        return Err(PathError::CornerArcNotTangent(b.seq));
    }
    Ok(())
}

/// Each motion starts where the one before it ended (1 nm).
fn check_gaps(mv: &[CompBlock]) -> Result<(), PathError> {
    for w in mv.windows(2) {
        let (_, e0, _) = w[0].block.motion().unwrap();
        let (s1, _, _) = w[1].block.motion().unwrap();
        if (e0 - s1).max_abs(6) > 1e-9 {
            return Err(PathError::Gap {
                before: Box::new(w[0]),
                after: Box::new(w[1]),
            });
        }
    }
    Ok(())
}

/// Continuity and finiteness only (for contours where loops are allowed).
pub fn check_continuous(out: &[CompBlock]) -> Result<(), PathError> {
    let mv = motions(out);
    for c in &mv {
        let (s, e, _) = c.block.motion().unwrap();
        if s.0.iter().chain(e.0.iter()).any(|v| !v.is_finite()) {
            return Err(PathError::NonFinite(Box::new(*c)));
        }
    }
    check_gaps(&mv)?;
    Ok(())
}

/// Signed sweep (rad) of an arc from angle `from` to angle `to` in its direction; an arc
/// whose ends meet sweeps a full turn when `closed_is_full_turn`, else nothing.
fn arc_sweep(from: f64, to: f64, ccw: bool, closed_is_full_turn: bool) -> f64 {
    let mut sweep = to - from;
    let full = closed_is_full_turn;
    while ccw && (sweep < 0.0 || (full && sweep == 0.0)) {
        sweep += std::f64::consts::TAU;
    }
    while !ccw && (sweep > 0.0 || (full && sweep == 0.0)) {
        sweep -= std::f64::consts::TAU;
    }
    sweep
}

/// An arc in a plane: centre, radius, start angle and signed sweep (rad).
struct PlaneArc {
    c: V2,
    rho: f64,
    a0: f64,
    sweep: f64,
    ccw: bool,
}

/// A motion's ends in `plane`, and its arc if it is one (see [`arc_sweep`] for
/// `closed_is_full_turn`).
fn plane_motion(b: &Block, plane: Plane, closed_is_full_turn: bool) -> (V2, V2, Option<PlaneArc>) {
    let (s, e, path) = b.motion().expect("motion");
    let (a, bb) = (V2::of(&s, plane), V2::of(&e, plane));
    let Path::Arc { dir, center, .. } = path else {
        return (a, bb, None);
    };
    let c = V2::of(&center, plane);
    let a0 = (a - c).angle();
    let ccw = dir == ArcDir::Ccw;
    let sweep = arc_sweep(a0, (bb - c).angle(), ccw, closed_is_full_turn);
    let arc = PlaneArc {
        c,
        rho: a.dist(c),
        a0,
        sweep,
        ccw,
    };
    (a, bb, Some(arc))
}

/// Distance from `q` to a programmed line or arc (plane G17).
pub fn dist_to_block(q: V2, b: &Block, plane: Plane) -> f64 {
    match plane_motion(b, plane, true) {
        (
            a,
            bb,
            Some(PlaneArc {
                c,
                rho,
                a0,
                sweep,
                ccw,
            }),
        ) => {
            let mut t = (q - c).angle() - a0;
            // Angle of q measured along the arc's direction, in [0, 2π).
            if !ccw {
                t = -t;
            }
            let t = t.rem_euclid(std::f64::consts::TAU);
            if t <= sweep.abs() {
                (q.dist(c) - rho).abs()
            } else {
                q.dist(a).min(q.dist(bb))
            }
        }
        (a, bb, None) => {
            let d = bb - a;
            let t = ((q - a).dot(d) / d.dot(d)).clamp(0.0, 1.0);
            q.dist(a + d * t)
        }
    }
}

/// Points along an output motion, at most `step_mm` apart.
pub fn samples(b: &Block, step_mm: f64, plane: Plane) -> Vec<V2> {
    match plane_motion(b, plane, false) {
        (
            _,
            _,
            Some(PlaneArc {
                c, rho, a0, sweep, ..
            }),
        ) => {
            let n = ((sweep.abs() * rho / step_mm).ceil() as usize).max(1);
            (0..=n)
                .map(|k| c + V2::from_angle(a0 + sweep * k as f64 / n as f64) * rho)
                .collect()
        }
        (a, bb, None) => {
            let n = ((a.dist(bb) / step_mm).ceil() as usize).max(1);
            (0..=n)
                .map(|k| a + (bb - a) * (k as f64 / n as f64))
                .collect()
        }
    }
}

/// The smallest distance of the compensated tool path (equidistants, corner arcs, collapsed
/// elements; not the start and cancel moves) from the programmed contour elements `contour`
/// (seq numbers), with the tool block and contour block where it occurs.
pub fn clearance(
    input: &[Block],
    out: &[CompBlock],
    contour: &[u32],
    plane: Plane,
) -> (f64, u32, u32) {
    let mut worst = (f64::INFINITY, 0, 0);
    let boxes: Vec<(V2, V2)> = contour
        .iter()
        .map(|&k| bbox(&samples(&input[k as usize], 1.0, plane)))
        .collect();
    for c in motions(out) {
        if !matches!(
            c.role,
            Role::Equidistant | Role::CornerArc | Role::Collapsed | Role::EquidistantChord
        ) {
            continue;
        }
        let qs = samples(&c.block, SAMPLE_MM, plane);
        let (lo, hi) = bbox(&qs);
        for (&k, &(a, b)) in contour.iter().zip(&boxes) {
            // Box gap (the 1 mm samples of an arc's box may cut its bulge by < 1 mm).
            let gap = (a.x - hi.x).max(lo.x - b.x).max(a.y - hi.y).max(lo.y - b.y) - 1.0;
            if gap > worst.0 {
                continue;
            }
            for &q in &qs {
                let d = dist_to_block(q, &input[k as usize], plane);
                if d < worst.0 {
                    worst = (d, c.block.seq, k);
                }
            }
        }
    }
    worst
}

fn bbox(pts: &[V2]) -> (V2, V2) {
    let mut lo = V2::new(f64::INFINITY, f64::INFINITY);
    let mut hi = V2::new(f64::NEG_INFINITY, f64::NEG_INFINITY);
    for p in pts {
        lo = V2::new(lo.x.min(p.x), lo.y.min(p.y));
        hi = V2::new(hi.x.max(p.x), hi.y.max(p.y));
    }
    (lo, hi)
}

/// Spacing of the tool-path samples of the independent gouge checker, mm.
pub const SAMPLE_MM: f64 = 0.02;

/// The seq numbers of the programmed contour: in-plane motions under G41/G42, without the
/// start block of each run (it leaves the equidistant by definition, SPEC §4.2).
pub fn contour_seqs(input: &[Block], plane: Plane) -> Vec<u32> {
    let mut out = Vec::new();
    let mut running = false;
    for b in input {
        let Some((s, e, path)) = b.motion() else {
            continue;
        };
        let in_plane =
            matches!(path, Path::Arc { .. }) || V2::of(&s, plane).dist(V2::of(&e, plane)) > 1e-9;
        if !in_plane {
            continue;
        }
        let on = b.comp != Comp::Off && path != Path::Rapid;
        if on && running {
            out.push(b.seq);
        }
        running = on;
    }
    out
}

/// The smallest sampled distance of each tool block's compensated pieces from the contour.
pub fn clearance_per_tool_block(
    input: &[Block],
    out: &[CompBlock],
    plane: Plane,
) -> HashMap<u32, f64> {
    let contour = contour_seqs(input, plane);
    let mut per = HashMap::new();
    for c in motions(out) {
        let one = [c];
        let (d, _, _) = clearance(input, &one, &contour, plane);
        if d.is_infinite() {
            continue;
        }
        let e = per.entry(c.block.seq).or_insert(f64::INFINITY);
        *e = d.min(*e);
    }
    per
}

/// The gouge invariant (issue #18): wherever the sampled tool centre comes closer than
/// r − `tol` to the contour, a gouge warning names that block; and every gouge warning is
/// real (the samples come within r − tol + the sampling step).
pub fn gouge_invariant(
    input: &[Block],
    out: &[CompBlock],
    diags: &[Diagnostic],
    r: f64,
    tol: f64,
    plane: Plane,
) -> Result<(), PathError> {
    let named: Vec<Option<u32>> = diags
        .iter()
        .filter(|d| kernel::comp::gouge::is_gouge(d))
        .map(|d| d.block)
        .collect();
    let n_of = |seq: u32| input[seq as usize].n;
    let per = clearance_per_tool_block(input, out, plane);
    for (&seq, &d) in &per {
        if d < r - tol && !named.contains(&n_of(seq)) {
            return Err(PathError::UnreportedGouge {
                seq,
                distance_mm: d,
                r,
                diags: format!("{diags:?}"),
            });
        }
    }
    for n in named {
        let real = per
            .iter()
            .any(|(seq, d)| n_of(*seq) == n && *d < r - tol + SAMPLE_MM);
        if !real {
            return Err(PathError::FalseGouge {
                block: n,
                clearances: format!("{per:?}"),
            });
        }
    }
    Ok(())
}
