//! Stage 1, raw path speed: chosen online each tick from the limits the planner attached to
//! each segment (acceleration-limited; SPEC §7.2), the raw arc length advancing by `v·Ts`.

use super::{
    ARRIVE_EPS_MM, AXIS_FILTER_MAX_TICKS, Ahead, FILTER_MAX_TICKS, FILTER_SCAN_SEGMENTS, GROUP,
    InterpState, Interpolator,
};
use crate::block::ProgramStop;
use crate::plan::{SegPath, Segment};
use crate::units::{AxesMm, TS_S};

/// Speed limits of one tick, mm/s, and the distance to the next stop point (∞: none in reach).
/// `soft_mm_s`/`hard_mm_s` hold when this tick does not accelerate; `*_accel_mm_s` when it
/// does (parabolic profile: braking then starts only after a coast gap of `m` ticks; equal to
/// the others in the linear profile).
#[derive(Clone, Copy, Debug)]
struct SpeedLimits {
    soft_mm_s: f64,
    hard_mm_s: f64,
    soft_accel_mm_s: f64,
    hard_accel_mm_s: f64,
    stop_dist_mm: f64,
}

/// The limits of `speed_limits` while it walks the caps ahead: with the coasting gap of a
/// tick at constant acceleration (`coast`) and of one that accelerates (`coast_accel`; the
/// parabolic profile's jerk limit makes them differ, the linear one has no gap).
pub(super) struct CapWalk {
    pub soft: f64,
    pub hard: f64,
    pub soft_acc: f64,
    pub hard_acc: f64,
    pub coast: f64,
    pub coast_accel: f64,
}

impl CapWalk {
    /// Lowers the limits for the caps `d` mm ahead, held `lead_s` early, braked to at
    /// `a_walk`.
    fn limit(&mut self, d: f64, hard_cap: f64, soft_cap: f64, lead_s: f64, a_walk: f64) {
        // Any speed up to the cap itself is safe for that cap; above it, we must still be
        // able to brake to it (later caps are checked on their own). A cap at or above the
        // limit so far cannot lower it (skipped: no square root on a dense path at its cap
        // speed).
        // A cap whose braking curve is certainly not below the limit so far is skipped with
        // a few products (`v_brake_at_least`): on a dense path most caps within the reach are
        // far enough, and their square roots were half of the tick.
        let limit = |cur: &mut f64, cap: f64, gap: f64| {
            if cap < *cur {
                let d_cap = d - cap * lead_s;
                if !Interpolator::v_brake_at_least(d_cap, cap, a_walk, gap, *cur) {
                    *cur = cur.min(cap.max(Interpolator::v_brake(d_cap, cap, a_walk, gap)));
                }
            }
        };
        limit(&mut self.hard, hard_cap, self.coast);
        limit(&mut self.soft, soft_cap, self.coast);
        if self.coast_accel != self.coast {
            limit(&mut self.hard_acc, hard_cap, self.coast_accel);
            limit(&mut self.soft_acc, soft_cap, self.coast_accel);
        }
    }

    fn finish(self, stop_dist_mm: f64) -> SpeedLimits {
        // (Linear profile: no gap, the same limits; not computed twice.)
        let (soft_acc, hard_acc) = if self.coast_accel == self.coast {
            (self.soft, self.hard)
        } else {
            (self.soft_acc, self.hard_acc)
        };
        SpeedLimits {
            soft_mm_s: self.soft,
            hard_mm_s: self.hard,
            soft_accel_mm_s: soft_acc.min(self.soft),
            hard_accel_mm_s: hard_acc.min(self.hard),
            stop_dist_mm,
        }
    }
}

impl Interpolator {
    pub(super) fn stops_here(&self, stop: ProgramStop) -> bool {
        match stop {
            ProgramStop::None => false,
            ProgramStop::Always | ProgramStop::ToolChange { .. } => true,
            ProgramStop::Optional => self.optional_stop,
        }
    }

    /// Holds at the program stop `stop` (due here): the tool it names, if a tool change.
    pub(super) fn hold_at_stop(&mut self, stop: ProgramStop) {
        self.state = InterpState::Holding;
        self.at_program_stop = true;
        self.tool_change = match stop {
            ProgramStop::ToolChange { tool } => Some(tool),
            _ => None,
        };
    }

    /// At rest between segment `raw_seg` and the next: holds if a program stop (M0/M1) is due
    /// there. Each stop is honoured once (cleared in the buffer).
    pub(super) fn program_stop_at(&mut self, before_next: bool) -> bool {
        if self.state != InterpState::Running {
            return false;
        }
        let here = self.idx(self.raw_seg);
        let after = self.buf[here].program_stop;
        let due_after = before_next && self.stops_here(after);
        let next = if before_next {
            self.idx(self.raw_seg + 1)
        } else {
            here
        };
        let before = self.buf[next].program_stop_before;
        let due_before = self.stops_here(before);
        if !(due_after || due_before) {
            return false;
        }
        if before_next {
            self.buf[here].program_stop = ProgramStop::None;
        }
        self.buf[next].program_stop_before = ProgramStop::None;
        let due = |due: bool, s: ProgramStop| if due { s } else { ProgramStop::None };
        self.hold_at_stop(due(due_after, after).stronger(due(due_before, before)));
        true
    }

    /// At rest at the end of the last buffered segment: holds if a program stop is due after
    /// it. The segment stays buffered until Resume, so the job does not end at the stop.
    fn program_stop_after_last(&mut self) {
        let here = self.idx(self.raw_seg);
        let stop = self.buf[here].program_stop;
        if self.state != InterpState::Running || !self.stops_here(stop) {
            return;
        }
        self.buf[here].program_stop = ProgramStop::None;
        self.hold_at_stop(stop);
    }

    /// The last buffered segment may be dropped once the raw position rests at its end: not
    /// while a program stop after it is due or held (a plain feed hold lets it go as before).
    pub(super) fn last_may_leave(&self, seg: &Segment) -> bool {
        !self.at_program_stop && !self.stops_here(seg.program_stop)
    }

    pub(super) fn raw_s(&self) -> f64 {
        if self.len == 0 {
            return self.buffered_end_s_mm;
        }
        self.seg_start_s_mm[self.idx(self.raw_seg)] + self.raw_in_seg_mm
    }

    /// Filter length for the motion that starts at rest on segment `raw_seg`: the raw
    /// acceleration never differs by more than a from the one `m` ticks before (the coast
    /// gap, `jerk_filter::jerk_accel_window`), so the jerk of the average is ≤ a/(m·Ts) ≤ J
    /// with m = ⌈a/(J·Ts)⌉. A motion that cannot reach `a` before its speed (the highest
    /// programmed speed up to the next stop, at 100 % override) is a pure parabola: it needs
    /// only a = √(v·J), and the ramp to F takes 2·√(F/J), the manual's T = 1.478·√(F/P).
    /// A move to a stop too short to reach its speed is sized for the peak it can reach.
    pub(super) fn filter_for(&self) -> usize {
        let seg = self.seg(self.raw_seg);
        let a = seg.accel_mm_s2.max(seg.stop_accel_mm_s2);
        let j = seg.jerk_mm_s3;
        if !j.is_finite() || j <= 0.0 {
            return 1;
        }
        // (Segments that arrive later are followed at the acceleration this filter allows:
        // slower, never above the jerk.)
        let mut v = f64::INFINITY;
        let mut top = 0.0f64;
        let mut dist_mm = -self.raw_in_seg_mm;
        for k in self.raw_seg..self.len.min(self.raw_seg + FILTER_SCAN_SEGMENTS) {
            let s = self.seg(k);
            top = top.max(s.feed_mm_s.min(s.v_max_mm_s));
            dist_mm += s.length_mm;
            if s.v_end_mm_s == 0.0 {
                // A move too short for its speed peaks at v with 2·v·√(v/J) = d (two
                // pure-parabola ramps): the filter is sized for that peak (a 2 mm move at
                // F6000 with P = 50000 took 1.6 × the ideal time with the filter of F).
                v = top.min((dist_mm * dist_mm * j / 4.0).cbrt());
                break;
            }
            if k + 1 == self.len {
                v = top;
                break;
            }
        }
        let a = a.min((v * j).sqrt());
        ((a / (j * TS_S)).ceil() as usize)
            .clamp(1, FILTER_MAX_TICKS - 2 * AXIS_FILTER_MAX_TICKS - 2)
    }

    /// Acceleration the raw stage may use with the current filter (jerk ≤ J needs a ≤ J·m·Ts).
    /// Lower bound of the raw acceleration on every buffered segment: a cap whose braking
    /// distance at this bound is out of reach cannot constrain this tick. (Judging the reach
    /// with the accelerations seen so far missed a stop behind a segment of lower
    /// acceleration and made the speed saw between braking harder than allowed and
    /// accelerating again.)
    pub(super) fn accel_floor(&self) -> f64 {
        let (floor_a, floor_j) = (
            self.floor_accel_mm_s2.value(),
            self.floor_jerk_mm_s3.value(),
        );
        let a = if floor_j.is_finite() {
            floor_a.min(floor_j * self.jerk_filter_ticks as f64 * TS_S)
        } else {
            floor_a
        };
        a.max(1e-6)
    }

    pub(super) fn raw_accel(&self, a: f64, seg: &Segment) -> f64 {
        self.raw_accel_j(a, seg.jerk_mm_s3)
    }

    pub(super) fn raw_accel_j(&self, a: f64, jerk_mm_s3: f64) -> f64 {
        let a = if jerk_mm_s3.is_finite() {
            a.min(jerk_mm_s3 * self.jerk_filter_ticks as f64 * TS_S)
        } else {
            a
        };
        a.max(1e-6)
    }

    /// Raw acceleration of a tick on a line whose steps touch only one of its junctions: that
    /// end's budget (`Segment::accel_start_mm_s2` or `accel_end_mm_s2`), never below the
    /// line's budget `line_mm_s2` (issue #32).
    pub(super) fn end_raw_accel(&self, end_mm_s2: f64, line_mm_s2: f64, jerk_mm_s3: f64) -> f64 {
        self.raw_accel_j(end_mm_s2.max(line_mm_s2), jerk_mm_s3)
    }

    /// Highest speed for this tick from which the per-tick speeds, falling by u = a·Ts per
    /// tick, are down to `v_cap` when the path reaches the cap point `d` ahead. Exact in
    /// discrete time: the speeds before the point are v_cap + r + j·u (j = J..0, 0 < r ≤ u),
    /// covering Ts·((J+1)·(v_cap + r) + u·J(J+1)/2) ≤ d − v_cap·Ts. For a stop (v_cap = 0) they end exactly on it, so braking runs at the full
    /// deceleration and the last tick is the only one rounded (the continuous bound
    /// (v² − v_cap²)/(2a) ≤ d − v·Ts started braking half a tick early and crept at the end).
    ///
    /// With `coast` > 0 (parabolic profile, `jerk_filter::coast_gaps`) the braking starts only
    /// after `coast` more ticks at this tick's speed: the ticks faster than v_cap are then
    /// J+1+coast, covering Ts·((J+1+coast)·(v_cap + r) + u·J(J+1)/2 + coast·J·u).
    pub(super) fn v_brake(d: f64, v_cap: f64, a: f64, coast: f64) -> f64 {
        let u = a * TS_S;
        // The last tick before the point runs at v_cap and ends on it (the tick after the point
        // is held to the cap too, see `entry_cap_mm_s`): the faster ticks end one v_cap·Ts
        // earlier. Distances in speed·ticks.
        let dd = d.max(0.0) / TS_S - v_cap;
        // Distance of the J+1+coast ticks faster than v_cap with r = 0.
        let lower = |j: f64| (j + 1.0 + coast) * v_cap + u * j * (j + 1.0) / 2.0 + coast * j * u;
        if dd <= (1.0 + coast) * v_cap {
            return (dd / (1.0 + coast)).max(0.0);
        }
        let b = v_cap + u / 2.0 + coast * u;
        let root = (-b + (b * b + 2.0 * u * (dd - (1.0 + coast) * v_cap)).sqrt()) / u;
        let mut j = (root.ceil() - 1.0).max(0.0);
        while j > 0.0 && lower(j) >= dd {
            j -= 1.0;
        }
        while lower(j + 1.0) < dd {
            j += 1.0;
        }
        let r = ((dd - lower(j)) / (j + 1.0 + coast)).min(u);
        v_cap + r + j * u
    }

    /// Whether `v_brake(d, v_cap, a, coast)` is certainly at least `v` (> `v_cap`), without
    /// computing it. `v_brake` returns v_cap + r + j·u (0 < r ≤ u) with lower(j + 1) ≥ dd,
    /// so j + 1 < x = (v_brake − v_cap)/u + 1 and dd < lower(x), lower increasing: if
    /// lower(x_v) ≤ dd at x_v = (v − v_cap)/u + 1, then v_brake > v. The margins (1e-9 of v
    /// and u in speed, 1e-9 of dd) cover the rounding of both computations, so a cap skipped
    /// this way would not have lowered the limit: the result is bit-identical.
    pub(super) fn v_brake_at_least(d: f64, v_cap: f64, a: f64, coast: f64, v: f64) -> bool {
        let u = a * TS_S;
        let dd = d.max(0.0) / TS_S - v_cap;
        let x = ((v - v_cap) + 1e-9 * (v + u)) / u + 1.0;
        let lower = (x + 1.0 + coast) * v_cap + u * x * (x + 1.0) / 2.0 + coast * x * u;
        lower * (1.0 + 1e-9) <= dd
    }

    /// Raw stage of one tick (SPEC §7.2, §7.3): leave a stop point or wait at rest, re-size
    /// the filters at rest, find this tick's speed limits and advance the raw position.
    /// Returns the caps (hard, feed) met during this tick, mm/s.
    pub(super) fn raw_step(&mut self) -> (f64, f64) {
        const IDLE: (f64, f64) = (f64::INFINITY, f64::INFINITY);
        if self.raw_at_stop && !self.leave_stop_point() {
            return IDLE;
        }
        if self.waits_before_motion() {
            return IDLE;
        }
        if self.raw_v_mm_s == 0.0 && self.settled() && !self.resize_filters_at_rest() {
            return IDLE;
        }
        let head = *self.seg(self.raw_seg);
        let braking = matches!(self.state, InterpState::Holding | InterpState::Stopping);
        let accel_mm_s2 = if braking {
            self.raw_accel(head.stop_accel_mm_s2, &head)
        } else {
            self.raw_accel(head.accel_mm_s2, &head)
        };
        if head.per_rev_nominal_rpm > 0.0 && self.spindle_feed_rpm <= 0.0 {
            // Feed per revolution with a standing spindle: the feed holds (status says why).
            self.spindle_wait = true;
        }
        self.arm_block_stop(&head, accel_mm_s2);
        let head = *self.seg(self.raw_seg);
        if self.jbox_applies() {
            return self.jbox_step(accel_mm_s2);
        }
        if self.jbox_filter_out {
            // The jerk filter is out for the box, which hands this motion over: the raw
            // position rests until the filters settle and the envelope's is sized.
            self.raw_v_mm_s = 0.0;
            return IDLE;
        }
        if let Some(ds) = self.box_step(braking) {
            return self.advance_raw_by(&head, accel_mm_s2, ds);
        }
        let limits = self.speed_limits(&head, accel_mm_s2, braking);
        self.advance_raw(&head, accel_mm_s2, limits)
    }

    /// At rest at the end of segment `raw_seg` (a stop point): moves on to the next segment
    /// when everything due there is done (settled filters, dwell, G24 in position, M0/M1).
    /// Returns whether the raw position may move this tick.
    fn leave_stop_point(&mut self) -> bool {
        let here = *self.seg(self.raw_seg);
        if self.raw_seg + 1 >= self.len || self.state != InterpState::Running {
            self.raw_v_mm_s = 0.0;
            // An M0/M1 after the last segment buffered (the program's end, or the next
            // segment not planned yet) holds here too.
            if self.settled() && self.still_ticks > 0 {
                self.program_stop_after_last();
            }
            return false;
        }
        // One tick at rest (and the filter settled) before leaving: the direction may
        // reverse here, and the arrival step must not add to the departure step. A plain
        // stop of the linear profile is left at once, with the departure step within what
        // the arrival step left of the tick (`departure_cap_mm_s`).
        if self.still_ticks > 0 {
            self.entry_cap_mm_s = f64::INFINITY;
            self.box_departs = false;
        }
        let departs = self.entry_cap_mm_s.is_finite() || self.box_departs;
        if !self.settled() || (self.still_ticks == 0 && !departs) {
            return false;
        }
        let next = *self.seg(self.raw_seg + 1);
        if !self.departure_adds_no_jerk(&next) {
            return false;
        }
        if self.dwell_ticks > 0 {
            self.dwell_ticks -= 1;
            return false;
        }
        if here.wait_in_position && !self.in_position {
            return false;
        }
        if self.program_stop_at(true) {
            // (One stop per point: single block does not hold again after this one.)
            self.block_stop_done = true;
            return false;
        }
        if self.block_stop_at() {
            return false;
        }
        self.raw_at_stop = false;
        self.raw_seg += 1;
        self.raw_in_seg_mm = 0.0;
        self.block_stop_done = false;
        self.block_stop_armed = false;
        true
    }

    /// At rest between segment `raw_seg` and the next, in single-block mode: holds where a
    /// block ends (the next segment comes from another block), once per stop point. A
    /// restart's approach legs carry block N's `seq` with line 0 (`kernel::restart`): the
    /// approach is one block of its own, so the path holds between it and block N.
    fn block_stop_at(&mut self) -> bool {
        let same = same_block(self.seg(self.raw_seg), self.seg(self.raw_seg + 1));
        if !self.single_block || self.block_stop_done || same {
            return false;
        }
        self.block_stop_done = true;
        self.state = InterpState::Holding;
        self.at_block_stop = true;
        true
    }

    /// Single-block mode while running: makes the first block end ahead that the path can
    /// still brake for a stop point (its end speed 0), unless a stop point comes first. A
    /// program started in single-block mode is planned with every block ending at rest (that
    /// end is found at once); one switched on while moving stops at the next block end out of
    /// braking reach, as a stop at the end of the buffer is (`speed_limits` then brakes for it
    /// like for any stop). Bounded by the braking reach, as the look-ahead of `speed_limits`;
    /// while the per-axis box chooses the setpoints (`setpoint_box`), by where its last
    /// proof comes to rest.
    fn arm_block_stop(&mut self, head: &Segment, accel_mm_s2: f64) {
        if !self.single_block || self.block_stop_armed || self.state != InterpState::Running {
            return;
        }
        let v_up = self.raw_v_mm_s + accel_mm_s2 * TS_S;
        let (_, coast_accel) = self.coast_gaps(head);
        let lag_s = self.cap_zone_ticks() as f64 * TS_S;
        // The reach of `speed_limits` with a margin: a stop point farther than this has not
        // constrained any tick yet, so braking for it from here is within the limits.
        let reach_mm = 1.5
            * (v_up * v_up / (2.0 * self.accel_floor())
                + (2.0 + coast_accel) * v_up * TS_S
                + v_up * lag_s)
            + 1e-6;
        let mut d = head.length_mm - self.raw_in_seg_mm;
        for k in self.raw_seg..self.len {
            let seg = self.seg(k);
            if seg.v_end_mm_s == 0.0 || k + 1 >= self.len {
                // A stop point first (or the end of the buffer: look again as segments come).
                self.block_stop_armed = seg.v_end_mm_s == 0.0;
                return;
            }
            let next = self.seg(k + 1);
            // (While the box chooses the setpoints, its last proof brakes to rest before
            // any stop point beyond where that proof rests.)
            let far_enough = if self.jbox_applies() {
                self.raw_s() + d >= self.jbox_rest_s
            } else if self.box_mode {
                self.raw_s() + d >= self.box_plan.rest_s(&self.box_paths, self.raw_s())
            } else {
                d >= reach_mm
            };
            if !same_block(seg, next) && far_enough {
                let i = self.idx(k);
                self.buf[i].v_end_mm_s = 0.0;
                self.note_stop_at(i);
                self.block_stop_armed = true;
                return;
            }
            d += next.length_mm;
        }
    }

    /// Before the first motion from rest: a program stop, a leading dwell or (for a cut) a
    /// spindle not yet at speed keeps the raw position where it is this tick.
    fn waits_before_motion(&mut self) -> bool {
        let at_rest = self.raw_v_mm_s == 0.0;
        if self.raw_in_seg_mm == 0.0 && at_rest && self.settled() && self.program_stop_at(false) {
            // M0/M1 before the first motion.
            return true;
        }
        if self.dwell_ticks > 0 && at_rest && self.settled() {
            // Leading dwell (before the first motion).
            self.dwell_ticks -= 1;
            return true;
        }
        let seen = self.last_spindle == self.reported_spindle;
        let waits = self.seg(self.raw_seg).spindle.outputs.wait != 0;
        if at_rest && self.raw_in_seg_mm == 0.0 && waits && !(self.inputs_confirmed && seen) {
            // An M function waits for its input before the motion (docs/io.md).
            self.inputs_wait = true;
            return true;
        }
        let spindle_ok = self.spindle_ready && seen;
        if at_rest && self.raw_in_seg_mm == 0.0 && !spindle_ok && !self.seg(self.raw_seg).rapid {
            // A cut starts from rest only with the spindle at speed, judged by the daemon on a
            // spindle state it has already been given.
            self.spindle_wait = true;
            return true;
        }
        false
    }

    /// Jerk-limited, whether a departure along `next` now keeps every axis's jerk: the filters
    /// settle on a stop point while their last step still moves, and the departure's first
    /// steps add to those of every axis it moves (an axis at 1.04 × its jerk on the reference
    /// splines, 1.17 × where the axis filter was re-sized too). So the setpoints' last two
    /// steps must be 0 on those axes; an axis the departure does not move only rests (a
    /// zig-zag's right-angled stops, from one axis to another, cost no tick). An arc may move
    /// every axis soon after its start: all of them rest first.
    fn departure_adds_no_jerk(&self, next: &Segment) -> bool {
        if !next.jerk_mm_s3.is_finite() {
            return true;
        }
        let dir = match next.path {
            SegPath::Line { start, end } => end - start,
            SegPath::Arc { .. } => AxesMm([1.0; crate::MAX_AXES]),
        };
        (0..self.axes).all(|i| {
            dir.0[i] == 0.0 || (self.sent_steps[0].0[i] == 0.0 && self.sent_steps[1].0[i] == 0.0)
        })
    }

    /// At rest (the commanded position equals the raw one): both filters may be re-sized for
    /// the dynamics of what comes next; their history is all this one point. Returns whether
    /// the raw position may move this tick: a re-sized jerk filter forgets the speeds it gave
    /// out, so it waits until the old one's last two were 0 (`still_ticks` > m). Its jerk is
    /// (a(n) − a(n−m))/(m·Ts) only over one m, and a departure one tick early took the
    /// path jerk to 1.0000017 × J after a braking tail of 8 nm (F600, 0.42 mm then 0.01 mm).
    /// The axis filter forgets the steps it gave out too: it is re-sized once a departure
    /// adds no jerk to them (`departure_adds_no_jerk`).
    fn resize_filters_at_rest(&mut self) -> bool {
        let n =
            usize::from(self.seg(self.raw_seg).axis_filter_ticks).clamp(1, AXIS_FILTER_MAX_TICKS);
        if n != self.axis_window_ticks {
            if !self.departure_adds_no_jerk(self.seg(self.raw_seg)) {
                return false;
            }
            self.axis_hist_in.fill(self.path_pos);
            self.axis_hist_mid.fill(self.path_pos);
            self.axis_window_ticks = n;
        }
        if self.jbox_refused && self.raw_s() != self.jbox_refused_s {
            self.jbox_refused = false;
        }
        // (The jerk-limited box runs with the jerk filter out: `jerk_box`.)
        let for_box = self.jbox_wanted();
        let m = if for_box { 1 } else { self.filter_for() };
        if m != self.jerk_filter_ticks {
            if self.still_ticks <= self.jerk_filter_ticks {
                return false;
            }
            let s = self.raw_s();
            self.hist_raw_s_mm.fill(s);
            self.hist_raw_slot.fill(self.idx(self.raw_seg));
            self.hist_cap_mm_s.fill(f64::INFINITY);
            self.hist_feed_mm_s.fill(f64::INFINITY);
            self.still_ticks = FILTER_MAX_TICKS;
            self.ticks_since_accel = FILTER_MAX_TICKS;
            self.jerk_filter_ticks = m;
        }
        self.jbox_filter_out = for_box;
        true
    }

    /// This tick's speed limits (SPEC §7.2: the envelope speed never exceeds a junction's
    /// speed; §7.3: with the filters, the caps hold `cap_zone_ticks` early and late):
    /// - hard: segment ceiling, caps of the last ticks, and for each cap ahead at distance d
    ///   the highest speed still able to brake to it, `max(v_cap, v_brake(d − v_cap·lag))`;
    /// - soft: feed × override, braked for the same way.
    ///
    /// The look-ahead stops at the first stop point, or once the remaining distance exceeds
    /// the braking reach `v²/(2a) + 2v·Ts + v·lag` (no cap beyond can bind this tick).
    fn speed_limits(&mut self, head: &Segment, accel_mm_s2: f64, braking: bool) -> SpeedLimits {
        let a_floor = self.accel_floor();
        let lag_s = self.cap_zone_ticks() as f64 * TS_S;
        let mut walk = self.caps_here(head, braking);
        let here = (walk.hard, walk.soft);
        let v_up = self.raw_v_mm_s + accel_mm_s2 * TS_S;
        let coast_accel = walk.coast_accel;
        // Caps farther than this cannot constrain this tick (braking distance at `a_walk`).
        let reach = |a_walk: f64| {
            v_up * v_up / (2.0 * a_walk) + (2.0 + coast_accel) * v_up * TS_S + v_up * lag_s
        };
        let mut d = head.length_mm - self.raw_in_seg_mm;
        let mut stop_dist_mm = f64::INFINITY;
        let mut a_walk = accel_mm_s2;
        let mut reach_mm = reach(a_floor.min(a_walk));
        // (The segments' fields from the compact table `ahead`: reading ~300 full segments
        // per tick on a dense path cost cache misses.)
        let mut k = self.raw_seg;
        'walk: while k < self.len {
            if k > self.raw_seg
                && self.idx(k).is_multiple_of(GROUP)
                && k + GROUP < self.len
                && self.group_clear(k, &walk, d, a_walk, lag_s, braking)
            {
                // No cap of this group can lower a limit (`ahead::group_bound_clear`): only
                // the distances and accelerations of the walk move on.
                for _ in 0..GROUP {
                    let a_seg = self.walk_accel(&self.ahead[self.idx(k)], braking);
                    if a_seg < a_walk {
                        a_walk = a_seg;
                        reach_mm = reach(a_floor.min(a_walk));
                    }
                    if d > reach_mm {
                        break 'walk;
                    }
                    k += 1;
                    d += self.ahead[self.idx(k)].length_mm;
                }
                continue;
            }
            let seg = &self.ahead[self.idx(k)];
            if k > self.raw_seg {
                let a_seg = self.walk_accel(seg, braking);
                if a_seg < a_walk {
                    a_walk = a_seg;
                    reach_mm = reach(a_floor.min(a_walk));
                }
            }
            let next = (k + 1 < self.len).then(|| &self.ahead[self.idx(k + 1)]);
            let (hard_cap, soft_cap, lead_s) = self.caps_at_end(seg, next, lag_s);
            walk.limit(d, hard_cap, soft_cap, lead_s, a_walk);
            if hard_cap == 0.0 {
                stop_dist_mm = d;
                break;
            }
            if d > reach_mm {
                break;
            }
            d += next.map_or(0.0, |n| n.length_mm);
            k += 1;
        }
        let linear = lag_s == 0.0 && walk.coast == 0.0 && walk.coast_accel == 0.0;
        let limits = walk.finish(stop_dist_mm);
        if linear {
            self.with_piecewise(limits, accel_mm_s2, braking, here)
        } else {
            limits
        }
    }

    /// The linear profile's `limits` raised to the piecewise curve where the exact one brakes
    /// (issue #32; `here`: the limits before any cap ahead).
    fn with_piecewise(
        &mut self,
        mut limits: SpeedLimits,
        accel_mm_s2: f64,
        braking: bool,
        here: (f64, f64),
    ) -> SpeedLimits {
        let keep = self.raw_v_mm_s;
        let exact = (limits.hard_mm_s, limits.soft_mm_s);
        // (Where the exact limit is within 0.1 % of this tick's speed the piecewise one can
        // gain no more than that: left out, the reference paths take the same time and the
        // dense circle walks it on far fewer ticks, p50 54 k → 25 k instructions.)
        let slack = keep * (1.0 - 1e-3);
        let brakes = exact.0 < slack || exact.1 < slack;
        if brakes && let Some(pw) = self.piecewise_limits(accel_mm_s2, braking, here, exact) {
            // The piecewise curve (issue #32) lets the speed fall later and by each tick's
            // own acceleration, but never rise above the exact curve: a tick accelerates only
            // where the smallest acceleration on the way allows it, as before (the lines'
            // budgets hold their turns' normal acceleration at the speeds planned; running
            // faster there through an accelerating tick took an axis of the random arcs to
            // 1.08 × its limit; so it is walked only where the exact curve brakes). Linear
            // profile: both limits of a pair are the same.
            limits.hard_mm_s = limits.hard_mm_s.max(pw.hard.min(keep));
            limits.soft_mm_s = limits.soft_mm_s.max(pw.soft.min(keep));
            limits.hard_accel_mm_s = limits.hard_mm_s;
            limits.soft_accel_mm_s = limits.soft_mm_s;
        }
        limits
    }

    /// The limits before any cap ahead: soft, feed × override of this and later segments
    /// (nothing when braking); hard, geometric ceilings, planned end speeds, end of the buffer.
    fn caps_here(&self, head: &Segment, braking: bool) -> CapWalk {
        let (behind_cap, behind_feed) = self.behind_caps();
        let soft = if braking {
            0.0
        } else {
            self.ceiling(head).min(behind_feed * self.override_factor)
        };
        let hard = head.v_max_mm_s.min(behind_cap).min(self.entry_cap_mm_s);
        let (coast, coast_accel) = self.coast_gaps(head);
        CapWalk {
            soft,
            hard,
            soft_acc: soft,
            hard_acc: hard,
            coast,
            coast_accel,
        }
    }

    /// The acceleration the look-ahead brakes with on a later segment `seg`.
    pub(super) fn walk_accel(&self, seg: &Ahead, braking: bool) -> f64 {
        let a = if braking {
            seg.stop_accel_mm_s2
        } else {
            seg.accel_mm_s2
        };
        self.raw_accel_j(a, seg.jerk_mm_s3)
    }

    /// The caps at the end of `seg` (hard, soft) and how long before them they hold: a stop
    /// point (0, 0, 0) at the end of the buffer or where the segment ends at rest.
    pub(super) fn caps_at_end(
        &self,
        seg: &Ahead,
        next: Option<&Ahead>,
        lag_s: f64,
    ) -> (f64, f64, f64) {
        match next {
            Some(n) if seg.v_end_mm_s > 0.0 => (
                self.end_cap_parts(seg.v_end_mm_s, seg.junction_cap_mm_s)
                    .min(n.v_max_mm_s),
                self.ceiling_of(n),
                lag_s,
            ),
            _ => (0.0, 0.0, 0.0),
        }
    }

    /// Hard cap at the end of a segment that is not a stop point. Its planned end speed is
    /// the junction's criteria cap or lower where the planner brakes there for later caps
    /// (continuous time, per-segment accelerations). In the linear profile the look-ahead of
    /// `speed_limits` brakes for those later caps itself, exactly in discrete time, with the
    /// smallest acceleration on the way, and the end of the buffer is a stop: the junction's
    /// own cap is enough. (Capping every tick at the braking curve's junction speeds made
    /// each junction of a braking zone cost part of a tick: the tick before a cap runs at the
    /// cap.) The parabolic filters keep the planned end speeds.
    fn end_cap_mm_s(&self, seg: &Segment) -> f64 {
        self.end_cap_parts(seg.v_end_mm_s, seg.junction_cap_mm_s)
    }

    fn end_cap_parts(&self, v_end_mm_s: f64, junction_cap_mm_s: f64) -> f64 {
        if self.filtered() {
            return v_end_mm_s;
        }
        v_end_mm_s.max(junction_cap_mm_s)
    }

    /// Smallest raw acceleration of the segments the next tick covers at speeds up to `v_up`,
    /// starting with `a` (the raw segment's): the velocity change of a tick is along the
    /// chord of that tick, and the planner gives each segment the tangential acceleration
    /// the turns near it leave (a segment next to a turn may have less than its neighbour).
    fn accel_over_next_tick(&self, a: f64, v_up: f64, braking: bool) -> f64 {
        let mut a = a;
        let mut d = self.seg(self.raw_seg).length_mm - self.raw_in_seg_mm;
        let reach = v_up * TS_S;
        let mut k = self.raw_seg + 1;
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

    /// Next raw speed `v' = max(0, min(hard, max(v − a·Ts, min(soft, v + a·Ts))))`: toward
    /// the soft limit within ±a·Ts, never above the hard one (SPEC §7.2); a tick that
    /// accelerates also keeps the limits with the coast gap after it (parabolic). The raw position
    /// then moves `v'·Ts`, or exactly onto a stop point once that step fits within the
    /// deceleration. Returns the caps (hard, feed) met, mm/s.
    fn advance_raw(&mut self, head: &Segment, accel_mm_s2: f64, limits: SpeedLimits) -> (f64, f64) {
        let v = self.raw_v_mm_s;
        let braking = matches!(self.state, InterpState::Holding | InterpState::Stopping);
        // Parabolic profile: the acceleration may differ by at most J·m·Ts from the one m
        // ticks before (`jerk_filter`); linear: ±a.
        let (down_mm_s2, up_mm_s2) = self.jerk_accel_window(accel_mm_s2, head);
        let inside = std::mem::take(&mut self.raw_step_inside);
        let a_up = self
            .accel_over_next_tick(accel_mm_s2, v + accel_mm_s2 * TS_S, braking)
            .min(up_mm_s2);
        let up = (v + a_up * TS_S)
            .max(self.free_up_mm_s(head, inside, braking))
            .max(self.ends_up_mm_s(head, inside, braking))
            .min(limits.soft_accel_mm_s)
            .min(limits.hard_accel_mm_s);
        // (A tick inside a line brakes toward a soft limit at the line's free acceleration,
        // as the piecewise curve assumes there: `piecewise::stretches`.)
        let down_mm_s2 = down_mm_s2
            .max(self.free_down_mm_s2(head, inside, braking))
            .max(self.ends_down_mm_s2(head, inside, braking));
        let mut v_next = if up > v {
            up
        } else {
            v.min(limits.soft_mm_s)
                .max(v - down_mm_s2 * TS_S)
                .min(limits.hard_mm_s)
                .max(0.0)
        };
        // Arrive exactly at a stop point once the last step fits inside the deceleration limit.
        let stop_dist = limits.stop_dist_mm;
        let mut ds = v_next * TS_S;
        if stop_dist <= (accel_mm_s2 * TS_S * TS_S).max(ARRIVE_EPS_MM)
            && stop_dist <= ds.max(ARRIVE_EPS_MM)
        {
            ds = stop_dist;
            v_next = ds / TS_S;
        }
        if let Some(box_ds) = self.box_hand_back(ds, (limits.hard_mm_s, limits.soft_mm_s)) {
            return self.advance_raw_by(head, accel_mm_s2, box_ds);
        }
        if v_next <= 0.0 && stop_dist > ARRIVE_EPS_MM {
            self.raw_v_mm_s = 0.0;
            return (head.v_max_mm_s, self.feed_of(head));
        }
        self.raw_v_mm_s = v_next;
        let caps = self.move_raw(ds);
        self.note_arrival(v_next, accel_mm_s2);
        caps
    }

    /// Moves the raw position by the step `ds` the per-axis box chose (`setpoint_box`), as
    /// `advance_raw` does with its own: a step of 0 rests where the box's proof came to rest.
    pub(super) fn advance_raw_by(
        &mut self,
        head: &Segment,
        accel_mm_s2: f64,
        ds: f64,
    ) -> (f64, f64) {
        self.raw_step_inside = false;
        if ds <= 0.0 {
            self.raw_v_mm_s = 0.0;
            return (head.v_max_mm_s, self.feed_of(head));
        }
        let v_next = ds / TS_S;
        self.raw_v_mm_s = v_next;
        let caps = self.move_raw(ds);
        self.note_arrival(v_next, accel_mm_s2);
        caps
    }

    /// After a raw step of `v_next` that may have arrived at a stop point: what the next
    /// tick may leave it with. The envelope's departure cap; and the box judges the departure
    /// exactly (the second difference across the stop point), so where it judges the segment
    /// after a plain stop the path may leave in the next tick whatever the arrival step
    /// (`setpoint_box::box_step`).
    fn note_arrival(&mut self, v_next: f64, accel_mm_s2: f64) {
        if self.raw_at_stop {
            self.entry_cap_mm_s = self.departure_cap_mm_s(v_next, accel_mm_s2);
            self.box_departs =
                self.plain_stop() && self.box_slots[self.idx(self.raw_seg + 1)].boxed;
        }
    }

    /// Path acceleration of the next tick when its step and the last one stay inside the
    /// line `head` (0 otherwise; linear profile, not braking). The second difference of
    /// the setpoints at the tick point σ between the steps s_n−1 and s_n is
    /// (s_n − s_n−1)·u(σ) plus, for each junction j within the two steps, its turn Δu_j
    /// weighted by the part of the step beyond it; with no junction there, each axis
    /// changes by (s_n − s_n−1)·u_k ≤ a·Ts²·|u_k|, within a_k for a ≤ min a_k/|u_k|.
    /// `last_inside`: the last step stayed inside `head`. Returns the highest next speed
    /// by it (0 where it does not apply), within the speeds the line's acceleration was
    /// planned for (`Segment::free_accel_v_max_mm_s`).
    fn free_up_mm_s(&self, head: &Segment, last_inside: bool, braking: bool) -> f64 {
        if !last_inside || braking || self.filtered() || !matches!(head.path, SegPath::Line { .. })
        {
            return 0.0;
        }
        let up = (self.raw_v_mm_s + head.free_accel_mm_s2 * TS_S).min(head.free_accel_v_max_mm_s);
        let rest = head.length_mm - self.raw_in_seg_mm;
        if up * TS_S < rest - ARRIVE_EPS_MM {
            up
        } else {
            0.0
        }
    }

    /// Path deceleration of the next tick when its step (at most this tick's) and the last
    /// one stay inside the line `head`: the line's free acceleration, as in
    /// `free_up_mm_s` (0 otherwise).
    fn free_down_mm_s2(&self, head: &Segment, last_inside: bool, braking: bool) -> f64 {
        if !last_inside || braking || self.filtered() || !matches!(head.path, SegPath::Line { .. })
        {
            return 0.0;
        }
        let rest = head.length_mm - self.raw_in_seg_mm;
        if self.raw_v_mm_s * TS_S < rest - ARRIVE_EPS_MM {
            head.free_accel_mm_s2
        } else {
            0.0
        }
    }

    /// Whether the per-end budgets of line `head` apply (linear profile, not braking).
    fn ends_apply(&self, head: &Segment, braking: bool) -> bool {
        !braking
            && !self.filtered()
            && matches!(head.path, SegPath::Line { .. })
            && (head.accel_start_mm_s2 > head.accel_mm_s2
                || head.accel_end_mm_s2 > head.accel_mm_s2)
    }

    /// Highest next speed of an accelerating tick whose steps touch only one junction of
    /// the line `head` (0 otherwise): the last step crossed its start junction and the next
    /// one stays inside it (`Segment::accel_start_mm_s2`), or the last step stayed inside
    /// and the next one reaches its end junction (`accel_end_mm_s2`, and the segments
    /// that step reaches, as `accel_over_next_tick`). The second difference at the tick
    /// point then holds the turns of that junction only (issue #32).
    fn ends_up_mm_s(&self, head: &Segment, last_inside: bool, braking: bool) -> f64 {
        if !self.ends_apply(head, braking) {
            return 0.0;
        }
        let v = self.raw_v_mm_s;
        let rest = head.length_mm - self.raw_in_seg_mm;
        if !last_inside {
            let a = self.end_raw_accel(head.accel_start_mm_s2, head.accel_mm_s2, head.jerk_mm_s3);
            let up = v + a * TS_S;
            if up * TS_S < rest - ARRIVE_EPS_MM {
                up
            } else {
                0.0
            }
        } else {
            let a = self.end_raw_accel(head.accel_end_mm_s2, head.accel_mm_s2, head.jerk_mm_s3);
            let a = self.accel_over_next_tick(a, v + a * TS_S, false);
            v + a * TS_S
        }
    }

    /// Path deceleration of a tick toward a soft limit whose steps touch only one junction
    /// of the line `head` (its step at most this tick's), as in `ends_up_mm_s` (0
    /// otherwise): what the piecewise curve assumes there (`piecewise::stretches`).
    fn ends_down_mm_s2(&self, head: &Segment, last_inside: bool, braking: bool) -> f64 {
        if !self.ends_apply(head, braking) {
            return 0.0;
        }
        let v = self.raw_v_mm_s;
        let rest = head.length_mm - self.raw_in_seg_mm;
        let inside = v * TS_S < rest - ARRIVE_EPS_MM;
        match (last_inside, inside) {
            (false, true) => {
                self.end_raw_accel(head.accel_start_mm_s2, head.accel_mm_s2, head.jerk_mm_s3)
            }
            (true, false) => {
                let a = self.end_raw_accel(head.accel_end_mm_s2, head.accel_mm_s2, head.jerk_mm_s3);
                self.accel_over_next_tick(a, v, false)
            }
            _ => 0.0,
        }
    }

    /// Arrived at a stop point in this tick at `v_arrive`: the highest speed of the first
    /// tick that leaves it in the next tick (∞: not allowed, the raw position rests a tick).
    /// Only for a plain stop (no dwell, G24, program stop or spindle change there) of the
    /// linear profile (no filter to settle). Per axis k the velocity changes by
    /// |v_d·u_out,k − v_a·u_in,k| ≤ v_d·|u_out,k| + v_a·|u_in,k| ≤ a_k·(v_d/a_out + v_a/a_in)
    /// (a segment's path acceleration is within a_k/|u_k| of every axis it moves), so
    /// v_d ≤ a_out·(Ts − v_a/a_in) keeps every axis within its limit, whatever the turn.
    fn departure_cap_mm_s(&self, v_arrive: f64, a_head: f64) -> f64 {
        if !self.plain_stop() {
            return f64::INFINITY;
        }
        let (here, next) = (self.seg(self.raw_seg), self.seg(self.raw_seg + 1));
        let a_in = a_head.min(self.raw_accel(here.accel_mm_s2, here));
        let a_out = self.raw_accel(next.accel_mm_s2.min(next.stop_accel_mm_s2), next);
        let cap = a_out * (TS_S - v_arrive / a_in);
        // An arrival at the full step leaves nothing of the tick: rest it (a cap of 0 would
        // hold the raw position without ever moving on).
        if cap > 1e-6 * a_out * TS_S {
            cap
        } else {
            f64::INFINITY
        }
    }

    /// The stop point at the end of segment `raw_seg` is a plain one, left as soon as the
    /// path has arrived (linear profile; no dwell, G24, program stop or spindle change
    /// there, and a segment after it).
    fn plain_stop(&self) -> bool {
        if self.raw_seg + 1 >= self.len || self.filtered() {
            return false;
        }
        let (here, next) = (self.seg(self.raw_seg), self.seg(self.raw_seg + 1));
        here.dwell_s <= 0.0
            && !here.wait_in_position
            && here.spindle_after.is_none()
            && !self.stops_here(here.program_stop)
            && !self.stops_here(next.program_stop_before)
            && !next.spindle.outputs.touched
            && next.spindle.outputs.wait == 0
            && next.dwell_before_s <= 0.0
    }

    /// Moves the raw position `ds` along the buffered path. Returns the smallest hard cap and
    /// feed met on the way (segment ceilings and junction speeds).
    pub(super) fn move_raw(&mut self, mut ds: f64) -> (f64, f64) {
        let first = *self.seg(self.raw_seg);
        self.raw_step_inside = ds < first.length_mm - self.raw_in_seg_mm - ARRIVE_EPS_MM;
        let mut cap = first.v_max_mm_s;
        let mut feed = self.feed_of(&first);
        self.entry_cap_mm_s = f64::INFINITY;
        loop {
            let seg = *self.seg(self.raw_seg);
            let rest = seg.length_mm - self.raw_in_seg_mm;
            if ds < rest - ARRIVE_EPS_MM {
                if self.raw_in_seg_mm == 0.0 && ds <= ARRIVE_EPS_MM {
                    // Ended on the junction just crossed.
                    self.entry_cap_mm_s = cap;
                }
                self.raw_in_seg_mm += ds;
                return (cap, feed);
            }
            ds -= rest;
            self.raw_in_seg_mm = seg.length_mm;
            if seg.v_end_mm_s == 0.0 || self.raw_seg + 1 >= self.len {
                // A stop point: never carry distance past it.
                self.raw_at_stop = true;
                self.raw_v_mm_s = 0.0;
                self.dwell_ticks = (seg.dwell_s / TS_S).round().max(0.0) as u32;
                return (cap, feed);
            }
            let next = *self.seg(self.raw_seg + 1);
            cap = cap.min(self.end_cap_mm_s(&seg)).min(next.v_max_mm_s);
            feed = feed.min(self.feed_of(&next));
            self.raw_seg += 1;
            self.raw_in_seg_mm = 0.0;
        }
    }
}

/// Whether two segments come from one block: the same `seq` and line (a restart's approach
/// has block N's `seq` with line 0, see `block_stop_at`).
fn same_block(a: &Segment, b: &Segment) -> bool {
    a.seq == b.seq && a.line == b.line
}
