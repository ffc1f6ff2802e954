//! The 4 ms interpolator: planned segments in, one setpoint per axis per tick out.
//!
//! Runs on the real-time thread, so it never allocates after [`Interpolator::new`] and does
//! bounded work per tick. It works in three stages, one module each (`raw`,
//! `jerk_filter`, `axis_filter`):
//!
//! 1. **Raw path speed**, chosen online each tick from the limits the planner attached to each
//!    [`Segment`] (acceleration-limited):
//!    - hard limits (geometry and axis ceilings, the planner's safe end speeds, and a stop at
//!      the end of what has been received) are braked for and never exceeded;
//!    - soft limits (programmed feed × override) are approached within the acceleration
//!      limit, so an override change never makes a speed step.
//!
//!    Speeds are per-tick averages: the raw arc length advances by `v·Ts` each tick, across
//!    as many segments as that distance covers (several short blocks per tick).
//! 2. **Jerk filter** (parabolic profile, SPEC §7.3): the commanded arc length is the moving
//!    average of the last `m` raw arc lengths. The average of an acceleration-limited motion
//!    over `m` ticks has acceleration ≤ a and jerk (a(n) − a(n−m))/(m·Ts); the raw stage keeps
//!    a coast gap of `m` ticks between accelerating and braking (`jerk_filter`), so
//!    `m = ⌈a/(J·Ts)⌉` gives the ideal jerk-limited (S-shaped) speed. Filtering the *arc length* (not the axes) keeps every
//!    setpoint exactly on the programmed path, and because arc length never decreases the
//!    filtered position never passes the raw one: stop points are reached exactly, at rest.
//!    The filtered speed is an average of raw speeds of the last `m` ticks, so the raw speed
//!    respects every speed cap `m+1` ticks early (caps are met `c·(m+1)·Ts` before the
//!    junction) and late (the caps of the last `m+1` ticks still hold; with the axis filter
//!    below, `m+1+2n` ticks). With `m = 1` (linear
//!    profile) both stages coincide.
//!
//! 3. **Axis smoothing filter** (parabolic profile only): the setpoints are the on-path
//!    positions averaged twice over the last `n` ticks (`Segment::axis_filter_ticks`). Where
//!    the path turns (a smooth corner, a line entering an arc) the axis velocities change
//!    direction within one tick; the double average spreads that change over 2n ticks, so the
//!    per-axis jerk stays bounded. The planner limits the speed at such turns so that the
//!    jerk, the acceleration and the distance from the programmed corner stay within their
//!    shares (`plan::criteria::FilterWindow`). On straight lines the average of points on the
//!    line is on the line; at rest the filter settles exactly on the stop point (the average is
//!    taken as offsets from the newest input, which are all zero there), and a stop point is
//!    left only after it has settled and, jerk-limited, the setpoints' last two steps are 0.
//!
//! A late tick of the real-time thread never makes a setpoint jump: one call is one Ts of
//! trajectory, however late it comes.

use crate::block::Spindle;
use crate::plan::Segment;
use crate::units::{AxesMm, TS_S};

mod ahead;
mod axis_filter;
mod jerk_box;
mod jerk_filter;
mod piecewise;
mod raw;
mod setpoint_box;

use ahead::{Ahead, AheadGroup, GROUP};

pub use jerk_filter::ideal_jerk_limited_move_s;

/// How many segments the interpolator holds (its own look-ahead for braking, plus the
/// segments the filtered position has not yet left).
pub const BUFFER_SEGMENTS: usize = 4096;
const _: () = assert!(BUFFER_SEGMENTS.is_power_of_two());

/// Longest jerk filter, ticks (1.024 s: a/J up to 0.5 s).
pub const FILTER_MAX_TICKS: usize = 256;

/// Longest axis smoothing filter, ticks per stage.
pub const AXIS_FILTER_MAX_TICKS: usize = crate::plan::AXIS_FILTER_MAX_TICKS;

/// Segments looked at (from rest) for the highest speed the jerk filter is sized for; with
/// more buffered before the next stop the filter is sized for the full acceleration.
const FILTER_SCAN_SEGMENTS: usize = 256;

/// Remaining distance under which a point counts as reached.
const ARRIVE_EPS_MM: f64 = 1e-9;

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum InterpState {
    /// Nothing to do.
    #[default]
    Idle,
    /// Following the path.
    Running,
    /// Feed hold requested: braking to rest on the path.
    Holding,
    /// At rest on the path after a feed hold; `resume` continues.
    Held,
    /// Stop requested: braking to rest, then the remaining segments are dropped.
    Stopping,
}

/// What one tick produced.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TickOut {
    /// Commanded position of every axis.
    pub position: AxesMm,
    /// Path speed over this tick, mm/s.
    pub path_v_mm_s: f64,
    /// Source block (index, `N`, line) of the segment the position lies on.
    pub seq: u32,
    pub n: Option<u32>,
    pub line: u32,
    pub state: InterpState,
    /// The last segment of a program was completed in this tick.
    pub program_end: bool,
    /// Spindle state and G0 flag of that segment (for constant cutting speed, SPEC §6).
    pub spindle: Spindle,
    pub rapid: bool,
}

pub struct Interpolator {
    /// Axes in use (the first `axes` entries of every position).
    axes: usize,
    /// Ring of buffered segments (`head`, `len`).
    buf: Box<[Segment]>,
    /// What the look-ahead reads of each buffered segment, by ring slot, and its bounds per
    /// group of `GROUP` slots (`ahead`).
    /// (Arrays of their fixed length: the walks index them without bounds checks.)
    ahead: Box<[Ahead; BUFFER_SEGMENTS]>,
    /// What the per-axis box reads of each buffered segment besides that (`setpoint_box`).
    box_slots: Box<[setpoint_box::BoxSlot; BUFFER_SEGMENTS]>,
    /// What the jerk-limited box reads of each buffered segment (`jerk_box`).
    jbox_slots: Box<[jerk_box::JerkSlot; BUFFER_SEGMENTS]>,
    groups: Box<[AheadGroup]>,
    /// Arc length (from the first buffered segment after the last reset) at each segment start.
    seg_start_s_mm: Box<[f64]>,
    /// Oldest buffered segment: the one the commanded (filtered) position lies on.
    head: usize,
    /// Buffered segments.
    len: usize,
    /// Arc length at the end of the newest buffered segment.
    buffered_end_s_mm: f64,
    // Raw stage (`raw`).
    /// Raw segment, as an offset from `head`.
    raw_seg: usize,
    /// Distance travelled on the raw segment, mm.
    raw_in_seg_mm: f64,
    /// Raw path speed over the last tick, mm/s.
    raw_v_mm_s: f64,
    /// The raw position rests at the end of segment `raw_seg`, a stop point.
    raw_at_stop: bool,
    /// The last raw step stayed inside segment `raw_seg` (it crossed and reached no
    /// junction): the next tick's second difference has no turn if its step stays inside
    /// too (`Segment::free_accel_mm_s2`).
    raw_step_inside: bool,
    /// The last tick ended exactly on a junction: its cap holds for the next tick too (the
    /// velocity turns between these two ticks).
    entry_cap_mm_s: f64,
    /// Ticks still to wait (G4 dwell) before the raw position moves on.
    dwell_ticks: u32,
    // Jerk filter stage (`jerk_filter`).
    /// Length `m` of the jerk filter, ticks (1: none).
    jerk_filter_ticks: usize,
    /// Ring of the last raw arc lengths, mm, and of the hard and feed caps met in those
    /// ticks, mm/s; `hist_newest` is this tick's entry.
    hist_raw_s_mm: Box<[f64]>,
    hist_cap_mm_s: Box<[f64]>,
    hist_feed_mm_s: Box<[f64]>,
    /// The ring slot of the segment each raw arc length lay on (`jerk_box`).
    hist_raw_slot: Box<[usize]>,
    hist_newest: usize,
    /// Consecutive ticks without raw motion.
    still_ticks: usize,
    /// Ticks since the last tick whose raw acceleration was positive (0: the newest).
    ticks_since_accel: usize,
    /// Smallest path acceleration (feed or stop) and jerk of the buffered segments, for the
    /// look-ahead reach (sliding-window minima: O(1) per segment, no rescan of the buffer).
    floor_accel_mm_s2: Floor,
    floor_jerk_mm_s3: Floor,
    /// Commanded (filtered) arc length, mm, and its speed over the last tick, mm/s.
    filtered_s_mm: f64,
    filtered_v_mm_s: f64,
    /// Commanded point on the path (input of the axis filter).
    path_pos: AxesMm,
    // Axis smoothing filter (`axis_filter`): ticks per stage (`n`), and rings of the last
    // inputs of both stages (`axis_newest` is this tick's entry).
    axis_window_ticks: usize,
    axis_hist_in: Box<[AxesMm]>,
    axis_hist_mid: Box<[AxesMm]>,
    axis_newest: usize,
    /// The setpoints' last two steps (newest first): a jerk-limited departure from a stop
    /// waits until they are 0 on every axis it moves (`departure_adds_no_jerk`).
    sent_steps: [AxesMm; 2],
    /// The last three setpoints sent, newest first (the jerk-limited box's track).
    sent_points: [AxesMm; 3],
    /// Setpoints sent to the drives (output of the axis filter).
    position: AxesMm,
    state: InterpState,
    /// Feed override as a factor (1.0 = 100 %).
    override_factor: f64,
    /// Rapid override (0..1) on G0 segments, on top of the feed override.
    rapid_factor: f64,
    /// Actual spindle speed for feed per revolution, rpm (∞: no spindle feedback, planned
    /// feed), see [`Interpolator::set_spindle_feed_rpm`].
    spindle_feed_rpm: f64,
    in_position: bool,
    spindle_ready: bool,
    /// Spindle state of the last tick's output (what `spindle_ready` was judged against).
    reported_spindle: Spindle,
    /// This tick a cut waited for the spindle to be at speed.
    spindle_wait: bool,
    /// The inputs a block waits for (its M functions' confirmations) read 1, judged by the
    /// daemon on the state it was last given (`set_inputs_confirmed`).
    inputs_confirmed: bool,
    /// This tick a block waited for its inputs.
    inputs_wait: bool,
    last_seq: u32,
    last_n: Option<u32>,
    last_spindle: Spindle,
    last_rapid: bool,
    last_line: u32,
    /// M1 stops the program (operator switch "optional stop").
    optional_stop: bool,
    /// Held at a program stop (M0/M1) rather than by a feed hold.
    at_program_stop: bool,
    /// The tool of the tool change (M6) held at, while `at_program_stop`.
    tool_change: Option<u8>,
    /// Single-block mode (`single_block`): the path stops at rest at the end of every block.
    single_block: bool,
    /// Held at the end of a block in single-block mode.
    at_block_stop: bool,
    /// The stop point the raw position rests at has had its single-block (or program) stop.
    block_stop_done: bool,
    /// A block end ahead within the buffer is a stop point for single block (no scan needed
    /// until the raw position leaves the next stop point).
    block_stop_armed: bool,
    /// Work space of the piecewise braking curve (`piecewise`): the window of accelerations
    /// (segment, end distance, acceleration) and the points of E within one tick (end
    /// distance, E, acceleration).
    pw_deque: Box<[(f64, f64)]>,
    pw_points: Box<[(f64, f64, f64)]>,
    /// Upper bounds of E after each segment of the piecewise walk, and the segments'
    /// accelerations (`piecewise_upper`).
    pw_hi: Box<[f64; piecewise::PIECEWISE_CAPS]>,
    pw_own: Box<[f64; piecewise::PIECEWISE_CAPS]>,
    // The per-axis box on the setpoints (`setpoint_box`).
    /// The box chooses the raw steps (until it hands back to the envelope or rests).
    box_mode: bool,
    /// The setpoint sent a tick before the last one (the last is `path_pos`).
    box_prev_point: AxesMm,
    /// The junction the raw position lies on (`OnJunction::NONE`: none), noted after each
    /// raw step while the segment before is still buffered.
    box_on: setpoint_box::OnJunction,
    /// Each axis's room for the second difference of its setpoints this tick, mm, and the
    /// norm of those rooms (`setpoint_box::note_box_room`).
    box_room: [f64; crate::units::MAX_AXES],
    box_room_norm: f64,
    /// The braking of the last accepted proof (`setpoint_box::Plan`), and the setpoints of
    /// the brakings proofs write (three regions of `setpoint_box::PLAN_SLOTS`).
    box_plan: setpoint_box::Plan,
    box_paths: Box<[f64]>,
    /// This tick's choice of the box, while the envelope is computed to see whether it takes
    /// over (`box_hand_back`).
    box_pending: Option<setpoint_box::Choice>,
    /// The box arrived at a plain stop point this tick: the next may leave it at once
    /// (`setpoint_box::box_step`).
    box_departs: bool,
    /// Where the box's search guesses, as a fraction of the way from the nearest setpoint to
    /// the farthest (`setpoint_box::box_search`).
    box_guess: f64,
    // The jerk-limited box (`jerk_box`, parabolic profile).
    /// The box handed the motion to the envelope at rest at arc length `jbox_refused_s`
    /// (until the envelope comes to rest elsewhere).
    jbox_refused: bool,
    jbox_refused_s: f64,
    /// The jerk filter was set to one tick for the box (`resize_filters_at_rest`): the
    /// envelope may not run with it.
    jbox_filter_out: bool,
    /// Ticks at rest with a step wanted and none proven.
    jbox_idle_ticks: u32,
    /// Where the box's search guesses (`jerk_box::jbox_search`).
    jbox_guess: f64,
    /// Where the braking of the last accepted proof rests, mm of arc length.
    jbox_rest_s: f64,
    /// Each axis's room for the second and third differences of its setpoints, mm (with
    /// the rounding slack).
    jbox_axis_room: [(f64, f64); crate::units::MAX_AXES],
    /// The stop point ahead as last found (`jerk_box::StopAhead`).
    jbox_stop: jerk_box::StopAhead,
    /// The stop point ahead of the raw position this tick, mm of arc length.
    jbox_stop_mm: f64,
    /// The limits of the box's brakings, from the segment the motion left rest on.
    jbox_brake: jerk_box::PathLimits,
    /// The share of those the last accepted proof's braking was proven with.
    jbox_brake_share: f64,
    /// The bounds that leave the piecewise walk early are used (tests turn them off to
    /// compare: the trajectory must be the same).
    pw_bounds: bool,
    /// Walks the bounds left early, and groups whose caps they skipped (tests).
    #[cfg(test)]
    pw_stats: (usize, usize),
}

impl Interpolator {
    pub fn new(axes: usize, position: AxesMm) -> Self {
        Interpolator {
            axes,
            buf: vec![Segment::default(); BUFFER_SEGMENTS].into_boxed_slice(),
            // (Built on the heap: a 320 kB array would pass through the stack.)
            ahead: vec![Ahead::default(); BUFFER_SEGMENTS]
                .into_boxed_slice()
                .try_into()
                .expect("BUFFER_SEGMENTS slots"),
            box_slots: vec![setpoint_box::BoxSlot::default(); BUFFER_SEGMENTS]
                .into_boxed_slice()
                .try_into()
                .expect("BUFFER_SEGMENTS slots"),
            jbox_slots: vec![jerk_box::JerkSlot::default(); BUFFER_SEGMENTS]
                .into_boxed_slice()
                .try_into()
                .expect("BUFFER_SEGMENTS slots"),
            groups: vec![AheadGroup::NONE; BUFFER_SEGMENTS / GROUP].into_boxed_slice(),
            seg_start_s_mm: vec![0.0; BUFFER_SEGMENTS].into_boxed_slice(),
            head: 0,
            len: 0,
            buffered_end_s_mm: 0.0,
            raw_seg: 0,
            raw_in_seg_mm: 0.0,
            raw_v_mm_s: 0.0,
            raw_at_stop: false,
            raw_step_inside: false,
            entry_cap_mm_s: f64::INFINITY,
            dwell_ticks: 0,
            jerk_filter_ticks: 1,
            hist_raw_s_mm: vec![0.0; FILTER_MAX_TICKS].into_boxed_slice(),
            hist_cap_mm_s: vec![f64::INFINITY; FILTER_MAX_TICKS].into_boxed_slice(),
            hist_feed_mm_s: vec![f64::INFINITY; FILTER_MAX_TICKS].into_boxed_slice(),
            hist_raw_slot: vec![0; FILTER_MAX_TICKS].into_boxed_slice(),
            hist_newest: 0,
            still_ticks: FILTER_MAX_TICKS,
            ticks_since_accel: FILTER_MAX_TICKS,
            floor_accel_mm_s2: Floor::new(BUFFER_SEGMENTS),
            floor_jerk_mm_s3: Floor::new(BUFFER_SEGMENTS),
            filtered_s_mm: 0.0,
            filtered_v_mm_s: 0.0,
            path_pos: position,
            axis_window_ticks: 1,
            axis_hist_in: vec![position; AXIS_FILTER_MAX_TICKS].into_boxed_slice(),
            axis_hist_mid: vec![position; AXIS_FILTER_MAX_TICKS].into_boxed_slice(),
            axis_newest: 0,
            sent_steps: [AxesMm::ZERO; 2],
            sent_points: [position; 3],
            position,
            state: InterpState::Idle,
            override_factor: 1.0,
            rapid_factor: 1.0,
            spindle_feed_rpm: f64::INFINITY,
            in_position: true,
            spindle_ready: true,
            reported_spindle: Spindle::default(),
            spindle_wait: false,
            inputs_confirmed: true,
            inputs_wait: false,
            last_seq: 0,
            last_n: None,
            last_spindle: Spindle::default(),
            last_rapid: false,
            last_line: 0,
            optional_stop: false,
            at_program_stop: false,
            tool_change: None,
            single_block: false,
            at_block_stop: false,
            block_stop_done: false,
            block_stop_armed: false,
            pw_deque: vec![(0.0, 0.0); piecewise::PIECEWISE_SLOTS].into_boxed_slice(),
            pw_points: vec![(0.0, 0.0, 0.0); piecewise::PIECEWISE_SLOTS].into_boxed_slice(),
            pw_hi: Box::new([0.0; piecewise::PIECEWISE_CAPS]),
            pw_own: Box::new([0.0; piecewise::PIECEWISE_CAPS]),
            pw_bounds: true,
            box_mode: false,
            box_prev_point: position,
            box_on: setpoint_box::OnJunction::NONE,
            box_room: [0.0; crate::units::MAX_AXES],
            box_room_norm: 0.0,
            box_plan: setpoint_box::Plan::default(),
            box_paths: vec![0.0; 3 * setpoint_box::PLAN_SLOTS].into_boxed_slice(),
            box_pending: None,
            box_departs: false,
            box_guess: 0.5,
            jbox_refused: false,
            jbox_refused_s: 0.0,
            jbox_filter_out: false,
            jbox_idle_ticks: 0,
            jbox_guess: 0.5,
            jbox_rest_s: 0.0,
            jbox_stop_mm: 0.0,
            jbox_stop: jerk_box::StopAhead::default(),
            jbox_axis_room: [(0.0, 0.0); crate::units::MAX_AXES],
            jbox_brake: jerk_box::PathLimits::default(),
            jbox_brake_share: 1.0,
            #[cfg(test)]
            pw_stats: (0, 0),
        }
    }

    /// Path of the segment the commanded position lies on (`None` with nothing buffered): the
    /// programmed path a fault stop is measured against.
    pub fn current_path(&self) -> Option<crate::plan::SegPath> {
        (self.len > 0).then(|| self.seg(0).path)
    }

    /// The probing segment (`Segment::probe`) the raw position is on, or rests at the stop
    /// point before: the caller watches the probe while it runs and calls [`Self::stop`] at
    /// the change (it is the last segment buffered: the path after it is planned only once
    /// its result is known).
    pub fn probing_segment(&self) -> Option<&Segment> {
        if self.len == 0 {
            return None;
        }
        let here = self.seg(self.raw_seg);
        if here.probe.is_some() {
            return Some(here);
        }
        let next =
            (self.raw_at_stop && self.raw_seg + 1 < self.len).then(|| self.seg(self.raw_seg + 1));
        next.filter(|s| s.probe.is_some())
    }

    /// Operator switch "optional stop": M1 stops the program only while it is on.
    pub fn set_optional_stop(&mut self, on: bool) {
        self.optional_stop = on;
    }

    /// Held at rest at a program stop (M0, or M1 with optional stop on); `resume` continues.
    pub fn at_program_stop(&self) -> bool {
        self.at_program_stop
    }

    /// Held at a tool change (M6): the tool to put in the spindle (0 = none).
    pub fn tool_change(&self) -> Option<u8> {
        self.tool_change.filter(|_| self.at_program_stop)
    }

    /// Single-block mode: the path stops at rest exactly at the end of every block (the
    /// first block end it can still brake for when switched on while moving) and holds
    /// there; `resume` runs the next block. Off: look-ahead across blocks as planned.
    pub fn set_single_block(&mut self, on: bool) {
        self.single_block = on;
        if !on {
            self.block_stop_armed = false;
        }
    }

    /// Held at rest at the end of a block in single-block mode; `resume` continues. The
    /// tick's `seq`/`n`/`line` name the block just finished.
    pub fn at_block_stop(&self) -> bool {
        self.at_block_stop
    }

    pub fn axes(&self) -> usize {
        self.axes
    }

    pub fn position(&self) -> AxesMm {
        self.position
    }

    pub fn state(&self) -> InterpState {
        self.state
    }

    pub fn has_room(&self) -> bool {
        self.len < self.buf.len()
    }

    pub fn buffered(&self) -> usize {
        self.len
    }

    /// Length of the jerk filter in ticks now in use (1 = no filter).
    pub fn filter_ticks(&self) -> usize {
        self.jerk_filter_ticks
    }

    /// Appends a segment. Gives it back when the buffer is full or while stopping (the caller
    /// keeps it for the next tick, so the error carries the whole segment by design).
    ///
    /// A segment of zero length only carries a spindle state (technology blocks without
    /// motion): in force at once when nothing is buffered, else once the buffered path ends.
    #[allow(clippy::result_large_err)]
    pub fn push(&mut self, seg: Segment) -> Result<(), Segment> {
        let empty = seg.length_mm.is_nan() || seg.length_mm <= 0.0;
        if !self.has_room() || self.state == InterpState::Stopping || seg.length_mm.is_nan() {
            return Err(seg);
        }
        if empty {
            self.push_empty(&seg);
            return Ok(());
        }
        let i = (self.head + self.len) % BUFFER_SEGMENTS;
        if self.len == 0 {
            // The raw position starts at this segment: wait its leading dwell there.
            self.dwell_ticks = (seg.dwell_before_s / TS_S).round().max(0.0) as u32;
            // Its spindle state is in force from now on, before the motion starts: a
            // spindle started ahead of the first cut runs up while the axes wait.
            self.last_spindle = seg.spindle;
        }
        self.buf[i] = seg;
        self.floor_accel_mm_s2
            .add(seg.accel_mm_s2.min(seg.stop_accel_mm_s2));
        self.floor_jerk_mm_s3.add(seg.jerk_mm_s3);
        self.seg_start_s_mm[i] = self.buffered_end_s_mm;
        self.buffered_end_s_mm += seg.length_mm;
        self.len += 1;
        self.note_pushed(i);
        self.jbox_note_pushed();
        if self.state == InterpState::Idle {
            self.state = InterpState::Running;
        }
        Ok(())
    }

    /// A segment of zero length: its spindle state, and a program stop with no motion after
    /// it (held at once at rest, or at the end of the buffered path).
    fn push_empty(&mut self, seg: &Segment) {
        let stop = seg.program_stop.stronger(seg.program_stop_before);
        if self.len == 0 {
            self.last_spindle = seg.spindle;
            if matches!(self.state, InterpState::Idle | InterpState::Running)
                && self.stops_here(stop)
            {
                self.last_seq = seg.seq;
                self.last_n = seg.n;
                self.last_line = seg.line;
                self.hold_at_stop(stop);
                self.state = InterpState::Held;
            }
        } else {
            let i = (self.head + self.len - 1) % BUFFER_SEGMENTS;
            self.buf[i].spindle_after = Some(seg.spindle);
            self.buf[i].program_stop = self.buf[i].program_stop.stronger(stop);
        }
    }

    /// A new job starts: the block the last one ended in is no longer the one in progress,
    /// so the ticks name no block until the new job's first segment is followed (the
    /// status must not show the last job's block as the new one's). Only when idle with
    /// nothing buffered.
    pub fn forget_block(&mut self) {
        if self.state == InterpState::Idle && self.len == 0 {
            self.last_seq = 0;
            self.last_n = None;
            self.last_line = 0;
        }
    }

    /// Feed override in percent, clamped to 0..=150.
    pub fn set_override(&mut self, percent: f64) {
        let p = if percent.is_finite() { percent } else { 0.0 };
        self.override_factor = p.clamp(0.0, 150.0) / 100.0;
    }

    /// Rapid override in percent, clamped to 0..=100: scales the speed of G0 segments (on top
    /// of the feed override). Like the feed override it is a soft limit of the path speed,
    /// approached within the acceleration limit: the path and the axis limits hold, no step.
    pub fn set_rapid_override(&mut self, percent: f64) {
        let p = if percent.is_finite() { percent } else { 0.0 };
        self.rapid_factor = p.clamp(0.0, 100.0) / 100.0;
    }

    /// Actual spindle speed (rpm, ≥ 0) that feed per revolution follows (SPEC §5: V = n·β).
    /// The daemon calls this every tick with the drive's feedback (0 when the spindle is below
    /// its hold threshold or turns the wrong way; ∞ without spindle feedback). A per-rev
    /// segment's feed is scaled by actual / nominal, capped at 1 so the planned limits hold;
    /// like the override it is a soft limit, approached within the acceleration limit.
    pub fn set_spindle_feed_rpm(&mut self, rpm: f64) {
        self.spindle_feed_rpm = if rpm.is_nan() { 0.0 } else { rpm.max(0.0) };
    }

    /// Whether the following error is below the G24 limit R06-R07 (SPEC §7.1). The daemon
    /// calls this every tick; a G24 stop point is left only while it is true.
    pub fn set_in_position(&mut self, in_position: bool) {
        self.in_position = in_position;
    }

    /// Whether the spindle runs at its commanded speed. The daemon calls this every tick; a
    /// feed move does not start from rest while it is false (rapids do), so the first cut
    /// after `M3 S..` waits for the spindle to run up.
    pub fn set_spindle_ready(&mut self, ready: bool) {
        self.spindle_ready = ready;
    }

    /// Whether every input the block about to start waits for
    /// (`TickOut::spindle.outputs.wait`) reads 1. The daemon calls this every tick; a block
    /// with such inputs does not start from rest while it is false (docs/io.md).
    pub fn set_inputs_confirmed(&mut self, confirmed: bool) {
        self.inputs_confirmed = confirmed;
    }

    /// A block is waiting at rest for the inputs its M functions wait for.
    pub fn waiting_for_inputs(&self) -> bool {
        self.inputs_wait
    }

    /// A cut is waiting for the spindle: at rest for it to be at speed, or a feed per
    /// revolution held by a spindle below its hold threshold (shown in the status).
    pub fn waiting_for_spindle(&self) -> bool {
        self.spindle_wait
    }

    /// Feed hold: brakes to rest on the path; or, when no segment has arrived yet (a job just
    /// started, its first segment still being planned), holds at the start: segments pushed
    /// meanwhile wait, and the motion begins only on `resume`. A hold is never lost.
    pub fn hold(&mut self) {
        match self.state {
            InterpState::Running => self.state = InterpState::Holding,
            InterpState::Idle => self.state = InterpState::Held,
            _ => {}
        }
    }

    pub fn resume(&mut self) {
        self.at_program_stop = false;
        self.tool_change = None;
        self.at_block_stop = false;
        if matches!(self.state, InterpState::Holding | InterpState::Held) {
            self.state = if self.len > 0 {
                InterpState::Running
            } else {
                InterpState::Idle
            };
        }
    }

    /// Brakes to rest on the path with the stop deceleration, then drops every segment.
    pub fn stop(&mut self) {
        match self.state {
            InterpState::Idle => {}
            InterpState::Held => self.clear(),
            _ => self.state = InterpState::Stopping,
        }
    }

    /// Takes `position` as the commanded position; only when idle with nothing buffered
    /// (returns false otherwise). After a fault the drives may have come to rest elsewhere:
    /// re-enabling them at the old setpoint would make them jump.
    pub fn set_position(&mut self, position: AxesMm) -> bool {
        if self.state != InterpState::Idle || self.len > 0 {
            return false;
        }
        self.clear();
        self.position = position;
        self.path_pos = position;
        self.box_prev_point = position;
        self.sent_points = [position; 3];
        self.axis_hist_in.fill(position);
        self.axis_hist_mid.fill(position);
        true
    }

    /// Length of the axis smoothing filter now in use, ticks per stage (1 = none).
    pub fn axis_filter_ticks(&self) -> usize {
        self.axis_window_ticks
    }

    fn clear(&mut self) {
        self.at_program_stop = false;
        self.tool_change = None;
        self.at_block_stop = false;
        self.block_stop_done = false;
        self.block_stop_armed = false;
        self.len = 0;
        self.floor_accel_mm_s2.clear();
        self.floor_jerk_mm_s3.clear();
        self.reset_arc_length();
        self.state = InterpState::Idle;
    }

    /// Restarts arc lengths at zero (only when nothing is buffered and the filter is at rest).
    fn reset_arc_length(&mut self) {
        self.buffered_end_s_mm = 0.0;
        self.raw_seg = 0;
        self.raw_in_seg_mm = 0.0;
        self.raw_v_mm_s = 0.0;
        self.raw_at_stop = false;
        self.entry_cap_mm_s = f64::INFINITY;
        self.dwell_ticks = 0;
        self.hist_raw_s_mm.fill(0.0);
        self.hist_cap_mm_s.fill(f64::INFINITY);
        self.hist_feed_mm_s.fill(f64::INFINITY);
        self.still_ticks = FILTER_MAX_TICKS;
        self.ticks_since_accel = FILTER_MAX_TICKS;
        self.filtered_s_mm = 0.0;
        self.filtered_v_mm_s = 0.0;
        self.box_mode = false;
        self.box_on = setpoint_box::OnJunction::NONE;
        self.jbox_refused = false;
        self.jbox_idle_ticks = 0;
        self.jbox_stop.valid = false;
    }

    fn idx(&self, k: usize) -> usize {
        // (A constant power of two: the look-ahead calls this for every segment it walks,
        // and a division by the slice length was a tenth of the tick.)
        (self.head + k) % BUFFER_SEGMENTS
    }

    fn seg(&self, k: usize) -> &Segment {
        &self.buf[self.idx(k)]
    }

    fn ceiling(&self, seg: &Segment) -> f64 {
        self.ceiling_of(&Ahead::of(seg))
    }

    fn ceiling_of(&self, seg: &Ahead) -> f64 {
        (self.feed_of_ahead(seg) * self.override_factor).min(seg.v_max_mm_s)
    }

    /// Programmed feed of a segment now: feed per revolution follows the actual spindle speed;
    /// a rapid runs at its rapid override's share of the speed the axes allow on it.
    fn feed_of(&self, seg: &Segment) -> f64 {
        self.feed_of_ahead(&Ahead::of(seg))
    }

    fn feed_of_ahead(&self, seg: &Ahead) -> f64 {
        if seg.rapid {
            seg.feed_mm_s.min(seg.v_max_mm_s) * self.rapid_factor
        } else if seg.per_rev_nominal_rpm > 0.0 {
            seg.feed_mm_s * (self.spindle_feed_rpm / seg.per_rev_nominal_rpm).min(1.0)
        } else {
            seg.feed_mm_s
        }
    }

    /// Both filters are at rest: the setpoint equals the raw position.
    fn settled(&self) -> bool {
        self.still_ticks + 1 >= self.jerk_filter_ticks && self.axis_settled()
    }

    /// Advances one tick.
    pub fn tick(&mut self) -> TickOut {
        let mut program_end = false;
        let mut path_v = 0.0;
        self.spindle_wait = false;
        self.inputs_wait = false;
        let sent_before = self.path_pos;
        let setpoint_before = self.position;
        if self.len > 0 {
            let (cap, feed) = if matches!(self.state, InterpState::Held | InterpState::Idle) {
                (f64::INFINITY, f64::INFINITY)
            } else {
                self.raw_step()
            };
            self.note_box_junction();
            self.record(cap, feed);
            program_end = self.follow();
            path_v = self.filtered_v_mm_s;
            self.smooth_axes();
            // (Resets the speed when the last segment has been left: report this tick's.)
            self.update_state();
        } else {
            self.filtered_v_mm_s = 0.0;
            self.smooth_axes();
        }
        self.box_prev_point = sent_before;
        self.sent_steps = [self.position - setpoint_before, self.sent_steps[0]];
        self.sent_points = [self.position, self.sent_points[0], self.sent_points[1]];
        self.reported_spindle = self.last_spindle;
        TickOut {
            position: self.position,
            path_v_mm_s: path_v,
            seq: self.last_seq,
            n: self.last_n,
            line: self.last_line,
            state: self.state,
            program_end,
            spindle: self.last_spindle,
            rapid: self.last_rapid,
        }
    }

    fn update_state(&mut self) {
        let rest = self.raw_v_mm_s == 0.0 && self.settled();
        match self.state {
            InterpState::Holding if rest => self.state = InterpState::Held,
            InterpState::Stopping if rest => self.clear(),
            _ => {}
        }
        if self.len == 0 && self.state != InterpState::Held {
            self.state = InterpState::Idle;
            self.reset_arc_length();
        }
    }
}

/// Smallest value over the buffered segments (a FIFO window: segments enter at the back and
/// leave at the front), as a monotonic queue of (value, how many segments of the window with
/// that value no smaller later one has replaced). Entering is amortized O(1) (at most the
/// queue's length once), leaving O(1): the tick never rescans the buffer (the rescan of all
/// buffered segments each time the last holder of the floor left cost up to 4096 steps in
/// one tick). Fixed capacity, allocated in `new`.
#[derive(Clone, Debug)]
struct Floor {
    runs: Box<[(f64, usize)]>,
    front: usize,
    len: usize,
}

impl Floor {
    fn new(capacity: usize) -> Self {
        Floor {
            runs: vec![(f64::INFINITY, 0); capacity].into_boxed_slice(),
            front: 0,
            len: 0,
        }
    }

    fn slot(&self, k: usize) -> usize {
        (self.front + k) % self.runs.len()
    }

    fn value(&self) -> f64 {
        if self.len == 0 {
            f64::INFINITY
        } else {
            self.runs[self.front].0
        }
    }

    /// A segment of value `v` enters the window.
    fn add(&mut self, v: f64) {
        while self.len > 0 && self.runs[self.slot(self.len - 1)].0 > v {
            self.len -= 1;
        }
        if self.len > 0 && self.runs[self.slot(self.len - 1)].0 == v {
            let last = self.slot(self.len - 1);
            self.runs[last].1 += 1;
        } else if self.len < self.runs.len() {
            let next = self.slot(self.len);
            self.runs[next] = (v, 1);
            self.len += 1;
        }
    }

    /// The oldest segment of the window, of value `v`, leaves it.
    fn remove(&mut self, v: f64) {
        if self.len > 0 && self.runs[self.front].0 == v {
            self.runs[self.front].1 -= 1;
            if self.runs[self.front].1 == 0 {
                self.front = self.slot(1);
                self.len -= 1;
            }
        }
    }

    fn clear(&mut self) {
        self.front = 0;
        self.len = 0;
    }
}

#[cfg(test)]
mod tests;
