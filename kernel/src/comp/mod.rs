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
//! One block goes through three steps, each in its own module:
//! 1. `lifecycle` (SPEC §4.1-4.2): start, continue, bridge and cancel a run of compensated
//!    elements; each new element is joined to the previous one (the junction closes it).
//! 2. `optimise` (SPEC §4.5): the R397 check of the element before the newest, the 3/4-block
//!    optimisations, the arc-to-chord replacements and the R764 exit optimisation.
//! 3. `emit`: elements no optimisation can move any more become tool-centre blocks.
//!
//! Geometry lives in [`geom`], junctions (R339, R234, R765) in [`corner`], the whole-run gouge
//! check in [`gouge`], settings in [`config`]. The user documentation is
//! `docs/compensation.md`.

pub mod config;
pub mod corner;
mod emit;
#[doc(hidden)]
pub mod fuzz;
pub mod geom;
pub mod gouge;
mod lifecycle;
mod optimise;

use std::collections::VecDeque;

use crate::block::{Block, Comp, Plane};
use crate::diag::{DiagCode, Diagnostic};
use crate::units::AxesMm;

pub use config::{CompConfig, CornerMode, EquidistantCheck, PercentRule};
use geom::{Geo, V2};
use lifecycle::{RunEnd, all_finite};

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

/// Where an element's tool-centre path stands. `Open` until the junction after it is known
/// (its end may still move); then `Kept` until the R397 check (SPEC §4.5) finds it running
/// backwards (`Backward`: no optimisation could fix it) or an optimisation removes its
/// equidistant (`Collapsed`: it starts and ends at one point). Only a closed element is
/// emitted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Equidistant {
    Open,
    Kept,
    Backward,
    Collapsed,
}

/// What the element's equidistant follows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Shape {
    /// The programmed line or arc.
    AsProgrammed,
    /// The chord of the programmed arc (R397 d5, d7, d8).
    Chord,
}

/// R765: the junction in front lies `distance_mm` from the programmed corner (beyond the
/// limit); reported when the element is emitted, so a junction replaced later by an
/// optimisation is not reported.
#[derive(Clone, Copy, Debug, PartialEq)]
enum FarCorner {
    /// The far intersection is used.
    Intersection { distance_mm: f64 },
    /// R765 d8 inserted an arc instead of the far intersection.
    ArcInserted { distance_mm: f64 },
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
    shape: Shape,
    kind: ElemKind,
    /// Tool-centre start and end in the plane (`end` final once the element is closed).
    start: V2,
    end: V2,
    state: Equidistant,
    /// Arc inserted before this element.
    corner: Option<CornerArc>,
    far: Option<FarCorner>,
    trailer: Vec<Block>,
}

impl Elem {
    /// A new open element whose tool centre starts at `start`.
    fn new(src: &Block, geo: Geo, shape: Shape, kind: ElemKind, start: V2) -> Self {
        Elem {
            src: *src,
            geo,
            programmed: geo,
            shape,
            kind,
            start,
            end: geo.end(),
            state: Equidistant::Open,
            corner: None,
            far: None,
            trailer: Vec::new(),
        }
    }

    fn is_regular(&self) -> bool {
        self.kind == ElemKind::Regular
    }

    fn is_closed(&self) -> bool {
        self.state != Equidistant::Open
    }

    fn is_collapsed(&self) -> bool {
        self.state == Equidistant::Collapsed
    }

    /// Its end is final (a closed element keeps its state).
    fn close(&mut self) {
        if self.state == Equidistant::Open {
            self.state = Equidistant::Kept;
        }
    }

    /// The equidistant is removed: the element starts and ends at `x`.
    fn collapse_at(&mut self, x: V2) {
        self.start = x;
        self.end = x;
        self.state = Equidistant::Collapsed;
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
                DiagCode::MessagesNotListed,
                None,
                0,
                0,
                format!("{n} more radius compensation messages were not kept"),
            ));
        }
        std::mem::take(&mut self.list)
    }
}

fn err(code: DiagCode, b: &Block, msg: impl Into<String>) -> Diagnostic {
    Diagnostic::error(code, b.n, b.line, 0, msg)
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
            return Err(err(
                DiagCode::NonFiniteCoordinate,
                b,
                "coordinate or radius is not a finite number",
            ));
        }
        if let Some((_, d, _)) = side_of(b.comp) {
            // SPEC §4: only with 8.R95 = 1; §4.1: the tool must be selected.
            if !self.cfg.enabled {
                return Err(err(
                    DiagCode::CompDisabled,
                    b,
                    "radius compensation G41/G42 is not enabled (machine constant 8.R95 = 0)",
                ));
            }
            if d == 0 {
                return Err(err(
                    DiagCode::CompWithoutTool,
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
