//! Radius compensation G41/G42/G40 on equidistants (SPEC §4). Issue #4.
//!
//! A streaming stage between interpreter and planner. Programmed blocks go in with
//! [`Compensator::push`]; tool-centre blocks come out of [`Compensator::poll`] (lines and arcs,
//! including inserted corner arcs), each keeping the `seq`/`n`/`line` of its source block.
//! [`Compensator::poll_traced`] also says what each output block is ([`Role`]). Warnings and
//! information messages (R397 check, R339 `-`, R764, R765, arc replacements) are collected
//! and handed out by [`Compensator::take_diagnostics`]; errors are returned by `push`, which
//! then leaves the compensator exactly as it was (the block is not taken).
//!
//! Memory is bounded: while compensation runs, the stage holds the last [`WINDOW`] in-plane
//! elements (the 4-block optimisation may still move them) and the blocks bridged between
//! them (at most 200 after each, SPEC §4.1).
//!
//! Geometry lives in [`geom`], junctions (R339, R234, R765) in [`corner`], settings in
//! [`config`]. The user documentation is `docs/compensation.md`.

pub mod config;
pub mod corner;
#[doc(hidden)]
pub mod fuzz;
pub mod geom;
pub mod gouge;

use std::collections::VecDeque;
use std::f64::consts::PI;

use crate::block::{ArcDir, Block, BlockKind, Comp, Path, Plane};
use crate::diag::Diagnostic;
use crate::units::AxesMm;

pub use config::{CompConfig, CornerMode, EquidistantCheck, PercentRule};
use corner::{Junction, NoIntersection, Resolved};
use geom::{EPS_MM, Geo, V2, intersect, wrap_pi};

/// Blocks without motion in the compensation plane that may stand between two compensated
/// motions (SPEC §4.1); one more is an error.
pub const MAX_BRIDGED: usize = 200;

/// Warnings and information messages kept until [`Compensator::take_diagnostics`]; beyond
/// this they are counted, not stored, so a caller that never collects them (or a program with
/// a message per block) cannot grow memory without bound.
pub const MAX_PENDING_DIAGNOSTICS: usize = 1000;

/// In-plane elements held back while compensation runs: the 4-block optimisation (R397 d4)
/// may move the end of the element three places back.
pub const WINDOW: usize = 4;

/// What an output block is, relative to the programmed path.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// Not compensated: passed through (at most its start moved to where the tool is).
    Passthrough,
    /// A start (G41/G42, or the rapid that restarts after G0): from where the tool is to the
    /// perpendicular point of the next element (SPEC §4.2).
    StartMove,
    /// The equidistant of the programmed element (trimmed at intersections).
    Equidistant,
    /// The equidistant of the chord that replaced a programmed arc (R397 d5, d7, d8).
    EquidistantChord,
    /// An arc of tool radius about a programmed corner (R339); carries the seq of the block
    /// it leads into.
    CornerArc,
    /// An element whose equidistant was removed by an optimisation (R397 3/4-block, R764):
    /// only its axes outside the plane move, or it is kept as a block without motion.
    Collapsed,
    /// A block bridged while compensation runs (no motion in the plane), placed where the
    /// tool centre stands.
    Bridged,
}

/// An output block with its role and the signed offset in force (mm, positive = left of the
/// programmed path, 0 when not compensated).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CompBlock {
    pub block: Block,
    pub role: Role,
    pub offset_mm: f64,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum ElemKind {
    /// Start block (G41/G42 from G40, a changed side/radius, or a rapid under G41/G42).
    Transition {
        rapid: bool,
    },
    Regular,
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct CornerArc {
    corner: V2,
    to: V2,
    sweep_rad: f64,
}

/// An in-plane motion under compensation, waiting for its end to be known and final.
#[derive(Clone, Debug)]
struct Elem {
    src: Block,
    geo: Geo,
    /// The programmed element as the gouge check measures it: `geo` before an arc was
    /// replaced by its chord for its equidistant (R397 d5, d8; d7's arc is not a circle, so
    /// its chord is the element).
    programmed: Geo,
    /// Arc replaced by its chord (R397 d5, d7, d8).
    chord: bool,
    kind: ElemKind,
    /// Tool-centre start and end in the plane (`end` valid once `closed`).
    start: V2,
    end: V2,
    closed: bool,
    /// Arc inserted before this element.
    corner: Option<CornerArc>,
    /// R765: the junction in front lies this far from the programmed corner (beyond the
    /// limit); reported when the element is emitted, so a junction replaced later by an
    /// optimisation is not reported.
    far_mm: Option<f64>,
    /// R765 d8 inserted the arc in front instead of a far intersection.
    position_arc: bool,
    /// Equidistant removed by an optimisation.
    collapsed: bool,
    /// Its equidistant runs backwards and the 3-block optimisation could not fix it.
    backward_unfixed: bool,
    trailer: Vec<Block>,
}

impl Elem {
    fn is_regular(&self) -> bool {
        self.kind == ElemKind::Regular
    }
}

#[derive(Clone, Debug)]
struct Run {
    comp: Comp,
    offset_mm: f64,
    plane: Plane,
    elems: VecDeque<Elem>,
}

/// The radius compensation stage (SPEC §4).
pub struct Compensator {
    cfg: CompConfig,
    run: Option<Run>,
    out: VecDeque<CompBlock>,
    notes: Notes,
    /// Where the tool (centre) is: end of the last output motion.
    tool: Option<AxesMm>,
    /// Plane of the last compensation, for reconciling after G40 without motion (7.R339).
    last_plane: Plane,
    /// The whole-run gouge check (docs/compensation.md decision 19).
    gouge: gouge::Check,
}

impl Default for Compensator {
    fn default() -> Self {
        Self::new(CompConfig::default())
    }
}

/// Pending warnings and information messages, bounded by [`MAX_PENDING_DIAGNOSTICS`].
#[derive(Default)]
struct Notes {
    list: Vec<Diagnostic>,
    /// Messages counted but not kept.
    dropped: usize,
}

impl Notes {
    fn push(&mut self, d: Diagnostic) {
        if self.list.len() < MAX_PENDING_DIAGNOSTICS {
            self.list.push(d);
        } else {
            self.dropped += 1;
        }
    }

    fn take(&mut self) -> Vec<Diagnostic> {
        if self.dropped > 0 {
            let n = std::mem::take(&mut self.dropped);
            self.list.push(Diagnostic::info(
                None,
                0,
                0,
                format!("{n} more radius compensation messages were not kept"),
            ));
        }
        std::mem::take(&mut self.list)
    }
}

/// Why a run of compensated elements ends.
#[derive(Clone, Copy, PartialEq, Eq)]
enum RunEnd {
    /// G40, a new side/radius, or program end: the last equidistant ends on the
    /// perpendicular at its programmed end point (SPEC §4.2).
    Cancel,
    /// A rapid: as `Cancel`, plus the R764 exit optimisation.
    Rapid,
}

fn err(b: &Block, msg: impl Into<String>) -> Diagnostic {
    Diagnostic::error(b.n, b.line, 0, msg)
}

fn name(b: &Block) -> String {
    source_name(b.n, b.line)
}

fn source_name(n: Option<u32>, line: u32) -> String {
    match n {
        Some(n) => format!("N{n}"),
        None => format!("on line {line}"),
    }
}

fn side_of(c: Comp) -> Option<(bool, u8, f64)> {
    match c {
        Comp::Off => None,
        Comp::Left { d, radius_mm } => Some((true, d, radius_mm)),
        Comp::Right { d, radius_mm } => Some((false, d, radius_mm)),
    }
}

/// Signed offset (positive = left): G41 left, G42 right, a negative radius swaps (SPEC §4.1).
fn signed_offset(c: Comp) -> f64 {
    match side_of(c) {
        Some((true, _, r)) => r,
        Some((false, _, r)) => -r,
        None => 0.0,
    }
}

fn with_plane(mut base: AxesMm, p: V2, plane: Plane) -> AxesMm {
    p.put(&mut base, plane);
    base
}

fn all_finite(b: &Block) -> bool {
    let fin = |p: &AxesMm| p.0.iter().all(|v| v.is_finite());
    let comp_ok = side_of(b.comp).is_none_or(|(_, _, r)| r.is_finite());
    comp_ok
        && match b.kind {
            BlockKind::Motion { start, end, path } => {
                fin(&start)
                    && fin(&end)
                    && match path {
                        Path::Arc { center, .. } => fin(&center),
                        _ => true,
                    }
            }
            BlockKind::Dwell { seconds } => seconds.is_finite(),
            BlockKind::TableWrite { values, .. } => values.iter().flatten().all(|v| v.is_finite()),
            BlockKind::Technology => true,
        }
}

/// What a block is for the compensation in `plane`.
enum Class {
    /// Motion in the plane: rapid (`None` geometry kind flag true), line or arc.
    InPlane { geo: Geo, rapid: bool },
    /// No motion in the plane (technology, dwell, motion of other axes only).
    Other,
}

fn classify(b: &Block, plane: Plane) -> Result<Class, Diagnostic> {
    let BlockKind::Motion { start, end, path } = b.kind else {
        return Ok(Class::Other);
    };
    let a = V2::of(&start, plane);
    let e = V2::of(&end, plane);
    match path {
        Path::Arc {
            dir,
            center,
            plane: arc_plane,
        } => {
            if arc_plane != plane {
                if b.comp == Comp::Off {
                    return Ok(Class::Other);
                }
                return Err(err(
                    b,
                    "arc in another plane than the radius compensation plane",
                ));
            }
            let c = V2::of(&center, plane);
            if a.dist(c) <= EPS_MM {
                return Err(err(b, "arc with zero radius"));
            }
            Ok(Class::InPlane {
                geo: Geo::arc(a, e, c, dir == ArcDir::Ccw),
                rapid: false,
            })
        }
        Path::Line | Path::Rapid if a.dist(e) > EPS_MM => Ok(Class::InPlane {
            geo: Geo::Line { a, b: e },
            rapid: path == Path::Rapid,
        }),
        _ => Ok(Class::Other),
    }
}

/// Signed sweep of the equidistant of an arc element between tool-centre points `start` and
/// `end`: the programmed sweep corrected by how far the junctions moved each end. A result
/// with the opposite sign is an equidistant that runs backwards.
fn arc_piece_sweep(geo: &Geo, start: V2, end: V2) -> f64 {
    let Geo::Arc {
        a, c, sweep_rad, ..
    } = *geo
    else {
        return 0.0;
    };
    let a0 = (a - c).angle();
    let ds = wrap_pi((start - c).angle() - a0);
    let de = wrap_pi((end - c).angle() - (a0 + sweep_rad));
    sweep_rad - ds + de
}

/// Whether the equidistant piece of `e` (between its tool-centre start and end) runs against
/// the programmed direction: the loop R397 looks for.
fn runs_backwards(e: &Elem, offset_mm: f64) -> bool {
    if e.collapsed {
        return false;
    }
    match e.geo {
        Geo::Line { a, b } => (e.end - e.start).dot(b - a) < -EPS_MM,
        Geo::Arc { sweep_rad, .. } => {
            if e.geo.offset_radius(offset_mm).unwrap_or(0.0) <= EPS_MM {
                return false;
            }
            let s = arc_piece_sweep(&e.geo, e.start, e.end);
            s * sweep_rad < 0.0 && s.abs() > 1e-12
        }
    }
}

impl Compensator {
    pub fn new(cfg: CompConfig) -> Self {
        Compensator {
            cfg,
            run: None,
            out: VecDeque::new(),
            notes: Notes::default(),
            tool: None,
            last_plane: Plane::G17,
            gouge: gouge::Check::default(),
        }
    }

    pub fn config(&self) -> &CompConfig {
        &self.cfg
    }

    /// Compensation is running (G41/G42 has taken effect and not been cancelled).
    pub fn is_active(&self) -> bool {
        self.run.is_some()
    }

    /// Blocks taken but not yet available from `poll` (bounded, see [`WINDOW`]).
    pub fn held_blocks(&self) -> usize {
        self.run.as_ref().map_or(0, |r| {
            r.elems.iter().map(|e| 1 + e.trailer.len()).sum::<usize>()
        })
    }

    /// Warnings and information messages produced so far (errors are returned by `push`).
    pub fn take_diagnostics(&mut self) -> Vec<Diagnostic> {
        self.notes.take()
    }

    /// Next tool-centre block.
    pub fn poll(&mut self) -> Option<Block> {
        self.out.pop_front().map(|c| c.block)
    }

    /// Next tool-centre block with its role.
    pub fn poll_traced(&mut self) -> Option<CompBlock> {
        self.out.pop_front()
    }

    /// No more blocks will come: a running compensation ends as if cancelled at the last
    /// programmed end point (program end, SPEC §4.1) and everything held back is released.
    pub fn finish(&mut self) {
        self.end_run(RunEnd::Cancel);
    }

    /// Takes one programmed block. On `Err` nothing has changed and the block is not taken.
    pub fn push(&mut self, b: &Block) -> Result<(), Diagnostic> {
        if !all_finite(b) {
            return Err(err(b, "coordinate or radius is not a finite number"));
        }
        if let Some((_, d, _)) = side_of(b.comp) {
            // SPEC §4: only with 8.R95 = 1; §4.1: the tool must be selected.
            if !self.cfg.enabled {
                return Err(err(
                    b,
                    "radius compensation G41/G42 is not enabled (machine constant 8.R95 = 0)",
                ));
            }
            if d == 0 {
                return Err(err(
                    b,
                    "G41/G42 without a tool: select the offset table entry with D first",
                ));
            }
        }
        match self.run.as_ref().map(|r| (r.plane, r.comp)) {
            None => self.push_idle(b),
            Some((plane, comp)) => self.push_running(b, plane, comp),
        }
    }

    fn push_idle(&mut self, b: &Block) -> Result<(), Diagnostic> {
        let class = classify(b, b.plane)?;
        let reconcile = self.needs_reconcile(b);
        match class {
            Class::InPlane { geo, rapid } if b.comp != Comp::Off => {
                // SPEC §4.2: start only in a block with linear interpolation.
                if geo.is_arc() {
                    return Err(err(
                        b,
                        "radius compensation can only start in a linear block (G0/G1), not on an arc",
                    ));
                }
                self.start_run(b, geo, rapid);
                Ok(())
            }
            Class::InPlane { geo, .. } if geo.is_arc() && reconcile => Err(err(
                b,
                "after G40 without motion the first motion in the plane must be linear",
            )),
            _ => {
                self.pass(b, Role::Passthrough, 0.0);
                Ok(())
            }
        }
    }

    /// After G40 without motion (7.R339 = 1) the tool centre is still off the programmed path.
    fn needs_reconcile(&self, b: &Block) -> bool {
        let (Some(tool), Some((start, _, _))) = (self.tool, b.motion()) else {
            return false;
        };
        V2::of(&tool, self.last_plane).dist(V2::of(&start, self.last_plane)) > 1e-6
    }

    fn push_running(&mut self, b: &Block, plane: Plane, comp: Comp) -> Result<(), Diagnostic> {
        if b.comp != Comp::Off && b.plane != plane {
            return Err(err(
                b,
                "the plane (G17/G18/G19) must not change while radius compensation is active",
            ));
        }
        let class = classify(b, plane)?;
        match class {
            Class::Other => {
                if b.comp == Comp::Off {
                    // SPEC §4.2: G40 without motion in the plane only with 7.R339 = 1.
                    if !self.cfg.g40_without_motion {
                        return Err(err(
                            b,
                            "G40 must be programmed in a block with motion in the compensation plane (or set 7.R339 = 1)",
                        ));
                    }
                    self.end_run(RunEnd::Cancel);
                    self.pass(b, Role::Passthrough, 0.0);
                    return Ok(());
                }
                // SPEC §4.1 bridging.
                let run = self.run.as_mut().expect("running");
                let back = run.elems.back_mut().expect("a run has an element");
                if back.trailer.len() >= MAX_BRIDGED {
                    return Err(err(
                        b,
                        format!(
                            "more than {MAX_BRIDGED} blocks without motion in the compensation plane"
                        ),
                    ));
                }
                back.trailer.push(*b);
                Ok(())
            }
            Class::InPlane { geo, rapid } => {
                if rapid {
                    // SPEC §4.2: G0 cancels; the rapid itself restarts if compensation stays on.
                    self.end_run(RunEnd::Rapid);
                    if b.comp != Comp::Off {
                        self.start_run(b, geo, true);
                    } else {
                        self.pass(b, Role::Passthrough, 0.0);
                    }
                    return Ok(());
                }
                if b.comp == Comp::Off {
                    if geo.is_arc() {
                        return Err(err(
                            b,
                            "G40 can only be programmed in a linear block, not on an arc",
                        ));
                    }
                    self.end_run(RunEnd::Cancel);
                    self.pass(b, Role::Passthrough, 0.0);
                    return Ok(());
                }
                if b.comp != comp {
                    let side_changed = side_of(b.comp).map(|s| s.0) != side_of(comp).map(|s| s.0);
                    if side_changed && !self.cfg.check.allow_side_change {
                        return Err(err(
                            b,
                            "direct change between G41 and G42 is not allowed (program G40 first, or set 6.R397 = 1)",
                        ));
                    }
                    if geo.is_arc() {
                        return Err(err(
                            b,
                            "radius compensation can only change in a linear block, not on an arc",
                        ));
                    }
                    self.end_run(RunEnd::Cancel);
                    self.start_run(b, geo, false);
                    return Ok(());
                }
                self.add_regular(b, geo)
            }
        }
    }

    fn start_run(&mut self, b: &Block, geo: Geo, rapid: bool) {
        self.last_plane = b.plane;
        let r = signed_offset(b.comp).abs();
        self.gouge.begin(b.plane, r, self.cfg.gouge_tolerance_mm(r));
        let start = self.tool.map_or(geo.start(), |t| V2::of(&t, b.plane));
        self.run = Some(Run {
            comp: b.comp,
            offset_mm: signed_offset(b.comp),
            plane: b.plane,
            elems: VecDeque::from([Elem {
                src: *b,
                geo,
                programmed: geo,
                chord: false,
                kind: ElemKind::Transition { rapid },
                start,
                end: geo.end(),
                closed: false,
                corner: None,
                far_mm: None,
                position_arc: false,
                collapsed: false,
                backward_unfixed: false,
                trailer: Vec::new(),
            }]),
        });
    }

    /// A compensated line or arc continuing the run.
    fn add_regular(&mut self, b: &Block, mut geo: Geo) -> Result<(), Diagnostic> {
        let cfg = self.cfg;
        let run = self.run.as_ref().expect("running");
        let s = run.offset_mm;
        let mut chord = false;
        let mut notes = Vec::new();
        if let Geo::Arc { a, b: e, c, .. } = geo {
            // R397 d7: an arc whose end point is off its circle becomes a line.
            if cfg.check.arc_off_circle_to_line
                && (a.dist(c) - e.dist(c)).abs() > cfg.arc_end_tolerance_mm
            {
                geo = geo.chord();
                chord = true;
                notes.push(Diagnostic::warning(
                    b.n,
                    b.line,
                    0,
                    "arc end point is not on the circle; replaced by a line (R397 d7)",
                ));
            }
        }
        if let Some(r) = geo.offset_radius(s)
            && r < -EPS_MM
        {
            return Err(err(
                b,
                format!(
                    "tool radius {:.3} mm is larger than the inside arc radius {:.3} mm",
                    s.abs(),
                    r + s.abs()
                ),
            ));
        }
        let elem = Elem {
            src: *b,
            geo,
            programmed: geo,
            chord,
            kind: ElemKind::Regular,
            start: geo.start(),
            end: geo.end(),
            closed: false,
            corner: None,
            far_mm: None,
            position_arc: false,
            collapsed: false,
            backward_unfixed: false,
            trailer: Vec::new(),
        };
        let back = run.elems.back().expect("a run has an element");
        match join(back, &elem, s, &cfg) {
            Ok(res) => {
                let run = self.run.as_mut().expect("running");
                run.elems.push_back(elem);
                let n = run.elems.len();
                apply_join(&mut run.elems, n - 1, res);
            }
            Err(NoIntersection) => {
                // R397 d8: replace an arc (the new one first, then the previous) by its chord.
                let mut elems = run.elems.clone();
                elems.push_back(elem);
                let n = elems.len();
                let fixed = cfg.check.arc_without_intersection_to_line
                    && [n - 1, n - 2]
                        .into_iter()
                        .any(|i| try_chord(&mut elems, i, s, &cfg));
                if !fixed {
                    let prev = &run.elems.back().expect("element").src;
                    return Err(err(
                        b,
                        format!(
                            "intersection of equidistants not found (NENALEZEN PRUSEČÍK EKVIDISTANT) between blocks {} and {}",
                            name(prev),
                            name(b)
                        ),
                    ));
                }
                for i in [n - 2, n - 1] {
                    let was_chord = if i == n - 1 {
                        chord
                    } else {
                        run.elems[i].chord
                    };
                    let e = &elems[i];
                    if e.chord && !was_chord {
                        notes.push(Diagnostic::warning(
                            e.src.n,
                            e.src.line,
                            0,
                            "no intersection of equidistants; arc replaced by a line (R397 d8)",
                        ));
                    }
                }
                self.run.as_mut().expect("running").elems = elems;
            }
        }
        for d in notes {
            self.notes.push(d);
        }
        let n = self.run.as_ref().expect("running").elems.len();
        if n >= 2 {
            self.check_middle(n - 2);
        }
        self.emit_ready();
        Ok(())
    }

    /// R397 check of the middle of three consecutive compensated elements, and the
    /// optimisations that remove the loop (SPEC §4.5). See `docs/compensation.md`.
    fn check_middle(&mut self, m: usize) {
        let cfg = self.cfg;
        let run = self.run.as_mut().expect("running");
        let s = run.offset_mm;
        let elems = &mut run.elems;
        if m == 0 || m + 1 >= elems.len() {
            return;
        }
        // Only between compensated blocks (no start).
        if !elems[m - 1].is_regular() || !elems[m].is_regular() {
            return;
        }
        if !runs_backwards(&elems[m], s) {
            return;
        }
        let src = elems[m].src;
        // Next to an inserted arc SPEC §4.5 does no R397 check; the loop is resolved
        // geometrically instead (docs/compensation.md, decision 18).
        if elems[m].corner.is_some() || elems[m + 1].corner.is_some() {
            if trim_at_corner_arc(elems, m, s) {
                return;
            }
            elems[m].backward_unfixed = true;
            if cfg.check.check && cfg.check.warn {
                self.notes.push(backward_warning(&src));
            }
            return;
        }
        if elems[m].geo.is_arc() && cfg.check.complementary_arc_to_line {
            let mut trial = elems.clone();
            if try_chord(&mut trial, m, s, &cfg) && !runs_backwards(&trial[m], s) {
                *elems = trial;
                self.notes.push(Diagnostic::warning(
                    src.n,
                    src.line,
                    0,
                    "the equidistant of the arc runs backwards; arc replaced by a line (R397 d5)",
                ));
                return;
            }
        }
        if !cfg.check.check {
            return;
        }
        if cfg.check.warn {
            self.notes.push(backward_warning(&src));
        }
        // 4-block: this and the previous element both loop; join m-2 and m+1 directly.
        if cfg.check.optimise_4_blocks
            && m >= 2
            && elems[m - 1].backward_unfixed
            && elems[m - 2].is_regular()
            && !elems[m - 2].collapsed
            && elems[m - 1].corner.is_none()
            && bypass(elems, m - 2, m + 1, s)
        {
            self.notes.push(Diagnostic::info(
                src.n,
                src.line,
                0,
                format!(
                    "blocks {} and {}: equidistant loop removed by the 4-block optimisation (R397 d4)",
                    name(&elems[m - 1].src),
                    name(&src)
                ),
            ));
            return;
        }
        if cfg.check.optimise_3_blocks && !elems[m - 1].collapsed && bypass(elems, m - 1, m + 1, s)
        {
            self.notes.push(Diagnostic::info(
                src.n,
                src.line,
                0,
                "equidistant loop removed by the 3-block optimisation (R397 d3)",
            ));
            return;
        }
        elems[m].backward_unfixed = true;
    }

    /// Emits elements that no optimisation can change any more.
    fn emit_ready(&mut self) {
        loop {
            let Some(run) = self.run.as_mut() else { return };
            if run.elems.len() <= WINDOW || !run.elems[0].closed {
                return;
            }
            let e = run.elems.pop_front().expect("non-empty");
            let (s, plane) = (run.offset_mm, run.plane);
            self.emit_elem(e, s, plane);
        }
    }

    /// Closes the run: the last element ends on the perpendicular at its programmed end
    /// (a rapid start ends at its programmed end), then everything is released.
    fn end_run(&mut self, why: RunEnd) {
        let Some(mut run) = self.run.take() else {
            return;
        };
        let s = run.offset_mm;
        if let Some(last) = run.elems.back_mut() {
            last.end = match last.kind {
                ElemKind::Transition { rapid: true } => last.geo.end(),
                _ => last.geo.offset_end(s),
            };
            last.closed = true;
        }
        let n = run.elems.len();
        if why == RunEnd::Rapid && n >= 2 && run.elems[n - 1].is_regular() {
            self.exit_optimisation(&mut run.elems[n - 1], s);
        }
        self.last_plane = run.plane;
        for e in run.elems {
            self.emit_elem(e, s, run.plane);
        }
        self.report_gouges();
    }

    /// The whole-run gouge check (docs/compensation.md decision 19): one message per tool
    /// block that cuts into the contour, naming both blocks and the depth.
    fn report_gouges(&mut self) {
        let (found, skipped) = self.gouge.finish();
        for g in found {
            let (t, c) = (g.tool, g.contour);
            let msg = format!(
                "{} the tool centre of block {} comes {:.3} mm closer than the tool radius to the contour of block {}: the tool cuts into the part",
                gouge::MESSAGE_PREFIX,
                source_name(t.n, t.line),
                g.depth_mm,
                source_name(c.n, c.line)
            );
            self.notes.push(if self.cfg.refuse_gouges {
                Diagnostic::error(t.n, t.line, 0, msg)
            } else {
                Diagnostic::warning(t.n, t.line, 0, msg)
            });
        }
        if let Some(t) = skipped {
            self.notes.push(Diagnostic::info(
                t.n,
                t.line,
                0,
                format!(
                    "the gouge check covers the first {} elements of a compensated contour; from here on it is not checked",
                    gouge::MAX_CHECKED_ELEMENTS
                ),
            ));
        }
    }

    /// R764: the last working block before a rapid, shorter than the limit, whose
    /// equidistant would run backwards, ends where it starts (SPEC §4.5).
    fn exit_optimisation(&mut self, e: &mut Elem, s: f64) {
        let rule = self.cfg.exit;
        if !(rule.report || rule.optimise) {
            return;
        }
        if e.geo.length_mm() >= rule.percent / 100.0 * s.abs() || !runs_backwards(e, s) {
            return;
        }
        let b = e.src;
        if rule.optimise {
            e.end = e.start;
            e.collapsed = true;
            if rule.report {
                self.notes.push(Diagnostic::info(
                    b.n,
                    b.line,
                    0,
                    "exit from the contour optimised, the backward move is left out (R764)",
                ));
            }
        } else {
            self.notes.push(Diagnostic::warning(
                b.n,
                b.line,
                0,
                "on the exit from the contour the tool centre moves backwards (R764)",
            ));
        }
    }

    fn tool_or(&self, p: AxesMm) -> AxesMm {
        self.tool.unwrap_or(p)
    }

    fn put(&mut self, block: Block, role: Role, offset_mm: f64) {
        match role {
            Role::Equidistant => self.gouge.tool(&block, true),
            // A chord's equidistant is not at the radius from the programmed arc.
            Role::EquidistantChord | Role::CornerArc | Role::Collapsed => {
                self.gouge.tool(&block, false)
            }
            _ => {}
        }
        if let Some((_, end, _)) = block.motion() {
            self.tool = Some(end);
        }
        self.out.push_back(CompBlock {
            block,
            role,
            offset_mm,
        });
    }

    /// A motion from where the tool is to `end`; without any axis moving it is kept as a
    /// block without motion (its M functions and feed still count).
    fn put_motion(&mut self, src: &Block, end: AxesMm, path: Path, role: Role, s: f64) {
        let start = self.tool_or(match src.kind {
            BlockKind::Motion { start, .. } => start,
            _ => end,
        });
        let mut b = *src;
        let moves = (end - start).max_abs(end.0.len()) > EPS_MM;
        b.kind = if moves || matches!(path, Path::Arc { .. }) {
            BlockKind::Motion { start, end, path }
        } else {
            BlockKind::Technology
        };
        self.put(b, role, s);
    }

    /// A block outside any run, or bridged inside one: motions start where the tool is, and
    /// a motion without displacement in `plane` keeps the tool's plane position.
    fn pass(&mut self, b: &Block, role: Role, s: f64) {
        let plane = if role == Role::Bridged {
            self.last_plane
        } else {
            b.plane
        };
        match b.kind {
            BlockKind::Motion {
                start: pstart,
                end,
                path,
            } => {
                let start = self.tool_or(pstart);
                let mut end = end;
                let moves_in_plane = matches!(path, Path::Arc { .. })
                    || V2::of(&pstart, plane).dist(V2::of(&end, plane)) > EPS_MM;
                if !moves_in_plane || role == Role::Bridged {
                    V2::of(&start, plane).put(&mut end, plane);
                }
                let mut out = *b;
                out.kind = BlockKind::Motion { start, end, path };
                self.put(out, role, s);
            }
            _ => self.put(*b, role, s),
        }
    }

    fn emit_elem(&mut self, e: Elem, s: f64, plane: Plane) {
        let src = e.src;
        let (pstart, pend) = match src.kind {
            BlockKind::Motion { start, end, .. } => (start, end),
            _ => (AxesMm::ZERO, AxesMm::ZERO),
        };
        match e.kind {
            ElemKind::Transition { rapid } => {
                let path = if rapid { Path::Rapid } else { Path::Line };
                // A rapid not followed by a cut stays uncompensated (SPEC §4.2).
                let (role, s) = if rapid && e.end == e.geo.end() {
                    (Role::Passthrough, 0.0)
                } else {
                    (Role::StartMove, s)
                };
                self.put_motion(&src, with_plane(pend, e.end, plane), path, role, s);
            }
            ElemKind::Regular => {
                self.gouge.contour(&e.programmed, &src);
                if let Some(d) = e.far_mm
                    && self.cfg.position.report
                {
                    let what = if e.position_arc {
                        "an arc was inserted instead (R765)"
                    } else {
                        "check the corner (R765)"
                    };
                    let pct = self.cfg.position.percent;
                    self.notes.push(Diagnostic::warning(
                        src.n,
                        src.line,
                        0,
                        format!(
                            "the equidistant lies {d:.3} mm from the programmed corner, more than {pct:.0} % of the tool radius; {what}"
                        ),
                    ));
                }
                if let Some(c) = e.corner {
                    let here = self.tool_or(pstart);
                    if c.sweep_rad.abs() * s.abs() > EPS_MM {
                        let dir = if c.sweep_rad > 0.0 {
                            ArcDir::Ccw
                        } else {
                            ArcDir::Cw
                        };
                        let path = Path::Arc {
                            dir,
                            center: with_plane(here, c.corner, plane),
                            plane,
                        };
                        self.put_motion(
                            &src,
                            with_plane(here, c.to, plane),
                            path,
                            Role::CornerArc,
                            s,
                        );
                        // SPEC §4.3: R339 sign `-`, an information message per inserted arc.
                        if self.cfg.report_inserted_arcs {
                            self.notes.push(Diagnostic::info(
                                src.n,
                                src.line,
                                0,
                                "arc of tool radius inserted at the corner (R339)",
                            ));
                        }
                    }
                }
                let role = if e.chord {
                    Role::EquidistantChord
                } else {
                    Role::Equidistant
                };
                let end = with_plane(pend, e.end, plane);
                let degenerate_arc = e.geo.offset_radius(s).is_some_and(|r| r <= EPS_MM);
                if e.collapsed || degenerate_arc {
                    self.put_motion(&src, end, Path::Line, Role::Collapsed, s);
                } else {
                    match e.geo {
                        Geo::Line { .. } => self.put_motion(&src, end, Path::Line, role, s),
                        Geo::Arc { c, .. } => {
                            let rho = e.geo.offset_radius(s).unwrap_or(0.0);
                            let sweep = arc_piece_sweep(&e.geo, e.start, e.end);
                            let centre = with_plane(pstart, c, plane);
                            if sweep.abs() * rho <= EPS_MM {
                                self.put_motion(&src, end, Path::Line, role, s);
                            } else {
                                let dir = if sweep > 0.0 { ArcDir::Ccw } else { ArcDir::Cw };
                                let path = Path::Arc {
                                    dir,
                                    center: centre,
                                    plane,
                                };
                                // Halves above 180°, so neither end coincides with its start
                                // and the planner reads the sweep unambiguously.
                                if sweep.abs() > PI {
                                    let start_angle = (e.start - c).angle();
                                    let mid = c + V2::from_angle(start_angle + sweep / 2.0) * rho;
                                    let start = self.tool_or(pstart);
                                    let mid_axes = with_plane(start.lerp(&end, 0.5), mid, plane);
                                    self.put_motion(&src, mid_axes, path, role, s);
                                }
                                self.put_motion(&src, end, path, role, s);
                            }
                        }
                    }
                }
            }
        }
        self.last_plane = plane;
        for t in &e.trailer {
            self.pass(t, Role::Bridged, s);
        }
    }
}

/// The junction in front of `next`: a start block ends on the perpendicular to `next` at its
/// start (SPEC §4.2); otherwise the corner rules.
fn join(prev: &Elem, next: &Elem, s: f64, cfg: &CompConfig) -> Result<Resolved, NoIntersection> {
    match prev.kind {
        ElemKind::Transition { .. } => Ok(Resolved {
            junction: Junction::Point {
                at: next.geo.offset_start(s),
                intersection: false,
            },
            far_mm: None,
            position_optimised: false,
        }),
        ElemKind::Regular => corner::resolve(&prev.geo, &next.geo, s, cfg),
    }
}

fn apply_join(elems: &mut VecDeque<Elem>, i: usize, res: Resolved) {
    let (from, to, corner) = match res.junction {
        Junction::Point { at, .. } => (at, at, None),
        Junction::Arc {
            corner,
            from,
            to,
            sweep_rad,
        } => (
            from,
            to,
            Some(CornerArc {
                corner,
                to,
                sweep_rad,
            }),
        ),
    };
    let prev = &mut elems[i - 1];
    prev.end = from;
    prev.closed = true;
    let next = &mut elems[i];
    next.start = to;
    next.corner = corner;
    next.far_mm = res.far_mm;
    next.position_arc = res.position_optimised;
}

/// Replaces the arc at `i` by its chord and resolves its junctions again (R397 d5, d8).
/// On failure `elems` may be partly changed: callers work on a copy.
fn try_chord(elems: &mut VecDeque<Elem>, i: usize, s: f64, cfg: &CompConfig) -> bool {
    if i >= elems.len() || !elems[i].geo.is_arc() || !elems[i].is_regular() {
        return false;
    }
    // A full circle has no chord.
    if elems[i].geo.start().dist(elems[i].geo.end()) <= EPS_MM {
        return false;
    }
    elems[i].geo = elems[i].geo.chord();
    elems[i].chord = true;
    for j in [i, i + 1] {
        if j == 0 || j >= elems.len() {
            continue;
        }
        match join(&elems[j - 1], &elems[j], s, cfg) {
            Ok(res) => apply_join(elems, j, res),
            Err(NoIntersection) => return false,
        }
    }
    true
}

/// The R397 warning: the equidistant of `src` runs backwards (SPEC §4.5).
fn backward_warning(src: &Block) -> Diagnostic {
    Diagnostic::warning(
        src.n,
        src.line,
        0,
        format!(
            "Chyba v zadání ekvidistanty pro poloměrové korekce v bloku {}: error in the equidistant of block {}: the tool centre would run backwards (the tool is too large for this detail)",
            name(src),
            name(src)
        ),
    )
}

/// Sweep from angle `from` to angle `to` (rad) in the direction of `like` (its sign), in
/// (0, 2π] for a positive direction.
fn sweep_like(from: f64, to: f64, like: f64) -> f64 {
    let mut sw = wrap_pi(to - from);
    if like > 0.0 && sw < 0.0 {
        sw += 2.0 * PI;
    } else if like < 0.0 && sw > 0.0 {
        sw -= 2.0 * PI;
    }
    sw
}

/// Element `m` runs backwards and an arc is inserted at one of its ends (a short step between
/// an inside and an outside corner). Its equidistant is dropped and the inserted arc is cut
/// against the equidistant on the other side of the step: the previous element when the arc
/// is at `m`'s end, the next one when it is at `m`'s start. The tool centre then goes straight
/// from that equidistant onto the arc, which stays at the tool radius from the corner, instead
/// of running back along the step (docs/compensation.md, decision 18). `false` (nothing
/// changed) when the arc and the equidistant do not meet within the arc, or the trimmed
/// neighbour would run backwards itself.
fn trim_at_corner_arc(elems: &mut VecDeque<Elem>, m: usize, s: f64) -> bool {
    let r = s.abs();
    if let Some(c) = elems[m + 1].corner {
        // Arc at the end of m: trim the previous equidistant against it.
        if elems[m].corner.is_some() || elems[m - 1].collapsed {
            return false;
        }
        let circle = geom::Support::Circle { c: c.corner, r };
        let Some(x) = intersect(&elems[m - 1].geo.support(s), &circle, elems[m].start) else {
            return false;
        };
        let sw = sweep_like(
            (x - c.corner).angle(),
            (c.to - c.corner).angle(),
            c.sweep_rad,
        );
        let mut trial = elems[m - 1].clone();
        trial.end = x;
        if sw.abs() > c.sweep_rad.abs() + 1e-9 || runs_backwards(&trial, s) {
            return false;
        }
        elems[m - 1].end = x;
        collapse_at(&mut elems[m], x);
        if let Some(cc) = elems[m + 1].corner.as_mut() {
            cc.sweep_rad = sw;
        }
        return true;
    }
    let (Some(c), true) = (elems[m].corner, elems[m + 1].corner.is_none()) else {
        return false;
    };
    // Arc at the start of m: it now ends on the next equidistant.
    let circle = geom::Support::Circle { c: c.corner, r };
    let Some(x) = intersect(&circle, &elems[m + 1].geo.support(s), elems[m].end) else {
        return false;
    };
    let from = (elems[m - 1].end - c.corner).angle();
    let sw = sweep_like(from, (x - c.corner).angle(), c.sweep_rad);
    let mut trial = elems[m + 1].clone();
    trial.start = x;
    trial.end = if trial.closed {
        trial.end
    } else {
        trial.geo.offset_end(s)
    };
    if sw.abs() > c.sweep_rad.abs() + 1e-9 || runs_backwards(&trial, s) {
        return false;
    }
    collapse_at(&mut elems[m], x);
    elems[m].corner = Some(CornerArc {
        to: x,
        sweep_rad: sw,
        ..c
    });
    elems[m + 1].start = x;
    true
}

/// The element's equidistant is removed: it starts and ends at `x`.
fn collapse_at(e: &mut Elem, x: V2) {
    e.start = x;
    e.end = x;
    e.collapsed = true;
    e.backward_unfixed = false;
}

/// The 3-block (`first + 2 == last`) and 4-block (`first + 3 == last`) optimisation: the
/// equidistants of `first` and `last` are intersected directly and the elements between them
/// collapse onto that point, which removes their backward loop. Applied only when the point
/// exists and the shortened `first` still runs forwards.
fn bypass(elems: &mut VecDeque<Elem>, first: usize, last: usize, s: f64) -> bool {
    let near = (elems[first + 1].start + elems[last - 1].end) * 0.5;
    let Some(x) = intersect(
        &elems[first].geo.support(s),
        &elems[last].geo.support(s),
        near,
    ) else {
        return false;
    };
    let mut trial = elems[first].clone();
    trial.end = x;
    if runs_backwards(&trial, s) || elems[last].corner.is_some() {
        return false;
    }
    elems[first].end = x;
    for e in elems.range_mut(first + 1..last) {
        e.start = x;
        e.end = x;
        e.collapsed = true;
        e.backward_unfixed = false;
    }
    elems[last].start = x;
    elems[last].far_mm = None;
    true
}

/// Compensates a whole program (validation and preview): the tool-centre blocks and every
/// diagnostic in program order. A block refused with an error is skipped.
pub fn compensate_all(blocks: &[Block], cfg: &CompConfig) -> (Vec<Block>, Vec<Diagnostic>) {
    let (traced, diags) = compensate_all_traced(blocks, cfg);
    (traced.into_iter().map(|c| c.block).collect(), diags)
}

/// As [`compensate_all`], with the role of every output block.
pub fn compensate_all_traced(
    blocks: &[Block],
    cfg: &CompConfig,
) -> (Vec<CompBlock>, Vec<Diagnostic>) {
    let mut c = Compensator::new(*cfg);
    let mut out = Vec::with_capacity(blocks.len() + blocks.len() / 4);
    let mut diags = Vec::new();
    for b in blocks {
        let res = c.push(b);
        diags.extend(c.take_diagnostics());
        if let Err(d) = res {
            diags.push(d);
        }
        while let Some(o) = c.poll_traced() {
            out.push(o);
        }
    }
    c.finish();
    while let Some(o) = c.poll_traced() {
        out.push(o);
    }
    diags.extend(c.take_diagnostics());
    (out, diags)
}
