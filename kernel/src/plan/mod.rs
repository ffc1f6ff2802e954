//! Look-ahead planner: compensated blocks in, planned [`Segment`]s out (SPEC §7).
//!
//! Envelope velocity over a window of up to 500 blocks (SPEC §7.2, §7.3). For every junction
//! the planner decides whether it is smooth (G98/G24/G23 and the manual or automatic rule,
//! §7.1) and, if so, the highest speed the criteria allow there (dynamic, accuracy, local
//! curvature); segment ceilings come from axis limits, arcs, the minimum block duration and
//! R395. A backward pass turns these caps into safe end speeds. The full design and every
//! decision on a SPEC **decide** point are in `docs/planner.md`.
//!
//! ## The seam between planner and interpolator
//! A [`Segment`] carries the geometry and the *limits* the interpolator must respect, not a
//! time law: the interpolator (running on the real-time thread) generates speed online each
//! tick so that feed override, feed hold and stop act at once and smoothly. The planner's
//! promise is that `v_end_mm_s` of every committed segment is safe: from that speed at that
//! point, all later committed segments can be followed and braked for. The interpolator in
//! addition treats the end of what it has received as a stop point, so a starved queue slows
//! the machine down instead of overrunning.
//!
//! ## Streaming and memory
//! `push` appends to the window; a segment is committed (returned by `poll`) as soon as its end
//! speed can no longer rise (it, or a later junction, reached its junction cap), or when the
//! window holds `lookahead_blocks` blocks (then with the speed that is safe for the window).
//! `wants_input` is false while the window is full, so memory is bounded by the look-ahead,
//! and execution of a long program starts after the first junctions are final, not after the
//! whole program.

mod ahead;
mod budget;
mod config;
pub mod criteria;
mod junction;
mod merge;
mod near;
mod path;

use std::collections::VecDeque;

pub use config::{
    AXIS_FILTER_MAX_TICKS, AXIS_JERK_PER_ACCEL_PER_S, AxisLimits, ContinuityRule,
    DEFAULT_AXIS_LIMITS, DynamicSet, Envelope, PlannerConfig, Profile, axis_filter_ticks_for,
    jerk_from_p_mm_s3,
};
pub use junction::BOX_NORMAL_SHARE;
pub use path::SegPath;

use crate::block::{Block, BlockKind, Continuity, Feed, Path, ProgramStop, Spindle};
use crate::diag::{DiagCode, Diagnostic};
use crate::units::{AxesMm, MAX_AXES, TS_S, mm_min_to_mm_s};

/// Share of the isotropic axis acceleration given to acceleration normal to the path
/// (corners, curvature); the rest is left to the tangential acceleration on curved segments,
/// so their sum never exceeds an axis limit (**decided**, see `docs/planner.md`).
pub const NORMAL_SHARE: f64 = 0.5;

/// Emitted blocks kept as history for the curvature window of later junctions.
const HISTORY_BLOCKS: usize = 32;

/// Junctions finalized between two backward passes. Every pass also walks back over the
/// braking ramp before the window's end, which each new block raises (about 100 blocks on
/// dense chords), so a pass per 64 junctions visited each one 2.7 times; per 128, 1.8 times.
const BACKWARD_BATCH: usize = 128;

/// Feed override ceiling (SPEC: 0-150 %): no speed can exceed 1.5 × feed.
const OVERRIDE_MAX: f64 = 1.5;

/// How the path continues at the end of a segment (SPEC §7.5: yellow / red dots).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Junction {
    /// Not a smooth junction: the machine stops here (G98, G24, rapid, angle above R39 ...).
    #[default]
    Stop,
    /// Smooth junction, the speed stays at or above the R384 d5..6 percentage of the feed.
    Smooth,
    /// Smooth junction, but the planned speed drops below the R384 d5..6 percentage.
    SpeedDrop,
}

impl Junction {
    /// Drawn as a red dot in the preview (a stop or a drop), SPEC §7.5.
    pub fn is_red(self) -> bool {
        self != Junction::Smooth
    }
}

/// One planned piece of path with the limits the interpolator must keep.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Segment {
    /// Job (program run) this segment belongs to; the interpolator drops other jobs' segments.
    pub job: u32,
    /// Index of the source block in the program.
    pub seq: u32,
    /// `N` number of the source block.
    pub n: Option<u32>,
    /// Source line of the block.
    pub line: u32,
    pub path: SegPath,
    pub length_mm: f64,
    /// Programmed path speed before override, mm/s (for G0: the rapid speed).
    pub feed_mm_s: f64,
    /// Ceiling from geometry and axis limits, not scaled by override, mm/s.
    pub v_max_mm_s: f64,
    /// Highest speed allowed at the end of the segment, mm/s (0: stop there). Safe: later
    /// committed segments can be followed from it.
    pub v_end_mm_s: f64,
    /// Speed the junction criteria allow at the end (0 at a stop), before braking for later
    /// blocks: what a time-optimal profile under the same constraints may reach there.
    pub junction_cap_mm_s: f64,
    /// What the per-axis box on the setpoints reads of it (`interp::setpoint_box`).
    pub axis_box: SegmentBox,
    /// Path acceleration limit on this segment, mm/s².
    pub accel_mm_s2: f64,
    /// Linear profile, lines: the path acceleration of a tick whose step and the step
    /// before it both lie inside this line, mm/s² (0: none beyond `accel_mm_s2`). Such a
    /// tick's second difference is the speed change along the line alone, so it may use
    /// the axes' full path acceleration; the share a turn takes (`accel_mm_s2` of a line
    /// next to one) is needed only by the ticks whose steps touch it (issue #32).
    pub free_accel_mm_s2: f64,
    /// Speed up to which `free_accel_mm_s2` applies, mm/s: the speeds a line's budget was
    /// computed for (its acceleration next to a turn falls with the speed it runs at).
    pub free_accel_v_max_mm_s: f64,
    /// Linear profile, budgeted lines: the path acceleration of a tick whose steps touch
    /// the line's start junction but not its end one (`accel_start_mm_s2`), or its end
    /// junction but not its start one (`accel_end_mm_s2`), at the same speeds as
    /// `accel_mm_s2` (0: none beyond `accel_mm_s2`). Such a tick's second difference holds
    /// the turns of that junction only (its turns weigh every junction within a step of it),
    /// so the budget of that junction's turns alone holds (issue #32).
    pub accel_start_mm_s2: f64,
    pub accel_end_mm_s2: f64,
    /// Path jerk limit, mm/s³ (`f64::INFINITY` for the linear profile).
    pub jerk_mm_s3: f64,
    /// Deceleration for feed hold and stop (rapid and stop set, SPEC §7.4), mm/s².
    pub stop_accel_mm_s2: f64,
    /// G0 positioning (override applies as rapid override).
    pub rapid: bool,
    /// Last segment of the program.
    pub last: bool,
    /// Continuity at the end of this segment (for the preview and the API, SPEC §7.5).
    pub junction: Junction,
    /// G24: after stopping at the end, wait until the following error is small (SPEC §7.1).
    pub wait_in_position: bool,
    /// Dwell after stopping at the end of this segment, s.
    pub dwell_s: f64,
    /// Dwell before this segment starts (a dwell programmed before the first motion), s.
    pub dwell_before_s: f64,
    /// Dynamic set 1..4 in force (SPEC §7.4).
    pub dyn_set: u8,
    /// Spindle state of the source block (M3/M4/M5, S, KŘR, G76 limit, gear): the RT thread
    /// computes the spindle speed from it each tick (SPEC §6).
    pub spindle: Spindle,
    /// Spindle state of a technology block that follows this segment (e.g. M5 after the last
    /// cut): in force once the segment is completed, at the stop before that block.
    pub spindle_after: Option<Spindle>,
    /// M0/M1 after this segment: the interpolator holds at its end (a stop point) until
    /// resumed (issue #15).
    pub program_stop: ProgramStop,
    /// M0/M1 before the first motion of a program: held at this segment's start.
    pub program_stop_before: ProgramStop,
    /// Axis smoothing filter the junction speeds were planned for, ticks per stage (0 or 1 =
    /// none; parabolic profile, `PlannerConfig::axis_filter_ticks`).
    pub axis_filter_ticks: u16,
    /// Feed per revolution: the spindle speed (rpm) `feed_mm_s` was planned at; the
    /// interpolator scales the feed by actual/nominal each tick (0 = feed per minute).
    pub per_rev_nominal_rpm: f64,
    /// A probing move (`crate::probe`): the RT thread watches the probe input while it
    /// runs and brakes at the change; it starts and ends at rest.
    pub probe: Option<crate::probe::ProbeMove>,
}

/// What the per-axis box on the setpoints reads of a segment (`interp::setpoint_box`, issues
/// #32 and #49): the box judges lines and arcs of the linear profile, choosing each setpoint
/// by the axes' accelerations and the path acceleration (R52, R236, R237, the set's A)
/// directly.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SegmentBox {
    /// The axes' accelerations; unset where the box does not judge the segment.
    pub accel_mm_s2: BoxAccel,
    /// Its ceiling, mm/s: the axes' speeds and the minimum block duration (on an arc also
    /// the manual's arc criteria, `Planner::arc_box_ceiling`), lowered by R395 to the faster
    /// of the manual's criteria speeds at its junctions (`criteria_end_mm_s`) where rising
    /// inside the block would not pay off. The envelope's own junction speeds, line budgets
    /// and share of the axes on an arc, which lower `Segment::v_max_mm_s`, are not its
    /// limits.
    pub v_max_mm_s: f64,
    /// The end junction: the speed the manual's criteria alone (R385, R384; SPEC §7.2) allow
    /// there, mm/s (∞ where the path goes straight on; 0 at a stop); and for the accuracy
    /// criterion over the junctions within one step (the criteria over the blocks within one
    /// tick), its turn as tan(α/2) and the criterion's Lm (mm, ∞: off).
    pub criteria_end_mm_s: f64,
    pub end_half_tan: f64,
    pub lm_mm: f64,
    /// The jerks and the corridor of the jerk-limited box (parabolic profile); unset in the
    /// linear profile.
    pub jerk: BoxJerk,
}

/// The axes' accelerations and the path acceleration a segment carries for the per-axis box
/// (`SegmentBox::accel_mm_s2`), mm/s², in single precision rounded down (every segment
/// carries them: half the bytes). The path acceleration bounds the second difference of the
/// arc length (the speed along the path); ∞ where the constants leave it to the axes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BoxAccel {
    axes: [f32; MAX_AXES],
    path: f32,
}

/// `a` in single precision, never above it.
fn f32_down(a: f64) -> f32 {
    let f = a as f32;
    if f as f64 > a { f.next_down() } else { f }
}

impl BoxAccel {
    /// Not judged by the box.
    pub const NONE: BoxAccel = BoxAccel {
        axes: [0.0; MAX_AXES],
        path: 0.0,
    };

    pub fn of_axes(a_mm_s2: &[f64; MAX_AXES], path_mm_s2: f64) -> Self {
        BoxAccel {
            axes: a_mm_s2.map(f32_down),
            path: f32_down(path_mm_s2),
        }
    }

    pub fn is_set(&self) -> bool {
        self.axes[0] > 0.0
    }

    /// Axis `k`'s acceleration, mm/s² (at most the configured one).
    pub fn axis(&self, k: usize) -> f64 {
        f64::from(self.axes[k])
    }

    /// The path acceleration, mm/s² (at most the configured one; ∞: none).
    pub fn path(&self) -> f64 {
        f64::from(self.path)
    }
}

/// What the jerk-limited box (`interp::jerk_box`, parabolic profile) reads of a segment
/// besides `BoxAccel`, in single precision rounded down: each axis's jerk, the path
/// acceleration and jerk (the constants' A and P, each within the lowest axis's:
/// `Planner::box_jerk_of`), and how far the filtered setpoints may lie from the path, mm
/// (half R384's Lm; ∞ where R384 is off).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BoxJerk {
    axes: [f32; MAX_AXES],
    path: f32,
    accel: f32,
    off: f32,
}

impl BoxJerk {
    /// From each axis's jerk, the path's acceleration and jerk (mm/s², mm/s³) and the
    /// corridor (mm).
    pub fn of_axes(j_mm_s3: &[f64; MAX_AXES], path: (f64, f64), off_mm: f64) -> Self {
        BoxJerk {
            axes: j_mm_s3.map(f32_down),
            accel: f32_down(path.0),
            path: f32_down(path.1),
            off: f32_down(off_mm),
        }
    }

    /// The path acceleration, mm/s².
    pub fn accel(&self) -> f64 {
        f64::from(self.accel)
    }

    /// Set on the segments of the parabolic profile the box may judge.
    pub fn is_set(&self) -> bool {
        self.axes[0] > 0.0 && self.path > 0.0 && self.accel > 0.0
    }

    /// Axis `k`'s jerk, mm/s³ (at most the configured one).
    pub fn axis(&self, k: usize) -> f64 {
        f64::from(self.axes[k])
    }

    /// The path jerk, mm/s³.
    pub fn path(&self) -> f64 {
        f64::from(self.path)
    }

    /// How far the filtered setpoints may lie from the path, mm (∞: no bound).
    pub fn off_mm(&self) -> f64 {
        f64::from(self.off)
    }
}

/// Limits of a new segment from the axes and the criteria of its block alone.
struct SegLimits {
    v_max_mm_s: f64,
    /// The ceiling the per-axis box keeps (`SegmentBox::v_max_mm_s`).
    box_v_max_mm_s: f64,
    feed_mm_s: f64,
    jerk_mm_s3: f64,
    a_axes_mm_s2: f64,
}

/// A block in the look-ahead window.
#[derive(Clone, Debug)]
struct Pending {
    seg: Segment,
    continuity: Continuity,
    /// Unit tangents at start and end.
    t_start: AxesMm,
    t_end: AxesMm,
    /// |t_end − the previous block's t_end| and |t_start − the next block's t_start| per
    /// axis (0 until known): the turns the absolute-turn sums add per block walked
    /// (`near.rs`), worked out once per block rather than once per junction that sees it.
    abs_du_end: AxesMm,
    abs_du_start: AxesMm,
    /// Dynamic set index 0..3.
    set: usize,
    /// Path acceleration along the block from the axis limits.
    a_axes: f64,
    /// Path jerk along the block from the axis limits.
    j_axes: f64,
    /// A technology block or dwell after this block forces a stop.
    stop_after: bool,
    /// Junction to the next block is smooth (known once the next block is in the window).
    smooth: bool,
    /// A smooth junction that will be planned as a stop whatever the look-ahead finds
    /// (`Planner::passes_below_a_tick_step`): not smooth from the start, so the junctions
    /// before it see the stop when they are finalized.
    certain_stop: bool,
    /// Turn at the end junction (its chord 2·sin(α/2) and 2·cos(α/2)).
    turn: criteria::Turn,
    /// Speed allowed by the criteria at the end junction as if it were smooth (for R395).
    crit: f64,
    /// Hard cap at the end junction (0 when not smooth).
    cap: f64,
    /// The per-axis box on the setpoints may judge this block (`interp::setpoint_box`, and
    /// `interp::jerk_box` in the parabolic profile): a line or an arc (`set_accelerations`
    /// decides, with the continuity of its junctions).
    box_candidate: bool,
    /// A line between turning junctions: its acceleration as a function of its speed.
    budget: Option<budget::LineBudget>,
    /// The turns near the end junction when it is passed (linear profile).
    turns: Option<budget::JunctionTurns>,
}

impl Pending {
    /// Unit tangent at fraction `t` of the block (a line's is the one computed on entry).
    fn tangent_at_fraction(&self, t: f64, axes: usize) -> AxesMm {
        match self.seg.path {
            SegPath::Line { .. } => self.t_start,
            SegPath::Arc { .. } => self.seg.path.tangent_at(t, axes),
        }
    }

    /// Gives the segment the acceleration of its budget for speeds up to `v` (feed moves: the
    /// constants' path acceleration; hold and stop: the stop set's `rapid_a`).
    fn apply_budget(&mut self, b: &budget::LineBudget, v: f64, rapid_a: f64) {
        apply_budget_to(&mut self.seg, b, v, rapid_a);
    }
}

/// [`Pending::apply_budget`] on the segment alone (its block's budget borrowed beside it,
/// not copied: this runs on every braking step).
fn apply_budget_to(seg: &mut Segment, b: &budget::LineBudget, v: f64, rapid_a: f64) {
    seg.accel_mm_s2 = b.accel_at(v);
    let stop = rapid_a.min(b.tangential_at(v));
    seg.stop_accel_mm_s2 = if stop > 0.0 && stop.is_finite() {
        stop
    } else {
        seg.accel_mm_s2
    };
}

/// Streaming planner: push blocks, poll committed segments.
pub struct Planner {
    cfg: PlannerConfig,
    job: u32,
    win: VecDeque<Pending>,
    /// Leading entries of `win` already returned by `poll` (kept as history).
    emitted: usize,
    /// Leading entries of `win` whose end junction is final.
    finalized: usize,
    /// Leading entries of `win` whose end speed is final: up to a junction the backward pass
    /// left at its cap (or a stop). Later passes stop there (end speeds only rise, and a
    /// capped one cannot), so the end speeds before it can no longer change.
    settled: usize,
    finished: bool,
    /// A probing move ends the window until the next block (`Planner::probing_move`).
    barrier: bool,
    carry: Option<merge::Carry>,
    /// Dynamic set chosen by the PLC cell DYNAM_SET, until the program selects one again.
    plc_set: Option<usize>,
    last_plc_cell: Option<u8>,
    last_block_set: u8,
    /// A technology block or dwell arrived before any motion block.
    leading_dwell_s: f64,
    /// M0/M1 that could not ride on the last segment (none yet, or already committed): held
    /// at the start of the next segment, which starts from rest anyway.
    leading_stop: ProgramStop,
    /// The block that set `leading_stop` last (seq, N, line): a stop with no motion after it
    /// is handed out in its name ([`Planner::finish`]).
    leading_stop_block: (u32, Option<u32>, u32),
    /// Inputs a technology block's M functions wait for (docs/io.md): the next motion starts
    /// once they read 1.
    pending_wait: u64,
    /// Spindle state of the last block pushed (to see changes in technology blocks).
    spindle_state: Spindle,
    /// The blocks near the junction being finalized, walked once (`near.rs`).
    near: Option<Box<near::NearJunction>>,
    /// The crossing the last curvature-window search found (a warm start for the next
    /// junction), mm/s.
    window_guess_mm_s: f64,
    /// Junctions finalized since the last backward pass.
    pending_backward: usize,
    /// The length known after the junction at `finalized` (`ahead_known`), kept as blocks
    /// arrive and junctions are finalized.
    ahead: ahead::AheadSum,
    /// Blocks dropped from the front of `win` so far: a block's absolute number is its index
    /// plus this.
    popped: u64,
    /// One past the absolute number of the last block that is followed by a stop (0: none).
    last_rough: u64,
    /// End speed of the last committed segment, mm/s (the start speed of the next).
    committed_end_mm_s: f64,
    /// A spindle change in a technology block before any motion (`M3 S..` at the top of a
    /// program, or a program of technology blocks only); the first motion segment carries it
    /// (its state is in force from when it reaches the interpolator), else `finish` hands it
    /// out as a segment of zero length.
    leading_spindle: Option<Segment>,
    /// That zero-length segment, once the program has ended without motion.
    tech_out: Option<Segment>,
}

impl Planner {
    pub fn new(cfg: PlannerConfig, job: u32) -> Self {
        Planner {
            cfg,
            job,
            win: VecDeque::new(),
            emitted: 0,
            finalized: 0,
            settled: 0,
            finished: false,
            barrier: false,
            carry: None,
            plc_set: None,
            last_plc_cell: None,
            last_block_set: 1,
            leading_dwell_s: 0.0,
            leading_stop: ProgramStop::None,
            leading_stop_block: (0, None, 0),
            pending_wait: 0,
            spindle_state: Spindle::default(),
            near: None,
            window_guess_mm_s: 0.0,
            pending_backward: 0,
            ahead: ahead::AheadSum::default(),
            popped: 0,
            last_rough: 0,
            committed_end_mm_s: 0.0,
            leading_spindle: None,
            tech_out: None,
        }
    }

    pub fn config(&self) -> &PlannerConfig {
        &self.cfg
    }

    /// Whether the planner can take another block now (its window is not full).
    pub fn wants_input(&self) -> bool {
        !self.finished && self.win.len() - self.emitted < self.cfg.lookahead_blocks.max(2)
    }

    /// The PLC cell DYNAM_SET (0..3 selects set 1..4, SPEC §7.4). Call it with the current
    /// cell value before pushing blocks; a change takes over the dynamic set for the blocks
    /// pushed from then on, until the program selects a set with `G23 I1..I4` again.
    /// (Blocks already planned keep their set: the change acts after the look-ahead.)
    pub fn set_dynam_set_cell(&mut self, cell: u8) {
        if self.last_plc_cell != Some(cell) {
            if self.last_plc_cell.is_some() || cell != 0 {
                self.plc_set = Some(usize::from(cell.min(3)));
            }
            self.last_plc_cell = Some(cell);
        }
    }

    /// Takes the next block. On error nothing is changed.
    pub fn push(&mut self, block: &Block) -> Result<(), Diagnostic> {
        self.barrier = false;
        if self.finished {
            return Err(Diagnostic::error(
                DiagCode::Internal,
                block.n,
                block.line,
                0,
                "internal: block after the end of the program",
            ));
        }
        let (start, end, path) = match block.kind {
            BlockKind::Motion { start, end, path } => (start, end, path),
            BlockKind::Dwell { seconds } => {
                self.flush_carry();
                self.force_stop(seconds.max(0.0));
                self.advance();
                return Ok(());
            }
            _ => {
                self.push_technology(block);
                return Ok(());
            }
        };
        // Inputs a technology block before waits for hold this block's start.
        let mut own = *block;
        own.spindle.outputs.wait |= self.pending_wait;
        let block = &own;
        let spindle_before = std::mem::replace(&mut self.spindle_state, block.spindle);
        let probing = matches!(path, Path::Probe(_));
        if block.spindle.outputs.wait != 0 || block.spindle.outputs.touched || probing {
            // M functions on outputs act before the motion, at rest (and one that waits for
            // an input waits there), and so does a probing move: the block starts from a
            // stop (docs/io.md).
            self.flush_carry();
            self.force_stop(0.0);
        }
        let axes = self.cfg.axes;
        check_finite(block, &start, &end, axes)?;
        let rapid = path == Path::Rapid;
        let feed_mm_min = if rapid { 0.0 } else { feed_mm_min(block)? };
        // R383: a short line with nothing else in it merges into the next block (SPEC §7.2).
        let start = self.merged_start(block, path, start, feed_mm_min);
        let seg_path = match path {
            Path::Rapid | Path::Line | Path::Probe(_) => SegPath::Line { start, end },
            Path::Arc { dir, center, plane } => SegPath::arc(start, end, center, plane, dir),
        };
        let length_mm = seg_path.length(axes);
        if length_mm.is_nan() || length_mm <= 1e-9 {
            // No motion: its M functions (M0, outputs, the spindle) still act, as in a
            // block without axis words.
            self.spindle_state = spindle_before;
            self.push_technology(block);
            return Ok(());
        }
        // (A block that waits for inputs keeps its own start: it is not merged away.)
        if block.spindle.outputs.wait == 0
            && self.hold_back_short_line(block, path, start, end, length_mm, feed_mm_min)
        {
            return Ok(());
        }
        let set = self.dyn_set_of(block);
        self.pending_wait = 0;
        self.append(block, seg_path, length_mm, rapid, feed_mm_min, set);
        self.after_motion(block, path);
        Ok(())
    }

    /// The end of a motion block's segment: a probing move closes the window there, M0/M1
    /// stop there at rest.
    fn after_motion(&mut self, block: &Block, path: Path) {
        if let Path::Probe(mv) = path {
            self.probing_move(mv);
        }
        let stop = ProgramStop::of_block(block);
        if stop != ProgramStop::None {
            self.force_stop(0.0);
            self.program_stop(stop);
        }
        self.advance();
    }

    /// A block without motion. Technology functions (M codes) run at standstill: stop before
    /// them. A spindle change rides on the segment it follows, so the RT thread applies it
    /// when that segment ends (M5 after the last cut, S between cuts).
    fn push_technology(&mut self, block: &Block) {
        self.pending_wait |= block.spindle.outputs.wait;
        let spindle_change = block.spindle != self.spindle_state;
        self.spindle_state = block.spindle;
        let has_m = block.m.iter().any(Option::is_some);
        if has_m {
            self.flush_carry();
            self.force_stop(0.0);
            let stop = ProgramStop::of_block(block);
            if stop != ProgramStop::None {
                self.leading_stop_block = (block.seq, block.n, block.line);
            }
            self.program_stop(stop);
        }
        // M3/M4/M5 count even when the state looks unchanged: each run starts from the
        // power-on state, while the spindle may still turn from an earlier run.
        let spindle_m =
            block.m.iter().flatten().any(|m| matches!(m, 3..=5)) || block.spindle.outputs.touched;
        if spindle_change || (spindle_m && self.win.is_empty()) {
            let open = self.finalized < self.win.len();
            if let Some(p) = self.win.back_mut().filter(|_| open) {
                p.seg.spindle_after = Some(block.spindle);
            } else if self.win.is_empty() {
                self.leading_spindle = Some(Segment {
                    job: self.job,
                    seq: block.seq,
                    n: block.n,
                    line: block.line,
                    spindle: block.spindle,
                    ..Segment::default()
                });
            }
        }
        if has_m {
            self.advance();
        }
    }

    /// Marks a program stop (M0/M1) at the end of the open last segment, or before the first
    /// motion when nothing has moved yet.
    fn program_stop(&mut self, stop: ProgramStop) {
        if stop == ProgramStop::None {
            return;
        }
        let open = self.finalized < self.win.len();
        let slot = match self.win.back_mut() {
            Some(p) if open => &mut p.seg.program_stop,
            _ => &mut self.leading_stop,
        };
        *slot = slot.stronger(stop);
    }

    /// A probing move was appended: it ends at rest, and everything up to its end is
    /// committed now (the next block's start is known only once it has run).
    fn probing_move(&mut self, mv: crate::probe::ProbeMove) {
        if let Some(p) = self.win.back_mut() {
            p.seg.probe = Some(mv);
        }
        self.force_stop(0.0);
        self.barrier = true;
    }

    /// The window is closed at its end: every pushed block is final (the program ended,
    /// or a probing move waits for its result).
    pub(super) fn closed(&self) -> bool {
        self.finished || self.barrier
    }

    /// No more blocks will come.
    pub fn finish(&mut self) {
        if self.finished {
            return;
        }
        self.flush_carry();
        self.finished = true;
        if let Some(last) = self.win.back_mut() {
            last.seg.last = true;
        } else {
            self.tech_out = self.leading_spindle.take();
        }
        self.trailing_stop();
        self.advance();
    }

    /// A program stop (M0, M1, a tool change) with no motion after it: on the last segment
    /// not yet handed out, else on a segment of zero length of its own (the interpolator
    /// holds at rest where the path ended: `T3 M6` by MDI, `M0` before `M30`).
    fn trailing_stop(&mut self) {
        let stop = std::mem::take(&mut self.leading_stop);
        if stop == ProgramStop::None {
            return;
        }
        if self.emitted < self.win.len()
            && let Some(last) = self.win.back_mut()
        {
            last.seg.program_stop = last.seg.program_stop.stronger(stop);
            return;
        }
        let (seq, n, line) = self.leading_stop_block;
        let mut seg = self.tech_out.take().unwrap_or(Segment {
            job: self.job,
            seq,
            n,
            line,
            spindle: self.spindle_state,
            ..Segment::default()
        });
        seg.program_stop = stop;
        self.tech_out = Some(seg);
    }

    /// Next committed segment, if any.
    ///
    /// A program without motion whose technology blocks change the spindle yields one segment
    /// of zero length carrying that spindle state (the interpolator applies it at once).
    pub fn poll(&mut self) -> Option<Segment> {
        if self.emitted >= self.win.len() {
            return self.tech_out.take();
        }
        let full = self.win.len() - self.emitted >= self.cfg.lookahead_blocks.max(2);
        let i = self.emitted;
        // Only junctions the backward pass has already seen: an end speed emitted before it
        // could still have to come down to brake for a later block.
        if i >= self.finalized - self.pending_backward {
            return None;
        }
        if !(i < self.settled || full || self.closed()) {
            return None;
        }
        self.commit_budget(i);
        let seg = self.win[i].seg;
        self.emitted += 1;
        while self.emitted > HISTORY_BLOCKS {
            self.win.pop_front();
            self.popped += 1;
            self.emitted -= 1;
            self.finalized -= 1;
            self.settled = self.settled.saturating_sub(1);
        }
        Some(seg)
    }

    /// True when everything pushed has been polled and `finish` was called.
    pub fn is_done(&self) -> bool {
        self.finished && self.emitted == self.win.len() && self.tech_out.is_none()
    }

    fn dyn_set_of(&mut self, block: &Block) -> usize {
        let prog = block.dyn_set.clamp(1, 4);
        if prog != self.last_block_set {
            // The program selected a set: it takes over from the PLC cell.
            self.plc_set = None;
            self.last_block_set = prog;
        }
        self.plc_set.unwrap_or(usize::from(prog - 1))
    }

    fn force_stop(&mut self, dwell_s: f64) {
        let open = self.finalized < self.win.len();
        match self.win.back_mut() {
            Some(p) if open => {
                p.stop_after = true;
                p.seg.dwell_s += dwell_s;
            }
            _ => self.leading_dwell_s += dwell_s,
        }
    }

    /// The envelope's ceiling of an arc (∞ for lines): the manual's arc criteria
    /// (`criteria_mm_s`, [`Planner::arc_box_ceiling`]), the axes' centripetal acceleration
    /// within the normal share, and in the parabolic profile the axis jerk of the circular
    /// motion (with the axis filter: within the corner share, and its pull towards the centre
    /// within Lm/2).
    fn arc_ceiling(
        &self,
        path: &SegPath,
        criteria_mm_s: f64,
        dir: &AxesMm,
        set: usize,
        (a_axes, j_axes): (f64, f64),
    ) -> f64 {
        let SegPath::Arc { radius_mm, .. } = *path else {
            return f64::INFINITY;
        };
        let env = &self.cfg.envelope;
        let set_ = &env.sets[set];
        let a_iso = self.cfg.iso_accel(dir, dir) * NORMAL_SHARE;
        let v_max = criteria::curvature_mm_s(a_iso, 1.0 / radius_mm).min(criteria_mm_s);
        if env.profile != Profile::Parabolic {
            return v_max;
        }
        let t_f = self.cfg.axis_filter_s();
        if t_f <= 0.0 {
            let j = set_.jerk_mm_s3.min(j_axes);
            return v_max.min(criteria::arc_jerk_mm_s(j, radius_mm));
        }
        let a = set_.accel_mm_s2.min(a_axes) * (1.0 - NORMAL_SHARE);
        v_max.min(criteria::arc_filtered_mm_s(
            radius_mm,
            a,
            self.cfg.iso_jerk(dir) * NORMAL_SHARE,
            t_f,
            set_.accuracy_um * 1e-3 / 2.0,
        ))
    }

    /// The ceiling of an arc the per-axis box keeps (∞ for lines): the manual's criteria
    /// alone, the centripetal acceleration of the set (R232 d5..8, R411) and the chord
    /// criterion R232. The axes' accelerations are not in it: the box holds them on every
    /// setpoint itself, tangential and normal together, where the envelope splits them
    /// (`NORMAL_SHARE`).
    fn arc_box_ceiling(&self, path: &SegPath, set: usize) -> f64 {
        let SegPath::Arc { radius_mm, .. } = *path else {
            return f64::INFINITY;
        };
        let env = &self.cfg.envelope;
        criteria::curvature_mm_s(env.sets[set].centripetal_mm_s2, 1.0 / radius_mm)
            .min(criteria::arc_chord_mm_s(radius_mm, env.arc_chord_um))
    }

    /// Judges the junction between the last block of the window and `p` (SPEC §7.1), and `p`
    /// takes over the M0/M1 and dwell waiting before the first motion.
    fn link_previous(&mut self, p: &mut Pending) {
        p.seg.program_stop_before = std::mem::take(&mut self.leading_stop);
        if self.win.is_empty() && self.leading_dwell_s > 0.0 {
            // A dwell before the first motion: waited for at the start of this segment.
            p.seg.dwell_before_s = self.leading_dwell_s;
            self.leading_dwell_s = 0.0;
        }
        // (One past the absolute number of the block before this one.)
        let prev_end = self.popped + self.win.len() as u64;
        if let Some(prev) = self.win.back_mut() {
            p.abs_du_end = (p.t_end - prev.t_end).abs();
            prev.abs_du_start = (prev.t_start - p.t_start).abs();
            // (|t1 − t0| and |t1 + t0|, not the angle: the criteria need no acos, sin or tan.)
            prev.turn = criteria::Turn::between(&prev.t_end, &p.t_start, self.cfg.axes);
            prev.smooth = Self::is_smooth(&self.cfg, prev, p);
            if prev.smooth && Self::passes_below_a_tick_step(&self.cfg, prev, p) {
                prev.smooth = false;
                prev.certain_stop = true;
            }
            if !prev.smooth {
                self.last_rough = prev_end;
                if prev.continuity == Continuity::G24 || p.continuity == Continuity::G24 {
                    prev.seg.wait_in_position = true;
                }
            }
        }
    }

    /// Path jerk of a segment: none in the linear profile; the set's (or the rapid set's)
    /// jerk within the axes' in the parabolic profile.
    fn path_jerk_of(&self, rapid: bool, set: usize, j_axes: f64) -> f64 {
        let env = &self.cfg.envelope;
        match env.profile {
            Profile::Linear => f64::INFINITY,
            Profile::Parabolic if rapid => env.rapid_jerk_mm_s3.min(j_axes),
            Profile::Parabolic => env.sets[set].jerk_mm_s3.min(j_axes),
        }
    }

    /// Direction for the axis limits of a path: the tangent, and for arcs both plane axes at
    /// full path speed.
    fn limit_direction(path: &SegPath, t_start: AxesMm, length_mm: f64) -> AxesMm {
        let mut dir = t_start;
        if let SegPath::Arc {
            plane,
            radius_mm,
            sweep_rad,
            ..
        } = *path
        {
            let (a, b) = plane.axes();
            let plane_share = (radius_mm * sweep_rad.abs()) / length_mm;
            dir[a] = plane_share;
            dir[b] = plane_share;
        }
        dir
    }

    /// Whether the per-axis box on the setpoints may judge a block (`Pending::box_candidate`):
    /// lines and arcs, an arc of any radius (the linear profile's box, and the jerk-limited
    /// box of the parabolic profile, `interp::jerk_box`). A step turns the arcs it
    /// runs on by at most a half turn (`interp::setpoint_box::StepTurn`), so a scan meets at
    /// most three quarter turns of an arc (`arc_within`), and an arc turns at most once
    /// (`SegPath::arc`; a longer one, were there any, would be left to the envelope).
    fn box_candidate(&self, path: &SegPath) -> bool {
        match *path {
            SegPath::Line { .. } => true,
            SegPath::Arc {
                radius_mm,
                sweep_rad,
                ..
            } => radius_mm > 0.0 && sweep_rad.abs() <= std::f64::consts::TAU + 1e-9,
        }
    }

    /// Appends a motion block to the window: its limits from the axes, the arc criteria and
    /// the minimum block duration (SPEC §7.2), and the junction to the block before.
    fn append(
        &mut self,
        block: &Block,
        path: SegPath,
        length_mm: f64,
        rapid: bool,
        feed_mm_min: f64,
        set: usize,
    ) {
        // The motion segment carries the spindle state of the blocks before it.
        self.leading_spindle = None;
        let axes = self.cfg.axes;
        let t_start = path.tangent_at(0.0, axes);
        let t_end = path.tangent_at(1.0, axes);
        let dir = Self::limit_direction(&path, t_start, length_mm);
        let (v_axes, a_axes) = self.cfg.path_limits(&dir);
        let j_axes = self.cfg.path_jerk(&dir);
        let mut box_v_max = self.arc_box_ceiling(&path, set);
        let mut v_max = self.arc_ceiling(&path, box_v_max, &dir, set, (a_axes, j_axes));
        v_max = v_max.min(v_axes);
        box_v_max = box_v_max.min(v_axes);
        if !rapid {
            let v_duration = criteria::min_duration_mm_s(length_mm, self.cfg.min_block_time_s);
            v_max = v_max.min(v_duration);
            box_v_max = box_v_max.min(v_duration);
        }
        let feed_mm_s = if rapid {
            v_axes
        } else {
            mm_min_to_mm_s(feed_mm_min)
        };
        let limits = SegLimits {
            v_max_mm_s: v_max,
            box_v_max_mm_s: box_v_max,
            feed_mm_s,
            jerk_mm_s3: self.path_jerk_of(rapid, set, j_axes),
            a_axes_mm_s2: a_axes,
        };
        let seg = self.new_segment(block, path, length_mm, rapid, set, &limits);
        let mut p = Pending {
            seg,
            continuity: block.continuity,
            t_start,
            t_end,
            abs_du_end: AxesMm::ZERO,
            abs_du_start: AxesMm::ZERO,
            set,
            a_axes,
            j_axes,
            stop_after: false,
            smooth: false,
            certain_stop: false,
            turn: criteria::Turn::STRAIGHT,
            crit: 0.0,
            cap: 0.0,
            box_candidate: self.box_candidate(&path),
            budget: None,
            turns: None,
        };
        self.link_previous(&mut p);
        p.seg.wait_in_position = false;
        self.win.push_back(p);
    }

    /// The segment of a new block, with a conservative acceleration until its junctions are
    /// known (final in `finalize`).
    fn new_segment(
        &self,
        block: &Block,
        path: SegPath,
        length_mm: f64,
        rapid: bool,
        set: usize,
        l: &SegLimits,
    ) -> Segment {
        let env = &self.cfg.envelope;
        let a_plan = l
            .a_axes_mm_s2
            .min(env.accel_stop_mm_s2)
            .min(env.sets[set].accel_mm_s2)
            * NORMAL_SHARE.min(1.0 - NORMAL_SHARE);
        Segment {
            job: self.job,
            seq: block.seq,
            n: block.n,
            line: block.line,
            path,
            length_mm,
            feed_mm_s: l.feed_mm_s,
            v_max_mm_s: l.v_max_mm_s,
            v_end_mm_s: 0.0,
            junction_cap_mm_s: 0.0,
            axis_box: SegmentBox {
                v_max_mm_s: l.box_v_max_mm_s,
                ..SegmentBox::default()
            },
            accel_mm_s2: a_plan,
            free_accel_mm_s2: 0.0,
            free_accel_v_max_mm_s: 0.0,
            accel_start_mm_s2: 0.0,
            accel_end_mm_s2: 0.0,
            jerk_mm_s3: l.jerk_mm_s3,
            stop_accel_mm_s2: a_plan,
            rapid,
            last: false,
            junction: Junction::Stop,
            wait_in_position: false,
            dwell_s: 0.0,
            dwell_before_s: 0.0,
            dyn_set: set as u8 + 1,
            spindle: block.spindle,
            spindle_after: None,
            program_stop: ProgramStop::None,
            program_stop_before: ProgramStop::None,
            axis_filter_ticks: self.cfg.axis_filter_ticks as u16,
            per_rev_nominal_rpm: per_rev_nominal_rpm(block, rapid),
            probe: None,
        }
    }

    /// Whether the smooth junction between `prev` and `next` is a planned stop however it is
    /// approached: the manual's criteria at the junction itself (R385 with the constants'
    /// overload acceleration, R384), which bound every cap the planner finds there, lie
    /// below one tick's acceleration step of both blocks, where `Planner::pass_gain_s`
    /// stops every turning junction (issue #32: a raster's 90° corner, 2 mm/s by R384,
    /// turned the junction before it, 0.05 mm away, into a stop too, its cap held by the
    /// corner's turn within its tick window). At one tick's step itself too (issue #49: the
    /// same corner under a path acceleration of 500 mm/s² is exactly 2 mm/s, and passed,
    /// held the 1 mm step-over beside it at that speed by R395): a stop leaves the corner
    /// at that speed within a tick.
    fn passes_below_a_tick_step(cfg: &PlannerConfig, prev: &Pending, next: &Pending) -> bool {
        let is_arc = |q: &Pending| matches!(q.seg.path, SegPath::Arc { .. });
        if prev.turn.chord <= 1e-9 && !is_arc(prev) && !is_arc(next) {
            return false;
        }
        let env = &cfg.envelope;
        let set = &env.sets[next.set];
        let a = |q: &Pending| env.sets[q.set].accel_mm_s2.min(q.a_axes);
        let len = 0.5 * (prev.seg.length_mm + next.seg.length_mm);
        let ub = prev
            .turn
            .dynamic_len_mm_s(set.overload_mm_s2, set.overload_ref_len_mm, len)
            .min(prev.turn.accuracy_mm_s(set.accuracy_um));
        ub <= a(prev).min(a(next)) * TS_S * (1.0 + 1e-9)
    }

    /// Junction rule of SPEC §7.1 between `prev` and `next`.
    fn is_smooth(cfg: &PlannerConfig, prev: &Pending, next: &Pending) -> bool {
        let env = &cfg.envelope;
        if prev.stop_after || prev.seg.rapid || next.seg.rapid {
            // G0 is never smooth (its own dynamic set; **decided** also for the manual rule).
            return false;
        }
        if next.continuity != Continuity::G23 {
            return false;
        }
        if let Some(b) = env.break_len_mm
            && (prev.seg.length_mm < b || next.seg.length_mm < b)
        {
            return false;
        }
        match env.rule {
            ContinuityRule::Manual => true,
            ContinuityRule::Automatic => {
                let t_min = cfg.min_block_time_s;
                // The angle test looks at the first three axes only (SPEC §7.1).
                angle_first3(&prev.t_end, &next.t_start).to_degrees() < env.smooth_angle_deg
                    && prev.seg.length_mm / prev.seg.feed_mm_s >= t_min
                    && next.seg.length_mm / next.seg.feed_mm_s >= t_min
            }
        }
    }

    /// Finalizes every junction that has enough look-ahead, then runs the backward pass.
    fn advance(&mut self) {
        let full = self.win.len() - self.emitted >= self.cfg.lookahead_blocks.max(2);
        while self.finalized < self.win.len() {
            let i = self.finalized;
            let last = i + 1 == self.win.len();
            if last && !self.closed() {
                break;
            }
            // A full window finalizes without the look-ahead only a junction that holds up
            // every commit (blocks shorter than the tick window throughout the window).
            let forced = full && i == self.emitted;
            if !last && self.win[i].smooth && !self.closed() && !forced && !self.ahead_known(i) {
                break;
            }
            self.finalize(i, last);
            self.finalized += 1;
            match self.win.get(self.finalized) {
                Some(p) => self
                    .ahead
                    .next_junction(self.popped + i as u64, p.seg.length_mm),
                None => self.ahead = ahead::AheadSum::default(),
            }
            self.pending_backward += 1;
        }
        // The backward pass runs once per BACKWARD_BATCH junctions (it walks back over the
        // braking distance, so running it per block would cost that many steps per block);
        // commits wait at most that many blocks, far less than the window.
        if self.pending_backward > 0
            && (self.pending_backward >= BACKWARD_BATCH || self.closed() || full)
        {
            let first_new = self.finalized - self.pending_backward;
            self.pending_backward = 0;
            self.backward(self.finalized - 1, first_new);
        }
    }

    /// Speeds at which the curvature window around junction `i` can matter.
    fn window_len_mm(&self, i: usize) -> f64 {
        let (a, b) = (&self.win[i].seg, &self.win[i + 1].seg);
        let v = a
            .v_max_mm_s
            .max(b.v_max_mm_s)
            .min(OVERRIDE_MAX * a.feed_mm_s.max(b.feed_mm_s));
        v * TS_S * (2 * self.cfg.axis_filter_ticks).max(1) as f64
    }

    /// Whether the blocks after junction `i` (the first one not finalized) cover half the
    /// curvature window, and in the linear profile the window of its turns
    /// (`junction_turns`: 3h = 1.5·v_ref·Ts), or end in a stop.
    fn ahead_known(&mut self, i: usize) -> bool {
        let mut need = self.window_len_mm(i) / 2.0;
        if self.cfg.envelope.profile == Profile::Linear {
            // window_len_mm is v·Ts here; v_ref ≤ v + A·Ts.
            let a = self.win[i].a_axes.max(self.win[i + 1].a_axes);
            let a_ts = if a.is_finite() { a * TS_S } else { 0.0 };
            need = need.max(1.5 * (need * 2.0 + a_ts * TS_S));
        }
        // A stop after one of the blocks ahead (but the last, whose junction is not known).
        let j = self.popped + i as u64;
        if self.last_rough > j + 1 {
            return true;
        }
        // Their length (`ahead.rs`); the blocks pushed since the last call are added.
        if !self.ahead.is_for(j) {
            self.ahead = ahead::AheadSum::start(j);
        }
        let end = self.popped + self.win.len() as u64;
        while self.ahead.end() < end {
            let k = (self.ahead.end() - self.popped) as usize;
            self.ahead.add(self.win[k].seg.length_mm);
        }
        match self.ahead.compare(need) {
            ahead::Verdict::Reached => true,
            ahead::Verdict::NotReached => false,
            // The lengths summed in order, as the comparison is defined.
            ahead::Verdict::Unsure => {
                let mut have = 0.0;
                self.win.range(i + 1..).any(|p| {
                    have += p.seg.length_mm;
                    have >= need
                })
            }
        }
    }

    /// Unit tangents at the distances `ds` (ascending, > 0) after (`ahead`) or before the end
    /// of block `i`, as [`Planner::tangent_near`] gives them, in one walk.
    fn tangents_near(&self, i: usize, ahead: bool, ds: &[f64], out: &mut [AxesMm]) {
        let axes = self.cfg.axes;
        let mut k = if ahead { i + 1 } else { i };
        let mut walked = 0.0;
        let mut n = 0;
        while n < ds.len() {
            let p = &self.win[k];
            let rest = ds[n] - walked;
            if rest <= p.seg.length_mm {
                let f = rest / p.seg.length_mm;
                out[n] = p.tangent_at_fraction(if ahead { f } else { 1.0 - f }, axes);
                n += 1;
                continue;
            }
            let last = if ahead {
                k + 1 >= self.win.len() || !p.smooth
            } else {
                k == 0 || !self.win[k - 1].smooth
            };
            if last {
                out[n..ds.len()].fill(if ahead { p.t_end } else { p.t_start });
                return;
            }
            walked += p.seg.length_mm;
            if ahead {
                k += 1;
            } else {
                k -= 1;
            }
        }
    }

    /// Unit tangent at distance `d` before (negative) or after the end of block `i`, not
    /// crossing a stop and not leaving the window.
    fn tangent_near(&self, i: usize, d: f64) -> AxesMm {
        let axes = self.cfg.axes;
        if d <= 0.0 {
            let mut rest = -d;
            let mut k = i;
            loop {
                let p = &self.win[k];
                if rest <= p.seg.length_mm {
                    return p.tangent_at_fraction(1.0 - rest / p.seg.length_mm, axes);
                }
                rest -= p.seg.length_mm;
                if k == 0 || !self.win[k - 1].smooth {
                    return p.t_start;
                }
                k -= 1;
            }
        } else {
            let mut rest = d;
            let mut k = i + 1;
            loop {
                let p = &self.win[k];
                if rest <= p.seg.length_mm {
                    return p.tangent_at_fraction(rest / p.seg.length_mm, axes);
                }
                rest -= p.seg.length_mm;
                if k + 1 >= self.win.len() || !p.smooth {
                    return p.t_end;
                }
                k += 1;
            }
        }
    }

    /// Backward pass from the newly finalized junction `i`: end speeds that allow braking for
    /// everything up to the end of the window (treated as a stop).
    /// Junctions `fresh..=i` are new and always computed; older ones stop the pass once
    /// unchanged (end speeds only rise as the window grows).
    fn backward(&mut self, i: usize, fresh: usize) {
        let mut v_next_end = if i + 1 < self.finalized {
            self.win[i + 1].seg.v_end_mm_s
        } else {
            0.0
        };
        let mut k = i;
        loop {
            let v = if k + 1 < self.win.len() {
                self.braking_start_mm_s(k + 1, v_next_end)
            } else {
                0.0
            };
            let p = &mut self.win[k];
            let v = v.min(p.cap);
            if k < fresh && v <= p.seg.v_end_mm_s {
                break;
            }
            p.seg.v_end_mm_s = v;
            if v >= p.cap * (1.0 - 1e-12) {
                // At its cap: this end speed and every one before it are final.
                self.settled = self.settled.max(k + 1);
            }
            // Reclassify a drop that came from braking (never below what the junction allows).
            if p.seg.junction != Junction::Stop {
                let drop = self.cfg.envelope.sets[p.set].drop_percent / 100.0;
                p.seg.junction = if v < drop * p.seg.feed_mm_s {
                    Junction::SpeedDrop
                } else {
                    Junction::Smooth
                };
            }
            if k == self.emitted {
                break;
            }
            k -= 1;
            v_next_end = v;
        }
    }
}

impl Planner {
    /// Highest speed at the start of block `k` from which it can brake to `v_end` at its end,
    /// within its ceiling. A line with a [`budget::LineBudget`] gets the acceleration of the
    /// speeds it runs at when it is committed (`commit_budget`, which every emitted segment
    /// passes).
    fn braking_start_mm_s(&mut self, k: usize, v_end: f64) -> f64 {
        let n = &self.win[k];
        match &n.budget {
            Some(b) => b.reach_mm_s(v_end, n.seg.length_mm).min(n.seg.v_max_mm_s),
            None => (v_end * v_end + 2.0 * n.seg.accel_mm_s2 * n.seg.length_mm)
                .sqrt()
                .min(n.seg.v_max_mm_s),
        }
    }

    /// At the commit of block `i` with a budget: its highest speed is bounded by braking to
    /// its final end speed and by accelerating from the end speed of the block before
    /// (committed); its ceiling becomes that speed and its acceleration the one of it.
    fn commit_budget(&mut self, i: usize) {
        let rapid_a = self.cfg.envelope.rapid_accel_mm_s2;
        let v_from = self.committed_end_mm_s;
        let p = &mut self.win[i];
        let Some(b) = &p.budget else {
            self.committed_end_mm_s = p.seg.v_end_mm_s;
            return;
        };
        let len = p.seg.length_mm;
        let v = b
            .reach_mm_s(p.seg.v_end_mm_s, len)
            .min(b.reach_mm_s(v_from, len))
            .min(p.seg.v_max_mm_s);
        apply_budget_to(&mut p.seg, b, v, rapid_a);
        // Each end's turns alone, at the same speeds (each at least the combined budget:
        // fewer turns, the same line): a tick whose steps touch one junction of the line
        // has only that junction's turns in its second difference (those turns weigh every
        // junction within a step of it). With the directions of both ends: an end's own
        // would leave a little more (splines 8 ms) for two more walks of the axes per commit.
        p.seg.accel_start_mm_s2 = b.end_accel_at(v, 0).max(p.seg.accel_mm_s2);
        p.seg.accel_end_mm_s2 = b.end_accel_at(v, 1).max(p.seg.accel_mm_s2);
        // Free ticks must not carry the line past the speeds its budget covers.
        p.seg.free_accel_v_max_mm_s = b.covered_mm_s(v);
        p.seg.v_max_mm_s = p.seg.v_max_mm_s.min(b.covered_mm_s(v));
        self.committed_end_mm_s = p.seg.v_end_mm_s.min(v);
    }
}

/// Programmed feed of a cutting move, mm/min, or the error of a missing one.
fn feed_mm_min(block: &Block) -> Result<f64, Diagnostic> {
    match block.feed {
        Feed::MmPerMin(f) if f.is_finite() && f > 0.0 => Ok(f),
        Feed::MmPerMin(_) => Err(Diagnostic::error(
            DiagCode::NoFeed,
            block.n,
            block.line,
            0,
            "no feed programmed for a cutting move (F missing or zero)",
        )),
        // Feed per revolution (G95, KŘR with mm/rev; SPEC §5, §6): V = n·β, planned at the
        // nominal (highest) spindle speed of the block; the interpolator scales it by
        // n_actual / nominal every tick (`Segment::per_rev_nominal_rpm`).
        Feed::MmPerRev(f) if f.is_finite() && f > 0.0 => {
            match block.spindle.per_rev_nominal_rpm() {
                Some(n) => Ok(f * n),
                None => Err(Diagnostic::error(
                    DiagCode::FeedPerRevWithoutSpindle,
                    block.n,
                    block.line,
                    0,
                    "feed per revolution needs a running spindle with a programmed speed S",
                )),
            }
        }
        Feed::MmPerRev(_) => Err(Diagnostic::error(
            DiagCode::FeedPerRevWithoutSpindle,
            block.n,
            block.line,
            0,
            "feed per revolution needs a running spindle with a programmed speed S and a \
             feed F above zero",
        )),
    }
}

/// Spindle speed (rpm) a feed per revolution was planned at (0 = feed per minute).
fn per_rev_nominal_rpm(block: &Block, rapid: bool) -> f64 {
    match block.feed {
        Feed::MmPerRev(_) if !rapid => block.spindle.per_rev_nominal_rpm().unwrap_or(0.0),
        _ => 0.0,
    }
}

/// Classification of a finalized junction for the preview and the API (SPEC §7.5).
fn junction_of(planned_stop: bool, smooth: bool, cap: f64, drop: f64, seg: &Segment) -> Junction {
    if planned_stop {
        // Still a G23 junction for the preview: a speed drop (to rest).
        Junction::SpeedDrop
    } else if !smooth {
        Junction::Stop
    } else if cap < drop * seg.feed_mm_s {
        Junction::SpeedDrop
    } else {
        Junction::Smooth
    }
}

/// Angle between two directions over the first three axes, rad (0 when either has no
/// component there: motion of further axes only never breaks continuity by angle).
fn angle_first3(a: &AxesMm, b: &AxesMm) -> f64 {
    let mut a3 = AxesMm::ZERO;
    let mut b3 = AxesMm::ZERO;
    a3.0[..3].copy_from_slice(&a.0[..3]);
    b3.0[..3].copy_from_slice(&b.0[..3]);
    let (na, nb) = (a3.norm(3), b3.norm(3));
    if na < 1e-12 || nb < 1e-12 {
        return 0.0;
    }
    angle_between(&(a3 * (1.0 / na)), &(b3 * (1.0 / nb)))
}

/// Angle between two unit vectors, rad.
fn angle_between(a: &AxesMm, b: &AxesMm) -> f64 {
    let dot: f64 = a.0.iter().zip(b.0.iter()).map(|(x, y)| x * y).sum();
    dot.clamp(-1.0, 1.0).acos()
}

/// A motion block's ends must be numbers on every axis.
fn check_finite(
    block: &Block,
    start: &AxesMm,
    end: &AxesMm,
    axes: usize,
) -> Result<(), Diagnostic> {
    if (0..axes).any(|i| !start[i].is_finite() || !end[i].is_finite()) {
        return Err(Diagnostic::error(
            DiagCode::NonFiniteCoordinate,
            block.n,
            block.line,
            0,
            "motion block with an invalid coordinate",
        ));
    }
    Ok(())
}
