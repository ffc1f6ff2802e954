//! The 4 ms interpolator: planned segments in, one setpoint per axis per tick out.
//!
//! Runs on the real-time thread, so it never allocates after [`Interpolator::new`] and does
//! bounded work per tick. It works in two stages:
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
//!    over `m` ticks has acceleration ≤ a and jerk ≤ 2a/(m·Ts), so `m = ⌈2a/(J·Ts)⌉` gives a
//!    jerk-limited (S-shaped) speed. Filtering the *arc length* (not the axes) keeps every
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
//!    left only after it has settled.
//!
//! A late tick of the real-time thread never makes a setpoint jump: one call is one Ts of
//! trajectory, however late it comes.

use crate::block::{ProgramStop, Spindle};
use crate::plan::Segment;
use crate::units::{AxesMm, TS_S};

/// How many segments the interpolator holds (its own look-ahead for braking, plus the
/// segments the filtered position has not yet left).
pub const BUFFER_SEGMENTS: usize = 4096;

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
    axes: usize,
    buf: Box<[Segment]>,
    /// Arc length (from the first buffered segment after the last reset) at each segment start.
    s0: Box<[f64]>,
    /// Oldest buffered segment: the one the commanded (filtered) position lies on.
    head: usize,
    len: usize,
    /// Arc length at the end of the newest buffered segment.
    s_end_mm: f64,
    // Raw stage.
    /// Raw segment, as an offset from `head`.
    rk: usize,
    /// Distance travelled on the raw segment, mm.
    rs_mm: f64,
    v_mm_s: f64,
    /// The raw position rests at the end of segment `rk`, a stop point.
    raw_at_stop: bool,
    /// The last tick ended exactly on a junction: its cap holds for the next tick too (the
    /// velocity turns between these two ticks).
    entry_cap_mm_s: f64,
    dwell_ticks: u32,
    // Filter stage.
    m: usize,
    hist_s: Box<[f64]>,
    hist_cap: Box<[f64]>,
    hist_feed: Box<[f64]>,
    hist_pos: usize,
    /// Consecutive ticks without raw motion.
    still: usize,
    /// Smallest path acceleration (feed or stop) and jerk of the buffered segments, for the
    /// look-ahead reach; recomputed when the last segment at a floor value leaves.
    floor_accel: Floor,
    floor_jerk: Floor,
    floor_dirty: bool,
    f_s_mm: f64,
    f_v_mm_s: f64,
    /// Commanded point on the path (input of the axis filter).
    path_pos: AxesMm,
    // Axis smoothing filter: ticks per stage, and the last inputs of both stages.
    axis_n: usize,
    axis_in: Box<[AxesMm]>,
    axis_mid: Box<[AxesMm]>,
    axis_pos: usize,
    /// Setpoints sent to the drives (output of the axis filter).
    position: AxesMm,
    state: InterpState,
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
    last_seq: u32,
    last_n: Option<u32>,
    last_spindle: Spindle,
    last_rapid: bool,
    last_line: u32,
    /// M1 stops the program (operator switch "optional stop").
    optional_stop: bool,
    /// Held at a program stop (M0/M1) rather than by a feed hold.
    at_program_stop: bool,
}

impl Interpolator {
    pub fn new(axes: usize, position: AxesMm) -> Self {
        Interpolator {
            axes,
            buf: vec![Segment::default(); BUFFER_SEGMENTS].into_boxed_slice(),
            s0: vec![0.0; BUFFER_SEGMENTS].into_boxed_slice(),
            head: 0,
            len: 0,
            s_end_mm: 0.0,
            rk: 0,
            rs_mm: 0.0,
            v_mm_s: 0.0,
            raw_at_stop: false,
            entry_cap_mm_s: f64::INFINITY,
            dwell_ticks: 0,
            m: 1,
            hist_s: vec![0.0; FILTER_MAX_TICKS].into_boxed_slice(),
            hist_cap: vec![f64::INFINITY; FILTER_MAX_TICKS].into_boxed_slice(),
            hist_feed: vec![f64::INFINITY; FILTER_MAX_TICKS].into_boxed_slice(),
            hist_pos: 0,
            still: FILTER_MAX_TICKS,
            floor_accel: Floor::default(),
            floor_jerk: Floor::default(),
            floor_dirty: false,
            f_s_mm: 0.0,
            f_v_mm_s: 0.0,
            path_pos: position,
            axis_n: 1,
            axis_in: vec![position; AXIS_FILTER_MAX_TICKS].into_boxed_slice(),
            axis_mid: vec![position; AXIS_FILTER_MAX_TICKS].into_boxed_slice(),
            axis_pos: 0,
            position,
            state: InterpState::Idle,
            override_factor: 1.0,
            rapid_factor: 1.0,
            spindle_feed_rpm: f64::INFINITY,
            in_position: true,
            spindle_ready: true,
            reported_spindle: Spindle::default(),
            spindle_wait: false,
            last_seq: 0,
            last_n: None,
            last_spindle: Spindle::default(),
            last_rapid: false,
            last_line: 0,
            optional_stop: false,
            at_program_stop: false,
        }
    }

    /// Path of the segment the commanded position lies on (`None` with nothing buffered): the
    /// programmed path a fault stop is measured against.
    pub fn current_path(&self) -> Option<crate::plan::SegPath> {
        (self.len > 0).then(|| self.seg(0).path)
    }

    /// Operator switch "optional stop": M1 stops the program only while it is on.
    pub fn set_optional_stop(&mut self, on: bool) {
        self.optional_stop = on;
    }

    /// Held at rest at a program stop (M0, or M1 with optional stop on); `resume` continues.
    pub fn at_program_stop(&self) -> bool {
        self.at_program_stop
    }

    fn stops_here(&self, stop: ProgramStop) -> bool {
        match stop {
            ProgramStop::None => false,
            ProgramStop::Always => true,
            ProgramStop::Optional => self.optional_stop,
        }
    }

    /// At rest between segment `rk` and the next: holds if a program stop (M0/M1) is due
    /// there. Each stop is honoured once (cleared in the buffer).
    fn program_stop_at(&mut self, before_next: bool) -> bool {
        if self.state != InterpState::Running {
            return false;
        }
        let here = self.idx(self.rk);
        let due_after = before_next && self.stops_here(self.buf[here].program_stop);
        let next = if before_next {
            self.idx(self.rk + 1)
        } else {
            here
        };
        let due_before = self.stops_here(self.buf[next].program_stop_before);
        if !(due_after || due_before) {
            return false;
        }
        if before_next {
            self.buf[here].program_stop = ProgramStop::None;
        }
        self.buf[next].program_stop_before = ProgramStop::None;
        self.state = InterpState::Holding;
        self.at_program_stop = true;
        true
    }

    /// At rest at the end of the last buffered segment: holds if a program stop is due after
    /// it. The segment stays buffered until Resume, so the job does not end at the stop.
    fn program_stop_after_last(&mut self) {
        let here = self.idx(self.rk);
        if self.state != InterpState::Running || !self.stops_here(self.buf[here].program_stop) {
            return;
        }
        self.buf[here].program_stop = ProgramStop::None;
        self.state = InterpState::Holding;
        self.at_program_stop = true;
    }

    /// The last buffered segment may be dropped once the raw position rests at its end: not
    /// while a program stop after it is due or held (a plain feed hold lets it go as before).
    fn last_may_leave(&self, seg: &Segment) -> bool {
        !self.at_program_stop && !self.stops_here(seg.program_stop)
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
        self.m
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
            if self.len == 0 {
                self.last_spindle = seg.spindle;
            } else {
                let i = (self.head + self.len - 1) % self.buf.len();
                self.buf[i].spindle_after = Some(seg.spindle);
            }
            return Ok(());
        }
        let i = (self.head + self.len) % self.buf.len();
        if self.len == 0 {
            // The raw position starts at this segment: wait its leading dwell there.
            self.dwell_ticks = (seg.dwell_before_s / TS_S).round().max(0.0) as u32;
            // Its spindle state is in force from now on, before the motion starts: a
            // spindle started ahead of the first cut runs up while the axes wait.
            self.last_spindle = seg.spindle;
        }
        self.buf[i] = seg;
        self.floor_accel
            .add(seg.accel_mm_s2.min(seg.stop_accel_mm_s2));
        self.floor_jerk.add(seg.jerk_mm_s3);
        self.s0[i] = self.s_end_mm;
        self.s_end_mm += seg.length_mm;
        self.len += 1;
        if self.state == InterpState::Idle {
            self.state = InterpState::Running;
        }
        Ok(())
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

    /// A cut is waiting for the spindle: at rest for it to be at speed, or a feed per
    /// revolution held by a spindle below its hold threshold (shown in the status).
    pub fn waiting_for_spindle(&self) -> bool {
        self.spindle_wait
    }

    pub fn hold(&mut self) {
        if self.state == InterpState::Running {
            self.state = InterpState::Holding;
        }
    }

    pub fn resume(&mut self) {
        self.at_program_stop = false;
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
        self.axis_in.fill(position);
        self.axis_mid.fill(position);
        true
    }

    /// Length of the axis smoothing filter now in use, ticks per stage (1 = none).
    pub fn axis_filter_ticks(&self) -> usize {
        self.axis_n
    }

    fn clear(&mut self) {
        self.at_program_stop = false;
        self.len = 0;
        self.floor_dirty = true;
        self.reset_arc_length();
        self.state = InterpState::Idle;
    }

    /// Restarts arc lengths at zero (only when nothing is buffered and the filter is at rest).
    fn reset_arc_length(&mut self) {
        self.s_end_mm = 0.0;
        self.rk = 0;
        self.rs_mm = 0.0;
        self.v_mm_s = 0.0;
        self.raw_at_stop = false;
        self.entry_cap_mm_s = f64::INFINITY;
        self.dwell_ticks = 0;
        self.hist_s.fill(0.0);
        self.hist_cap.fill(f64::INFINITY);
        self.hist_feed.fill(f64::INFINITY);
        self.still = FILTER_MAX_TICKS;
        self.f_s_mm = 0.0;
        self.f_v_mm_s = 0.0;
    }

    fn idx(&self, k: usize) -> usize {
        (self.head + k) % self.buf.len()
    }

    fn seg(&self, k: usize) -> &Segment {
        &self.buf[self.idx(k)]
    }

    fn ceiling(&self, seg: &Segment) -> f64 {
        (self.feed_of(seg) * self.override_factor).min(seg.v_max_mm_s)
    }

    /// Programmed feed of a segment now: feed per revolution follows the actual spindle speed;
    /// a rapid runs at its rapid override's share of the speed the axes allow on it.
    fn feed_of(&self, seg: &Segment) -> f64 {
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
        self.still + 1 >= self.m && self.axis_settled()
    }

    fn axis_settled(&self) -> bool {
        if self.axis_n <= 1 {
            return true;
        }
        let p = self.path_pos;
        (0..self.axis_n).all(|j| {
            let i = (self.axis_pos + AXIS_FILTER_MAX_TICKS - j) % AXIS_FILTER_MAX_TICKS;
            self.axis_in[i] == p && self.axis_mid[i] == p
        })
    }

    /// Mean of the last `n` entries of `ring` ending at `pos`, as the newest entry plus the
    /// mean offset from it (exact when all entries are equal).
    fn ring_mean(ring: &[AxesMm], pos: usize, n: usize, axes: usize) -> AxesMm {
        let newest = ring[pos];
        let mut sum = AxesMm::ZERO;
        for j in 1..n {
            let e = &ring[(pos + AXIS_FILTER_MAX_TICKS - j) % AXIS_FILTER_MAX_TICKS];
            for a in 0..axes {
                sum.0[a] += e.0[a] - newest.0[a];
            }
        }
        let mut out = newest;
        for a in 0..axes {
            out.0[a] += sum.0[a] / n as f64;
        }
        out
    }

    /// Axis filter stage: the setpoint is the double moving average of the path positions.
    fn smooth_axes(&mut self) {
        if self.axis_n <= 1 {
            self.position = self.path_pos;
            return;
        }
        self.axis_pos = (self.axis_pos + 1) % AXIS_FILTER_MAX_TICKS;
        self.axis_in[self.axis_pos] = self.path_pos;
        let mid = Self::ring_mean(&self.axis_in, self.axis_pos, self.axis_n, self.axes);
        self.axis_mid[self.axis_pos] = mid;
        self.position = Self::ring_mean(&self.axis_mid, self.axis_pos, self.axis_n, self.axes);
    }

    fn raw_s(&self) -> f64 {
        if self.len == 0 {
            return self.s_end_mm;
        }
        self.s0[self.idx(self.rk)] + self.rs_mm
    }

    /// Filter length for the motion that starts at rest on segment `rk`: the raw acceleration
    /// steps by at most 2a, so the jerk of the average is ≤ 2a/(m·Ts) ≤ J. A motion that
    /// cannot reach `a` before its speed (the highest programmed speed up to the next stop,
    /// at 100 % override) is a pure parabola: it needs only a = √(v·J), so the filter is sized
    /// for that (the ramp to F takes 3·√(F/J) instead of 2a/J + F/a; the manual's
    /// T = 1.478·√(F/P) is 2·√(F/J)).
    fn filter_for(&self) -> usize {
        let seg = self.seg(self.rk);
        let a = seg.accel_mm_s2.max(seg.stop_accel_mm_s2);
        let j = seg.jerk_mm_s3;
        if !j.is_finite() || j <= 0.0 {
            return 1;
        }
        // (Segments that arrive later are followed at the acceleration this filter allows:
        // slower, never above the jerk.)
        let mut v = f64::INFINITY;
        let mut top = 0.0f64;
        for k in self.rk..self.len.min(self.rk + FILTER_SCAN_SEGMENTS) {
            let s = self.seg(k);
            top = top.max(s.feed_mm_s.min(s.v_max_mm_s));
            if s.v_end_mm_s == 0.0 || k + 1 == self.len {
                v = top;
                break;
            }
        }
        let a = a.min((v * j).sqrt());
        ((2.0 * a / (j * TS_S)).ceil() as usize)
            .clamp(1, FILTER_MAX_TICKS - 2 * AXIS_FILTER_MAX_TICKS - 2)
    }

    /// Acceleration the raw stage may use with the current filter (jerk ≤ J needs a ≤ J·m·Ts/2).
    /// Lower bound of the raw acceleration on every buffered segment: a cap whose braking
    /// distance at this bound is out of reach cannot constrain this tick. (Judging the reach
    /// with the accelerations seen so far missed a stop behind a segment of lower
    /// acceleration and made the speed saw between braking harder than allowed and
    /// accelerating again.)
    fn accel_floor(&mut self) -> f64 {
        if self.floor_dirty {
            self.floor_accel = Floor::default();
            self.floor_jerk = Floor::default();
            for k in 0..self.len {
                let seg = &self.buf[(self.head + k) % self.buf.len()];
                self.floor_accel
                    .add(seg.accel_mm_s2.min(seg.stop_accel_mm_s2));
                self.floor_jerk.add(seg.jerk_mm_s3);
            }
            self.floor_dirty = false;
        }
        let (floor_a, floor_j) = (self.floor_accel.value, self.floor_jerk.value);
        let a = if floor_j.is_finite() {
            floor_a.min(floor_j * self.m as f64 * TS_S / 2.0)
        } else {
            floor_a
        };
        a.max(1e-6)
    }

    fn raw_accel(&self, a: f64, seg: &Segment) -> f64 {
        let a = if seg.jerk_mm_s3.is_finite() {
            a.min(seg.jerk_mm_s3 * self.m as f64 * TS_S / 2.0)
        } else {
            a
        };
        a.max(1e-6)
    }

    /// Highest speed for this tick from which the per-tick speeds, falling by u = a·Ts per
    /// tick, are down to `v_cap` when the path reaches the cap point `d` ahead. Exact in
    /// discrete time: the speeds before the point are v_cap + r + j·u (j = J..0, 0 < r ≤ u),
    /// covering Ts·((J+1)·(v_cap + r) + u·J(J+1)/2) ≤ d − v_cap·Ts. For a stop (v_cap = 0) they end exactly on it, so braking runs at the full
    /// deceleration and the last tick is the only one rounded (the continuous bound
    /// (v² − v_cap²)/(2a) ≤ d − v·Ts started braking half a tick early and crept at the end).
    fn v_brake(d: f64, v_cap: f64, a: f64) -> f64 {
        let u = a * TS_S;
        // The last tick before the point runs at v_cap and ends on it (the tick after the point
        // is held to the cap too, see `entry_cap_mm_s`): the faster ticks end one v_cap·Ts
        // earlier. Distances in speed·ticks.
        let dd = d.max(0.0) / TS_S - v_cap;
        // Distance of the J+1 ticks faster than v_cap with r = 0.
        let lower = |j: f64| (j + 1.0) * v_cap + u * j * (j + 1.0) / 2.0;
        if dd <= v_cap {
            return dd.max(0.0);
        }
        let b = v_cap + u / 2.0;
        let root = (-b + (b * b + 2.0 * u * (dd - v_cap)).sqrt()) / u;
        let mut j = (root.ceil() - 1.0).max(0.0);
        while j > 0.0 && lower(j) >= dd {
            j -= 1.0;
        }
        while lower(j + 1.0) < dd {
            j += 1.0;
        }
        let r = ((dd - lower(j)) / (j + 1.0)).min(u);
        v_cap + r + j * u
    }

    /// Smallest raw acceleration of the segments the next tick covers at speeds up to `v_up`,
    /// starting with `a` (the raw segment's): the velocity change of a tick is along the
    /// chord of that tick, and the planner gives each segment the tangential acceleration
    /// the turns near it leave (a segment next to a turn may have less than its neighbour).
    fn accel_over_next_tick(&self, a: f64, v_up: f64, braking: bool) -> f64 {
        let mut a = a;
        let mut d = self.seg(self.rk).length_mm - self.rs_mm;
        let reach = v_up * TS_S;
        let mut k = self.rk + 1;
        while d < reach && k < self.len {
            if self.seg(k - 1).v_end_mm_s == 0.0 {
                // A stop point: the tick ends there.
                break;
            }
            let seg = self.seg(k);
            let ak = if braking {
                seg.stop_accel_mm_s2
            } else {
                seg.accel_mm_s2
            };
            a = a.min(self.raw_accel(ak, seg));
            d += seg.length_mm;
            k += 1;
        }
        a
    }

    /// Advances one tick.
    pub fn tick(&mut self) -> TickOut {
        let mut program_end = false;
        let mut path_v = 0.0;
        self.spindle_wait = false;
        if self.len > 0 {
            let (cap, feed) = if matches!(self.state, InterpState::Held | InterpState::Idle) {
                (f64::INFINITY, f64::INFINITY)
            } else {
                self.raw_step()
            };
            self.record(cap, feed);
            program_end = self.follow();
            path_v = self.f_v_mm_s;
            self.smooth_axes();
            // (Resets the speed when the last segment has been left: report this tick's.)
            self.update_state();
        } else {
            self.f_v_mm_s = 0.0;
            self.smooth_axes();
        }
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
        let rest = self.v_mm_s == 0.0 && self.settled();
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

    /// Pushes this tick's raw arc length and local caps into the filter history.
    fn record(&mut self, cap: f64, feed: f64) {
        let s = self.raw_s();
        let prev = self.hist_s[self.hist_pos];
        self.hist_pos = (self.hist_pos + 1) % FILTER_MAX_TICKS;
        self.hist_s[self.hist_pos] = s;
        self.hist_cap[self.hist_pos] = cap;
        self.hist_feed[self.hist_pos] = feed;
        if s == prev {
            self.still = (self.still + 1).min(FILTER_MAX_TICKS);
        } else {
            self.still = 0;
        }
    }

    /// Ticks before and after a speed cap during which the raw speed stays within it (0: only
    /// at the cap). The jerk filter averages raw speeds over `m` ticks, so its speed at a
    /// point is within a cap if the raw speed was over the `m + 1` ticks around it; the axis
    /// filter takes path speeds from 2n ticks before to 2n ticks after a turn, and the
    /// planner's corner limits count on all of them being within the junction speed.
    fn cap_zone_ticks(&self) -> usize {
        if self.m <= 1 && self.axis_n <= 1 {
            return 0;
        }
        let axis = if self.axis_n > 1 { 2 * self.axis_n } else { 0 };
        self.m + 1 + axis
    }

    /// Smallest cap (hard, feed) recorded over the last `cap_zone_ticks` ticks.
    fn behind_caps(&self) -> (f64, f64) {
        let zone = self.cap_zone_ticks();
        if zone == 0 {
            return (f64::INFINITY, f64::INFINITY);
        }
        let mut cap = f64::INFINITY;
        let mut feed = f64::INFINITY;
        for j in 0..zone {
            let i = (self.hist_pos + FILTER_MAX_TICKS - j) % FILTER_MAX_TICKS;
            cap = cap.min(self.hist_cap[i]);
            feed = feed.min(self.hist_feed[i]);
        }
        (cap, feed)
    }

    /// Raw stage of one tick. Returns the caps (hard, feed) met during this tick.
    fn raw_step(&mut self) -> (f64, f64) {
        let idle = (f64::INFINITY, f64::INFINITY);
        if self.raw_at_stop {
            let here = *self.seg(self.rk);
            if self.rk + 1 >= self.len || self.state != InterpState::Running {
                self.v_mm_s = 0.0;
                // An M0/M1 after the last segment buffered (the program's end, or the next
                // segment not planned yet) holds here too.
                if self.settled() && self.still > 0 {
                    self.program_stop_after_last();
                }
                return idle;
            }
            // One tick at rest (and the filter settled) before leaving: the direction may
            // reverse here, and the arrival step must not add to the departure step.
            if !self.settled() || self.still == 0 {
                return idle;
            }
            if self.dwell_ticks > 0 {
                self.dwell_ticks -= 1;
                return idle;
            }
            if here.wait_in_position && !self.in_position {
                return idle;
            }
            if self.program_stop_at(true) {
                return idle;
            }
            self.raw_at_stop = false;
            self.rk += 1;
            self.rs_mm = 0.0;
        }
        if self.rs_mm == 0.0 && self.v_mm_s == 0.0 && self.settled() && self.program_stop_at(false)
        {
            // M0/M1 before the first motion.
            return idle;
        }
        if self.dwell_ticks > 0 && self.v_mm_s == 0.0 && self.settled() {
            // Leading dwell (before the first motion).
            self.dwell_ticks -= 1;
            return idle;
        }
        let spindle_ok = self.spindle_ready && self.last_spindle == self.reported_spindle;
        if self.v_mm_s == 0.0 && self.rs_mm == 0.0 && !spindle_ok && !self.seg(self.rk).rapid {
            // A cut starts from rest only with the spindle at speed, judged by the daemon on a
            // spindle state it has already been given.
            self.spindle_wait = true;
            return idle;
        }
        if self.v_mm_s == 0.0 && self.settled() {
            // At rest (the commanded position equals the raw one): the filter may be re-sized
            // for the dynamics of what comes next; its history is all this one point.
            let n =
                usize::from(self.seg(self.rk).axis_filter_ticks).clamp(1, AXIS_FILTER_MAX_TICKS);
            if n != self.axis_n {
                self.axis_in.fill(self.path_pos);
                self.axis_mid.fill(self.path_pos);
                self.axis_n = n;
            }
            let m = self.filter_for();
            if m != self.m {
                let s = self.raw_s();
                self.hist_s.fill(s);
                self.hist_cap.fill(f64::INFINITY);
                self.hist_feed.fill(f64::INFINITY);
                self.still = FILTER_MAX_TICKS;
                self.m = m;
            }
        }
        let a_floor = self.accel_floor();
        let head = *self.seg(self.rk);
        let braking = matches!(self.state, InterpState::Holding | InterpState::Stopping);
        let a = if braking {
            self.raw_accel(head.stop_accel_mm_s2, &head)
        } else {
            self.raw_accel(head.accel_mm_s2, &head)
        };
        let lag = self.cap_zone_ticks() as f64 * TS_S;
        let v = self.v_mm_s;
        let (behind_cap, behind_feed) = self.behind_caps();
        if head.per_rev_nominal_rpm > 0.0 && self.spindle_feed_rpm <= 0.0 {
            // Feed per revolution with a standing spindle: the feed holds (status says why).
            self.spindle_wait = true;
        }
        // Soft limits: feed × override of this and later segments, approached at `a`.
        let mut soft = if braking {
            0.0
        } else {
            self.ceiling(&head).min(behind_feed * self.override_factor)
        };
        // Hard limits: geometric ceilings, planned end speeds, end of the buffer.
        let mut hard = head.v_max_mm_s.min(behind_cap).min(self.entry_cap_mm_s);
        let v_up = v + a * TS_S;
        // Caps farther than this cannot constrain this tick (braking distance at `a_walk`).
        let reach = |a_walk: f64| v_up * v_up / (2.0 * a_walk) + 2.0 * v_up * TS_S + v_up * lag;
        let mut d = head.length_mm - self.rs_mm;
        let mut stop_dist = f64::INFINITY;
        let mut a_walk = a;
        for k in self.rk..self.len {
            let seg = *self.seg(k);
            if k > self.rk {
                let ak = if braking {
                    seg.stop_accel_mm_s2
                } else {
                    seg.accel_mm_s2
                };
                a_walk = a_walk.min(self.raw_accel(ak, &seg));
            }
            let next = (k + 1 < self.len).then(|| *self.seg(k + 1));
            let (hard_cap, soft_cap, lead) = match next {
                Some(n) if seg.v_end_mm_s > 0.0 => {
                    (seg.v_end_mm_s.min(n.v_max_mm_s), self.ceiling(&n), lag)
                }
                _ => (0.0, 0.0, 0.0),
            };
            // Any speed up to the cap itself is safe for that cap; above it, we must still be
            // able to brake to it (later caps are checked on their own).
            hard = hard.min(hard_cap.max(Self::v_brake(d - hard_cap * lead, hard_cap, a_walk)));
            soft = soft.min(soft_cap.max(Self::v_brake(d - soft_cap * lead, soft_cap, a_walk)));
            if hard_cap == 0.0 {
                stop_dist = d;
                break;
            }
            if d > reach(a_floor.min(a_walk)) {
                break;
            }
            d += next.map_or(0.0, |n| n.length_mm);
        }
        let a_up = self.accel_over_next_tick(a, v_up, braking);
        let mut v_next = (v + a_up * TS_S)
            .min(soft)
            .max(v - a * TS_S)
            .min(hard)
            .max(0.0);
        // Arrive exactly at a stop point once the last step fits inside the deceleration limit.
        let mut ds = v_next * TS_S;
        if stop_dist <= (a * TS_S * TS_S).max(ARRIVE_EPS_MM) && stop_dist <= ds.max(ARRIVE_EPS_MM) {
            ds = stop_dist;
            v_next = ds / TS_S;
        }
        if v_next <= 0.0 && stop_dist > ARRIVE_EPS_MM {
            self.v_mm_s = 0.0;
            return (head.v_max_mm_s, self.feed_of(&head));
        }
        self.v_mm_s = v_next;
        self.move_raw(ds)
    }

    /// Moves the raw position `ds` along the buffered path. Returns the smallest hard cap and
    /// feed met on the way (segment ceilings and junction speeds).
    fn move_raw(&mut self, mut ds: f64) -> (f64, f64) {
        let first = *self.seg(self.rk);
        let mut cap = first.v_max_mm_s;
        let mut feed = self.feed_of(&first);
        self.entry_cap_mm_s = f64::INFINITY;
        loop {
            let seg = *self.seg(self.rk);
            let rest = seg.length_mm - self.rs_mm;
            if ds < rest - ARRIVE_EPS_MM {
                if self.rs_mm == 0.0 && ds <= ARRIVE_EPS_MM {
                    // Ended on the junction just crossed.
                    self.entry_cap_mm_s = cap;
                }
                self.rs_mm += ds;
                return (cap, feed);
            }
            ds -= rest;
            self.rs_mm = seg.length_mm;
            if seg.v_end_mm_s == 0.0 || self.rk + 1 >= self.len {
                // A stop point: never carry distance past it.
                self.raw_at_stop = true;
                self.v_mm_s = 0.0;
                self.dwell_ticks = (seg.dwell_s / TS_S).round().max(0.0) as u32;
                return (cap, feed);
            }
            let next = *self.seg(self.rk + 1);
            cap = cap.min(seg.v_end_mm_s).min(next.v_max_mm_s);
            feed = feed.min(self.feed_of(&next));
            self.rk += 1;
            self.rs_mm = 0.0;
        }
    }

    /// Filter stage: the commanded arc length is the mean of the last `m` raw arc lengths.
    /// Returns whether the program's last segment was completed.
    fn follow(&mut self) -> bool {
        let s_raw = self.hist_s[self.hist_pos];
        let mut lag_sum = 0.0;
        for j in 0..self.m {
            let i = (self.hist_pos + FILTER_MAX_TICKS - j) % FILTER_MAX_TICKS;
            lag_sum += s_raw - self.hist_s[i];
        }
        let s_f = (s_raw - lag_sum / self.m as f64).max(self.f_s_mm);
        self.f_v_mm_s = (s_f - self.f_s_mm) / TS_S;
        self.f_s_mm = s_f;
        let mut program_end = false;
        // Drop segments the commanded position has left (never the raw one).
        while self.len > 0 {
            let i = self.idx(0);
            let seg = self.buf[i];
            let end = self.s0[i] + seg.length_mm;
            let raw_done = self.rk > 0
                || (self.raw_at_stop
                    && self.len == 1
                    && self.settled()
                    && self.last_may_leave(&seg));
            if s_f >= end - ARRIVE_EPS_MM && raw_done {
                self.path_pos = seg.path.end();
                self.last_seq = seg.seq;
                self.last_n = seg.n;
                self.last_line = seg.line;
                self.last_spindle = seg.spindle_after.unwrap_or(seg.spindle);
                self.last_rapid = seg.rapid;
                program_end |= seg.last;
                self.head = (self.head + 1) % self.buf.len();
                // Rescan only when the last segment at a floor value leaves (a uniform dense
                // path never rescans).
                let a_left = self
                    .floor_accel
                    .remove(seg.accel_mm_s2.min(seg.stop_accel_mm_s2));
                let j_left = self.floor_jerk.remove(seg.jerk_mm_s3);
                self.floor_dirty |= a_left || j_left;
                self.len -= 1;
                self.rk = self.rk.saturating_sub(1);
                if self.len == 0 {
                    self.rs_mm = 0.0;
                }
                continue;
            }
            let local = s_f - self.s0[i];
            self.path_pos = if local >= seg.length_mm - ARRIVE_EPS_MM {
                seg.path.end()
            } else {
                seg.path.point_at((local / seg.length_mm).max(0.0))
            };
            self.last_seq = seg.seq;
            self.last_n = seg.n;
            self.last_line = seg.line;
            // At rest at a stop point (from the tick after the arrival): the spindle state of
            // what comes next is in force, so the spindle runs up (or stops) before the next
            // move, not with it.
            let at_stop = self.raw_at_stop
                && self.rk == 0
                && self.f_v_mm_s == 0.0
                && local >= seg.length_mm - ARRIVE_EPS_MM;
            self.last_spindle = match (at_stop, seg.spindle_after) {
                (false, _) => seg.spindle,
                (true, _) if self.len > 1 => self.buf[self.idx(1)].spindle,
                (true, after) => after.unwrap_or(seg.spindle),
            };
            self.last_rapid = seg.rapid;
            break;
        }
        program_end
    }
}

/// Smallest value over the buffered segments and how many of them have it.
#[derive(Clone, Copy, Debug)]
struct Floor {
    value: f64,
    count: usize,
}

impl Default for Floor {
    fn default() -> Self {
        Floor {
            value: f64::INFINITY,
            count: 0,
        }
    }
}

impl Floor {
    fn add(&mut self, v: f64) {
        if v < self.value {
            self.value = v;
            self.count = 1;
        } else if v == self.value {
            self.count += 1;
        }
    }

    /// Takes a leaving segment's value out; true when the floor must be recomputed.
    fn remove(&mut self, v: f64) -> bool {
        if v <= self.value && self.count > 0 {
            self.count -= 1;
        }
        v <= self.value && self.count == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::SegPath;

    fn line(seq: u32, from: [f64; 3], to: [f64; 3], feed: f64, v_end: f64) -> Segment {
        let mut s = AxesMm::ZERO;
        let mut e = AxesMm::ZERO;
        s.0[..3].copy_from_slice(&from);
        e.0[..3].copy_from_slice(&to);
        let path = SegPath::Line { start: s, end: e };
        Segment {
            seq,
            path,
            length_mm: path.length(3),
            feed_mm_s: feed,
            v_max_mm_s: 1000.0,
            v_end_mm_s: v_end,
            accel_mm_s2: 500.0,
            jerk_mm_s3: f64::INFINITY,
            stop_accel_mm_s2: 500.0,
            ..Segment::default()
        }
    }

    fn run(ip: &mut Interpolator, max_ticks: usize) -> Vec<TickOut> {
        let mut out = vec![];
        for _ in 0..max_ticks {
            let t = ip.tick();
            out.push(t);
            if t.state == InterpState::Idle {
                break;
            }
        }
        out
    }

    fn check_limits(trace: &[TickOut], v_max: f64, a_max: f64) {
        let mut prev_v = 0.0;
        for w in trace.windows(2) {
            let v = (w[1].position - w[0].position).norm(3) / TS_S;
            assert!(v <= v_max * (1.0 + 1e-9) + 1e-9, "speed {v} > {v_max}");
            let a = (v - prev_v).abs() / TS_S;
            assert!(a <= a_max * (1.0 + 1e-6) + 1e-6, "accel {a} > {a_max}");
            prev_v = v;
        }
    }

    #[test]
    fn single_line_ends_exactly_within_limits() {
        let mut ip = Interpolator::new(3, AxesMm::ZERO);
        ip.push(line(0, [0.0; 3], [10.0, 5.0, 0.0], 50.0, 0.0))
            .unwrap();
        let mut trace = vec![TickOut::default()];
        trace.extend(run(&mut ip, 10_000));
        let end = trace.last().unwrap().position;
        assert_eq!(&end.0[..3], &[10.0, 5.0, 0.0]);
        check_limits(&trace, 50.0, 500.0);
    }

    #[test]
    fn smooth_junction_does_not_stop() {
        let mut ip = Interpolator::new(3, AxesMm::ZERO);
        ip.push(line(0, [0.0; 3], [10.0, 0.0, 0.0], 50.0, 50.0))
            .unwrap();
        ip.push(line(1, [10.0, 0.0, 0.0], [20.0, 0.0, 0.0], 50.0, 0.0))
            .unwrap();
        let trace = run(&mut ip, 10_000);
        let min_mid = trace
            .iter()
            .filter(|t| (5.0..15.0).contains(&t.position[0]))
            .map(|t| t.path_v_mm_s)
            .fold(f64::INFINITY, f64::min);
        assert!(min_mid > 49.0, "slowed to {min_mid}");
        assert_eq!(trace.last().unwrap().position[0], 20.0);
    }

    #[test]
    fn hold_brakes_and_resume_finishes() {
        let mut ip = Interpolator::new(3, AxesMm::ZERO);
        ip.push(line(0, [0.0; 3], [100.0, 0.0, 0.0], 50.0, 0.0))
            .unwrap();
        let mut trace = vec![TickOut::default()];
        for _ in 0..100 {
            trace.push(ip.tick());
        }
        ip.hold();
        for _ in 0..100 {
            trace.push(ip.tick());
        }
        assert_eq!(ip.state(), InterpState::Held);
        ip.resume();
        trace.extend(run(&mut ip, 10_000));
        check_limits(&trace, 50.0, 500.0);
        assert_eq!(trace.last().unwrap().position[0], 100.0);
    }

    #[test]
    fn stop_brakes_then_drops_the_rest() {
        let mut ip = Interpolator::new(3, AxesMm::ZERO);
        ip.push(line(0, [0.0; 3], [100.0, 0.0, 0.0], 50.0, 0.0))
            .unwrap();
        let mut trace = vec![TickOut::default()];
        for _ in 0..100 {
            trace.push(ip.tick());
        }
        ip.stop();
        trace.extend(run(&mut ip, 1000));
        check_limits(&trace, 50.0, 500.0);
        assert_eq!(ip.state(), InterpState::Idle);
        assert!(ip.position()[0] < 100.0);
    }

    #[test]
    fn jerk_filter_limits_jerk_and_arrives_exactly() {
        let mut ip = Interpolator::new(3, AxesMm::ZERO);
        let mut seg = line(0, [0.0; 3], [30.0, 0.0, 0.0], 80.0, 0.0);
        seg.jerk_mm_s3 = 20_000.0;
        ip.push(seg).unwrap();
        let mut trace = vec![TickOut::default()];
        trace.extend(run(&mut ip, 10_000));
        assert!(ip.filter_ticks() > 1);
        assert_eq!(trace.last().unwrap().position[0], 30.0);
        let v: Vec<f64> = trace
            .windows(2)
            .map(|w| (w[1].position - w[0].position).norm(3) / TS_S)
            .collect();
        let a: Vec<f64> = v.windows(2).map(|w| (w[1] - w[0]) / TS_S).collect();
        for w in a.windows(2) {
            let j = (w[1] - w[0]).abs() / TS_S;
            assert!(j <= 20_000.0 * 1.001 + 1e-3, "jerk {j}");
        }
        assert!(a.iter().all(|x| x.abs() <= 500.0 * 1.001));
    }

    #[test]
    fn axis_filter_rounds_a_smooth_corner_and_settles_exactly() {
        // Two lines with a smooth 30° corner at speed 5 mm/s, axis filter 3 ticks.
        let mut ip = Interpolator::new(3, AxesMm::ZERO);
        let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let mut a = line(0, [0.0; 3], [2.0, 0.0, 0.0], 20.0, 5.0);
        let mut b = line(1, [2.0, 0.0, 0.0], [2.0 + 2.0 * c, 2.0 * s, 0.0], 20.0, 0.0);
        a.axis_filter_ticks = 3;
        b.axis_filter_ticks = 3;
        b.last = true;
        ip.push(a).unwrap();
        ip.push(b).unwrap();
        let mut trace = vec![TickOut::default()];
        trace.extend(run(&mut ip, 10_000));
        assert_eq!(ip.axis_filter_ticks(), 3);
        let last = trace.last().unwrap();
        assert_eq!(&last.position.0[..3], &[2.0 + 2.0 * c, 2.0 * s, 0.0]);
        assert!(last.program_end);
        // The corner is cut (a setpoint off both lines), by much less than the raw tick.
        let off = trace
            .iter()
            .map(|t| t.position[1] - (t.position[0] - 2.0).max(0.0) * s / c)
            .fold(0.0f64, |m, d| m.max(d.abs()));
        assert!(off > 1e-6 && off < 5.0 * TS_S, "{off}");
        // Per-axis velocity of the Y axis starts over several ticks, not in one.
        let vy: Vec<f64> = trace
            .windows(2)
            .map(|w| (w[1].position[1] - w[0].position[1]) / TS_S)
            .collect();
        let first = vy.iter().position(|v| *v > 0.0).unwrap();
        assert!(vy[first] < 0.5 * 5.0 * s, "{:?}", &vy[first..first + 6]);
    }

    #[test]
    fn a_cut_waits_for_the_spindle_a_rapid_does_not() {
        use crate::block::SpindleDir;
        let mut ip = Interpolator::new(3, AxesMm::ZERO);
        let mut cut = line(0, [0.0; 3], [1.0, 0.0, 0.0], 50.0, 0.0);
        cut.spindle.dir = SpindleDir::Cw;
        cut.spindle.s = 1000.0;
        ip.set_spindle_ready(false);
        ip.push(cut).unwrap();
        // The spindle state is in force at once, the axes wait.
        for _ in 0..50 {
            let t = ip.tick();
            assert_eq!(t.spindle.dir, SpindleDir::Cw);
            assert_eq!(t.position[0], 0.0);
            assert!(ip.waiting_for_spindle());
        }
        ip.set_spindle_ready(true);
        ip.tick();
        assert!(!ip.waiting_for_spindle());
        run(&mut ip, 1000);
        assert_eq!(ip.position()[0], 1.0);
        let mut rapid = line(1, [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], 50.0, 0.0);
        rapid.rapid = true;
        ip.set_spindle_ready(false);
        ip.push(rapid).unwrap();
        run(&mut ip, 1000);
        assert_eq!(ip.position()[0], 2.0);
    }

    #[test]
    fn floor_asks_for_a_rescan_only_when_its_last_holder_leaves() {
        let mut f = Floor::default();
        for v in [5.0, 3.0, 3.0, 4.0] {
            f.add(v);
        }
        assert_eq!((f.value, f.count), (3.0, 2));
        assert!(!f.remove(5.0));
        assert!(!f.remove(3.0));
        assert!(f.remove(3.0));
        let mut inf = Floor::default();
        inf.add(f64::INFINITY);
        assert!(inf.remove(f64::INFINITY));
    }

    #[test]
    fn g24_waits_for_in_position() {
        let mut ip = Interpolator::new(3, AxesMm::ZERO);
        let mut a = line(0, [0.0; 3], [1.0, 0.0, 0.0], 50.0, 0.0);
        a.wait_in_position = true;
        ip.push(a).unwrap();
        ip.push(line(1, [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], 50.0, 0.0))
            .unwrap();
        ip.set_in_position(false);
        for _ in 0..500 {
            ip.tick();
        }
        assert_eq!(ip.position()[0], 1.0);
        ip.set_in_position(true);
        run(&mut ip, 1000);
        assert_eq!(ip.position()[0], 2.0);
    }
}
