//! The jerk-limited box (parabolic profile, issue #49; docs/planner.md, *The jerk-limited
//! box*): the per-axis box of the linear profile (`setpoint_box`) for the profile with a jerk.
//!
//! Each tick the raw stage chooses the next raw setpoint on the path (an arc length), with the
//! jerk filter out (one tick) and the axis filter (`axis_filter`) after it, so the setpoints
//! the drives see are the axis filter's output `q`. A raw setpoint is taken only where
//! - every axis keeps its acceleration and jerk in `q` (second and third differences), and `q`
//!   stays within half R384's Lm of the path (the corners the axis filter rounds, the arcs it
//!   cuts);
//! - the raw arc length keeps the path's acceleration and jerk (the constants' A and P within
//!   the axes), each segment's ceiling and feed × override, the manual's criteria speed of
//!   every junction it crosses (R384, R385), and never passes a stop point;
//! - a braking from it proves that the motion can come to rest within all of the above: the
//!   raw acceleration falls at P to at most −A and rises back to 0 as the speed reaches 0
//!   (the time-optimal stop of a jerk-limited path, `stop_accel`), and the axis filter
//!   settles (`jbox_brake`).
//!
//! The braking is a function of the last raw setpoints only (its limits are those of the
//! segment the motion left rest on, `Interpolator::jbox_brake`, times the share its proof
//! passed with: on a curve the normal acceleration takes part of the axes, so a proof tries
//! the full limits, then half, then a quarter, `BRAKE_SHARES`), so the braking of the last
//! accepted proof is its next step from here (`jbox_brake_next`): it is taken where no search
//! finds a farther setpoint, which keeps every tick within the limits. Each tick tries the
//! farthest setpoint the path limits allow, a guess that follows the last tick's find, then
//! halving (`RUNS` proofs, as the linear box's `box_search`); the proofs of a tick fail after
//! `TICK_CHECKS` checks of the axes together. On one line each axis moves as the arc length
//! times its direction cosine, so where every raw setpoint the check reads lies on one line
//! the path's own limits hold for the axes (A and P are within the lowest axis's,
//! `plan::BoxJerk`) and the axes are not computed (the rapids' long brakings cost arithmetic
//! only). The speed of each axis is within its limit because every raw step keeps the ceiling
//! of each segment it runs on.
//!
//! The box starts from rest with the jerk filter at one tick (`Interpolator::jbox_wanted`;
//! a line from a stop to a stop is the envelope's) and hands the motion to the envelope at
//! rest when it finds no step from there (`REFUSE_TICKS`): the envelope then sizes its jerk
//! filter and leaves. The segments the checks read stay buffered until the raw setpoints
//! have left them (`jbox_keep_from_s`).

use super::ahead::GROUP;
use super::{
    ARRIVE_EPS_MM, AXIS_FILTER_MAX_TICKS, BUFFER_SEGMENTS, FILTER_MAX_TICKS, InterpState,
    Interpolator,
};
use crate::plan::{SegPath, Segment};
use crate::units::{AxesMm, TS_S};

/// Proofs one tick may run while it searches (the first tries the farthest setpoint).
const RUNS: usize = 3;
/// Checks of the axes the proofs of one tick may make together (a braking on one line needs
/// none): the tick's cost is bounded by it. A braking from F6000 on the dense reference paths
/// needs about 60; 128 instead changes their times by less than 1 %.
const TICK_CHECKS: usize = 72;
/// Braking ticks one proof may simulate (333 mm/s to rest at 500 mm/s² and 25 000 mm/s³
/// takes about 180).
const PROOF_TICKS: usize = 1024;
/// A speed this low is rest, mm/s.
const REST_MM_S: f64 = 1e-9;
/// The share of the path's acceleration and jerk a braking uses (the rest of the rounding).
const BRAKE_SHARE: f64 = 1.0 - 1e-6;
/// The shares of them a proof's braking tries, in turn.
const BRAKE_SHARES: [f64; 3] = [1.0, 0.5, 0.25];
/// Relative slack of each limit: a limit met exactly is not passed by rounding.
const ROUNDING: f64 = 1e-9;
/// Guesses of the search, as fractions of the way from the kept braking's setpoint to the
/// farthest (which has just failed): the range, and the step above the last find.
const GUESS_MIN: f64 = 1.0 / 16.0;
const GUESS_MAX: f64 = 15.0 / 16.0;
const GUESS_STEP: f64 = 1.0 / 16.0;
/// Ticks at rest with a step wanted and none proven before the envelope takes the motion.
const REFUSE_TICKS: u32 = 3;
/// Raw arc lengths a track keeps (a power of two above the `2n + 1` a check reads).
const S_RING: usize = 64;
const _: () = assert!(S_RING > 2 * AXIS_FILTER_MAX_TICKS + 1 && S_RING <= FILTER_MAX_TICKS);
const _: () = assert!(BUFFER_SEGMENTS <= u16::MAX as usize);

/// The state a step of the box depends on: the last raw arc lengths, the axis filter's rings
/// (as `axis_filter` keeps them) and the last four setpoints. A proof advances a copy.
#[derive(Clone, Copy, Debug)]
pub(super) struct Track {
    s: [f64; S_RING],
    /// The segment of each raw arc length (the ring of `s`).
    ks: [u16; S_RING],
    s_newest: usize,
    inp: [AxesMm; AXIS_FILTER_MAX_TICKS],
    mid: [AxesMm; AXIS_FILTER_MAX_TICKS],
    newest: usize,
    /// The last four setpoints, a ring whose newest is at `q_newest` (a third difference
    /// reads them).
    q: [AxesMm; 4],
    q_newest: usize,
    /// The segment of the newest raw arc length.
    k: usize,
    /// Ticks per stage of the axis filter.
    n: usize,
}

impl Track {
    /// The raw arc length `j` ticks back (0: the newest).
    fn back(&self, j: usize) -> f64 {
        self.s[(self.s_newest + S_RING - j) % S_RING]
    }

    /// The segment of the raw arc length `j` ticks back.
    fn k_back(&self, j: usize) -> usize {
        usize::from(self.ks[(self.s_newest + S_RING - j) % S_RING])
    }

    fn speed_mm_s(&self) -> f64 {
        (self.back(0) - self.back(1)) / TS_S
    }

    fn accel_mm_s2(&self) -> f64 {
        (self.back(0) - 2.0 * self.back(1) + self.back(2)) / (TS_S * TS_S)
    }

    /// Appends raw setpoint `p` at arc length `s` on segment `k`: the axis filter's output, as
    /// `Interpolator::smooth_axes` computes it.
    fn push(&mut self, s: f64, k: usize, p: AxesMm, axes: usize) {
        self.s_newest = (self.s_newest + 1) % S_RING;
        self.s[self.s_newest] = s;
        self.ks[self.s_newest] = k as u16;
        self.k = k;
        let q = if self.n <= 1 {
            p
        } else {
            // Each mean moves by (newest − the one leaving)/n: a few ulp from the axis
            // filter's own sums over a proof, far below the rounding slack of the limits.
            let (n, inv) = (self.n, 1.0 / self.n as f64);
            let last = self.newest;
            self.newest = (self.newest + 1) % AXIS_FILTER_MAX_TICKS;
            let leaving = (self.newest + AXIS_FILTER_MAX_TICKS - n) % AXIS_FILTER_MAX_TICKS;
            let (old_in, old_mid) = (self.inp[leaving], self.mid[leaving]);
            self.inp[self.newest] = p;
            let mut mid = self.mid[last];
            let mut q = self.q[self.q_newest];
            for ax in 0..axes {
                mid.0[ax] += (p.0[ax] - old_in.0[ax]) * inv;
                q.0[ax] += (mid.0[ax] - old_mid.0[ax]) * inv;
            }
            self.mid[self.newest] = mid;
            q
        };
        self.q_newest = (self.q_newest + 1) % 4;
        self.q[self.q_newest] = q;
    }
}

/// What the box reads of a buffered segment, kept at push time in a compact table
/// (`Interpolator::jbox_slots`; a step on a dense path crosses several segments, each read
/// once): the `Segment` itself is read only for its path.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct JerkSlot {
    /// The box judges it (`BoxJerk::is_set` and `BoxAccel::is_set`).
    pub set: bool,
    pub line: bool,
    /// It ends at a stop point (`Segment::v_end_mm_s` 0; single block may make it one).
    pub stop_end: bool,
    /// Its feed is `feed_mm_s` as programmed (not a rapid, not per revolution).
    pub plain_feed: bool,
    pub limits: PathLimits,
    /// `BoxJerk::off_mm`.
    pub off_mm: f64,
    pub length_mm: f64,
    pub feed_mm_s: f64,
    /// The longest step on it, and the longest that crosses or ends on its end junction (its
    /// criteria speed), mm (with the rounding slack).
    pub v_max_step_mm: f64,
    pub crit_step_mm: f64,
}

impl JerkSlot {
    pub(super) fn of(seg: &Segment) -> Self {
        let b = &seg.axis_box;
        let step = |v_mm_s: f64| v_mm_s * TS_S * (1.0 + ROUNDING);
        JerkSlot {
            set: b.jerk.is_set() && b.accel_mm_s2.is_set(),
            line: matches!(seg.path, SegPath::Line { .. }),
            stop_end: seg.v_end_mm_s == 0.0,
            plain_feed: !seg.rapid && seg.per_rev_nominal_rpm <= 0.0,
            limits: PathLimits::of(seg),
            off_mm: b.jerk.off_mm(),
            length_mm: seg.length_mm,
            feed_mm_s: seg.feed_mm_s,
            v_max_step_mm: step(b.v_max_mm_s),
            crit_step_mm: step(b.criteria_end_mm_s),
        }
    }
}

/// The stop point ahead of the raw position as last found (`Interpolator::jbox_stop_ahead`):
/// `fixed` where it is a stop, not the end of the buffer (which pushes move on).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct StopAhead {
    pub valid: bool,
    pub fixed: bool,
    pub s_mm: f64,
}

/// The path's limits on the raw arc length over one tick on a segment: its acceleration and
/// jerk (mm/s², mm/s³).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct PathLimits {
    a_mm_s2: f64,
    j_mm_s3: f64,
}

impl PathLimits {
    fn of(seg: &Segment) -> Self {
        let j = &seg.axis_box.jerk;
        PathLimits {
            a_mm_s2: j.accel(),
            j_mm_s3: j.path(),
        }
    }

    fn min(self, o: PathLimits) -> Self {
        PathLimits {
            a_mm_s2: self.a_mm_s2.min(o.a_mm_s2),
            j_mm_s3: self.j_mm_s3.min(o.j_mm_s3),
        }
    }
}

/// The feed of a step: each segment's feed × override (`soft`, mm/s per segment) holds, or,
/// where the override was lowered below the speed (`over` > 1: the speed over the feed of the
/// segment it runs on), a speed that falls.
#[derive(Clone, Copy, Debug)]
struct Feed {
    over: f64,
    /// Holding or stopping: the speed only falls.
    braking: bool,
}

impl Feed {
    /// The longest step a segment of feed step `soft` (mm a tick) allows after a step of
    /// `ds_prev`.
    fn room(&self, soft: f64, ds_prev: f64) -> f64 {
        if self.braking {
            ds_prev
        } else if self.over <= 1.0 {
            soft
        } else if soft <= 0.0 {
            ds_prev
        } else {
            soft.max((soft * self.over).min(ds_prev))
        }
    }
}

/// What one search found: the raw setpoint, where its braking rests and the share of the
/// braking's limits it was proven with.
struct Found {
    s: f64,
    rest_s: f64,
    share: f64,
}

/// Why a braking is not proven: it meets a limit, or the checks or ticks run out.
enum Unproven {
    Limit,
    Budget,
}

/// The raw acceleration of the next tick of the time-optimal stop of a path with jerk `j`
/// and acceleration `a_max` from speed `v` and acceleration `a` (mm/s, mm/s², mm/s³): as low
/// as the limits allow while a rise back to 0 at `j` still ends at a speed ≥ 0. Closed form:
/// with the next acceleration −x·j·Ts and m = ⌊x⌋, the rise back ends at
/// v − j·Ts²·(m + 1)·(x − m + m/2).
pub(super) fn stop_accel(v: f64, a: f64, a_max: f64, j: f64) -> f64 {
    let lo = (a - j * TS_S).max(-a_max);
    let hi = (a + j * TS_S).min(a_max);
    if hi < lo {
        // (An acceleration beyond ±a_max by more than a tick's jerk, left by a step or a
        // braking with more of the limits: back toward the range as fast as j allows.)
        return if a < 0.0 { a + j * TS_S } else { a - j * TS_S };
    }
    if end_speed(v, hi, j) < 0.0 {
        return hi;
    }
    // The speed in units of one tick's rise; the largest m with m(m + 1)/2 <= w.
    let w = v / (j * TS_S * TS_S);
    // (`as u64` truncates, the floor of a value ≥ 0, without a call to `floor`.)
    let mut m = ((((1.0 + 8.0 * w).sqrt() - 1.0) / 2.0).max(0.0) as u64) as f64;
    while (m + 1.0) * (m + 2.0) / 2.0 <= w {
        m += 1.0;
    }
    while m > 0.0 && m * (m + 1.0) / 2.0 > w {
        m -= 1.0;
    }
    let x = m + (w / (m + 1.0) - m / 2.0).min(1.0);
    (-x * j * TS_S).max(lo).min(hi)
}

/// The speed once the acceleration, `a` in the next tick, has risen back to 0 at `j`.
fn end_speed(v: f64, a: f64, j: f64) -> f64 {
    if a >= 0.0 {
        return v + a * TS_S;
    }
    let x = -a / (j * TS_S);
    let m = (x as u64) as f64;
    v - j * TS_S * TS_S * (m + 1.0) * (x - m + m / 2.0)
}

impl Interpolator {
    /// The jerk-limited box may choose the raw steps on the segment the raw position lies on
    /// (parabolic profile, a segment it judges, not handed to the envelope here). A line
    /// from a stop to a stop (the planner runs it without the axis filter) is the envelope's:
    /// its filtered profile is the ideal jerk-limited move (within 1.03 of Ruckig), which a
    /// box that proves its brakings to rest approaches only by creeping onto the stop.
    pub(super) fn jbox_wanted(&self) -> bool {
        if self.len == 0 || self.jbox_refused {
            return false;
        }
        let seg = self.seg(self.raw_seg);
        let isolated_line = seg.axis_filter_ticks <= 1 && matches!(seg.path, SegPath::Line { .. });
        !isolated_line && self.jbox_slots[self.idx(self.raw_seg)].set
    }

    /// The box chooses this tick's raw step: wanted, with the jerk filter out.
    pub(super) fn jbox_applies(&self) -> bool {
        self.jerk_filter_ticks == 1 && self.jbox_wanted()
    }

    /// The arc length behind which the box reads no segment (∞ while it does not run): the
    /// oldest raw setpoint a check reads, `2n` ticks back.
    pub(super) fn jbox_keep_from_s(&self) -> f64 {
        if !self.jbox_applies() {
            return f64::INFINITY;
        }
        let back = 2 * self.axis_window_ticks + 1;
        self.hist_raw_s_mm[(self.hist_newest + FILTER_MAX_TICKS - back) % FILTER_MAX_TICKS]
    }

    /// The track of the raw position now.
    fn jbox_track(&self) -> Track {
        let mut s = [0.0; S_RING];
        let mut ks = [0; S_RING];
        // (A check reads `2n` back at most; older entries are overwritten before they are.)
        for j in 0..(2 * self.axis_window_ticks + 3).min(S_RING) {
            let i = (self.hist_newest + FILTER_MAX_TICKS - j) % FILTER_MAX_TICKS;
            // (The newest at the ring's end, `s_newest`.) A segment dropped since is behind
            // the first buffered one: the walks start there.
            s[S_RING - 1 - j] = self.hist_raw_s_mm[i];
            let k = (self.hist_raw_slot[i] + BUFFER_SEGMENTS - self.head) % BUFFER_SEGMENTS;
            ks[S_RING - 1 - j] = if k < self.len { k as u16 } else { 0 };
        }
        let mut inp = [AxesMm::ZERO; AXIS_FILTER_MAX_TICKS];
        let mut mid = [AxesMm::ZERO; AXIS_FILTER_MAX_TICKS];
        inp.copy_from_slice(&self.axis_hist_in[..AXIS_FILTER_MAX_TICKS]);
        mid.copy_from_slice(&self.axis_hist_mid[..AXIS_FILTER_MAX_TICKS]);
        let [p0, p1, p2] = self.sent_points;
        Track {
            s,
            ks,
            s_newest: S_RING - 1,
            inp,
            mid,
            newest: self.axis_newest,
            q: [p2, p2, p1, p0],
            q_newest: 3,
            k: self.raw_seg,
            n: self.axis_window_ticks,
        }
    }

    /// The stop point ahead of the raw position (`jbox_stop_s`), kept across ticks: found
    /// again where it is not known or the raw position has reached it, else as it was (a
    /// step never passes it; segments pushed since extend it at push time,
    /// `jbox_note_pushed`).
    fn jbox_stop_ahead(&mut self, k: usize, s0: f64) -> f64 {
        let known = &self.jbox_stop;
        if !known.valid || known.s_mm <= s0 {
            let s_mm = self.jbox_stop_s(k);
            let fixed = s_mm < self.buffered_end_s_mm;
            self.jbox_stop = StopAhead {
                valid: true,
                fixed,
                s_mm,
            };
        }
        self.jbox_stop.s_mm
    }

    /// A segment was pushed: where the stop point ahead was the end of the buffer, it moves
    /// on to the new segment's end, or stays where a stop comes first.
    pub(super) fn jbox_note_pushed(&mut self) {
        let known = self.jbox_stop;
        if !known.valid || known.fixed {
            return;
        }
        if self.len < 2 {
            self.jbox_stop.valid = false;
            return;
        }
        let (before, new) = (self.idx(self.len - 2), self.idx(self.len - 1));
        if self.jbox_slots[before].stop_end || !self.jbox_slots[new].set {
            self.jbox_stop.fixed = true;
        } else {
            self.jbox_stop.s_mm = self.seg_start_s_mm[new] + self.ahead[new].length_mm;
        }
    }

    /// The arc length of the first stop point from segment `k` on: the end of a segment that
    /// ends at rest, of the last buffered one, or the start of one the box does not judge.
    /// Whole groups without one are crossed at once (`AheadGroup`): at most a few hundred
    /// steps over a full buffer.
    fn jbox_stop_s(&self, k: usize) -> f64 {
        let mut j = k;
        while j < self.len {
            let i = self.idx(j);
            if i.is_multiple_of(GROUP) && j > k && j + GROUP < self.len {
                let g = &self.groups[i / GROUP];
                if g.v_end_mm_s > 0.0 && !g.jerk_unboxed {
                    j += GROUP;
                    continue;
                }
            }
            if j > k && !self.jbox_slots[i].set {
                return self.seg_start_s_mm[i];
            }
            if self.ahead[i].v_end_mm_s == 0.0 || j + 1 >= self.len {
                return self.seg_start_s_mm[i] + self.ahead[i].length_mm;
            }
            j += 1;
        }
        self.buffered_end_s_mm
    }

    /// Feed × override of a segment now, mm/s.
    fn jbox_soft(&self, k: usize) -> f64 {
        let i = self.idx(k);
        let slot = &self.jbox_slots[i];
        let feed = if slot.plain_feed {
            slot.feed_mm_s
        } else {
            self.feed_of_ahead(&self.ahead[i])
        };
        feed * self.override_factor
    }

    /// One step of the box: advances track `t` to raw arc length `s_new` and tells whether
    /// the step is within every limit (where it is not, `t` is left part-way: a proof drops
    /// it then). `checks` counts the steps whose axes were computed.
    fn jbox_advance(&self, t: &mut Track, s_new: f64, feed: &Feed, checks: &mut usize) -> bool {
        self.jbox_advance_within(t, s_new, feed, checks).is_some()
    }

    fn jbox_advance_within(
        &self,
        t: &mut Track,
        s_new: f64,
        feed: &Feed,
        checks: &mut usize,
    ) -> Option<()> {
        let (s0, s1, s2) = (t.back(0), t.back(1), t.back(2));
        let s_new = self.jbox_snap(t, s_new);
        let ds = s_new - s0;
        // (A NaN step is refused too.)
        if ds.is_nan() || ds < -1e-12 {
            return None;
        }
        // The segments the step runs on: ceilings, feeds, junction criteria, stop points.
        let ds_prev = s0 - s1;
        let fits = |j: usize, slot: &JerkSlot| {
            slot.set
                && ds <= slot.v_max_step_mm
                && ds <= feed.room(self.jbox_soft(j) * TS_S, ds_prev) * (1.0 + ROUNDING) + 1e-12
        };
        let mut k = t.k;
        let mut slot = &self.jbox_slots[self.idx(k)];
        if !fits(k, slot) {
            return None;
        }
        let mut lim = slot.limits;
        let mut end_k = self.start_of_seg(k) + slot.length_mm;
        while k + 1 < self.len && end_k < s_new {
            // (Crossing the end junction of segment `k`.)
            if slot.stop_end || (end_k > s0 && ds > slot.crit_step_mm) {
                return None;
            }
            k += 1;
            slot = &self.jbox_slots[self.idx(k)];
            if !fits(k, slot) {
                return None;
            }
            lim = lim.min(slot.limits);
            end_k = self.start_of_seg(k) + slot.length_mm;
        }
        if s_new > end_k + 1e-12 {
            return None;
        }
        // (A step that ends on a junction meets its criteria speed as one that crosses it.)
        let passes = k + 1 < self.len && !slot.stop_end;
        if passes && s_new >= end_k && end_k > s0 && ds > slot.crit_step_mm {
            return None;
        }
        if (s_new - 2.0 * s0 + s1).abs() > lim.a_mm_s2 * TS_S * TS_S * (1.0 + ROUNDING) {
            return None;
        }
        let d3 = s_new - 3.0 * s0 + 3.0 * s1 - s2;
        if d3.abs() > lim.j_mm_s3 * TS_S.powi(3) * (1.0 + ROUNDING) {
            return None;
        }
        let one_line = self.jbox_on_one_line(t, k, s_new);
        t.push(s_new, k, self.box_point(k, s_new), self.axes);
        if one_line {
            return Some(());
        }
        *checks += 1;
        self.jbox_axes_hold(t).then_some(())
    }

    /// A step from track `t` this close to the stop point ahead ends on it, as `move_raw`
    /// takes it.
    fn jbox_snap(&self, t: &Track, s: f64) -> f64 {
        let stop_s = self.jbox_stop_mm;
        if (stop_s - s).abs() <= ARRIVE_EPS_MM && s > t.back(0) {
            stop_s
        } else {
            s
        }
    }

    fn start_of_seg(&self, k: usize) -> f64 {
        self.seg_start_s_mm[self.idx(k)]
    }

    /// Whether every raw setpoint the newest setpoints' third difference reads (`2n + 1`
    /// back from the new one at `s_new`) lies on line `k`: the axes move as the arc length
    /// there, within the path's limits.
    fn jbox_on_one_line(&self, t: &Track, k: usize, s_new: f64) -> bool {
        self.jbox_slots[self.idx(k)].line
            && t.back(2 * t.n) >= self.start_of_seg(k)
            && s_new >= self.start_of_seg(k)
    }

    /// Every axis within its acceleration and jerk at the newest setpoint of `t`, and the
    /// setpoint within the corridor of the path the raw setpoints it averages lie on.
    fn jbox_axes_hold(&self, t: &Track) -> bool {
        let q = |j: usize| &t.q[(t.q_newest + 4 - j) % 4];
        let (q0, q1, q2, q3) = (q(0), q(1), q(2), q(3));
        for ax in 0..self.axes {
            let (a_room, j_room) = self.jbox_axis_room[ax];
            let d2 = q0[ax] - 2.0 * q1[ax] + q2[ax];
            if d2.abs() > a_room {
                return false;
            }
            let d3 = q0[ax] - 3.0 * q1[ax] + 3.0 * q2[ax] - q3[ax];
            if d3.abs() > j_room {
                return false;
            }
        }
        let off = self.jbox_slots[self.idx(t.k)].off_mm;
        if t.n <= 1 || !off.is_finite() {
            return true;
        }
        self.jbox_near_path(t, q0, off)
    }

    /// Whether setpoint `q` lies within `off` of the segments the raw setpoints it averages
    /// lie on (the newest `2n − 1` of track `t`): looked for from the middle one's segment
    /// outwards, where it lies nearest (a helix is judged from the point at its angle, at
    /// least the true distance).
    fn jbox_near_path(&self, t: &Track, q: &AxesMm, off: f64) -> bool {
        let (from, mid, to) = (t.k_back(2 * t.n - 2), t.k_back(t.n - 1), t.k);
        let off2 = off * off;
        let near = |k: usize| distance2_to(&self.seg(k).path, q, self.axes) <= off2;
        if near(mid) {
            return true;
        }
        let (mut lo, mut hi) = (mid, mid);
        while lo > from || hi < to {
            if hi < to {
                hi += 1;
                if near(hi) {
                    return true;
                }
            }
            if lo > from {
                lo -= 1;
                if near(lo) {
                    return true;
                }
            }
        }
        false
    }
}

/// Squared distance of `q` from path `path` over the first `axes` axes, mm²: exact on a
/// line and a plane arc; on a helix from the point at the same angle (not below the exact
/// one).
fn distance2_to(path: &SegPath, q: &AxesMm, axes: usize) -> f64 {
    let dist = |p: &AxesMm| (0..axes).map(|ax| (q[ax] - p[ax]).powi(2)).sum::<f64>();
    match *path {
        SegPath::Line { start, end } => {
            let (mut dot, mut len2) = (0.0, 0.0);
            for ax in 0..axes {
                let u = end[ax] - start[ax];
                dot += (q[ax] - start[ax]) * u;
                len2 += u * u;
            }
            let t = if len2 > 0.0 {
                (dot / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            dist(&start.lerp(&end, t))
        }
        SegPath::Arc {
            start,
            end,
            center,
            plane,
            start_angle_rad,
            sweep_rad,
            ..
        } => {
            let (a, b) = plane.axes();
            let helix = (0..axes).any(|ax| ax != a && ax != b && start[ax] != end[ax]);
            if !helix {
                return planar_arc_distance2(path, q, axes);
            }
            let phi = (q[b] - center[b]).atan2(q[a] - center[a]);
            let tau = std::f64::consts::TAU;
            let mut d = (phi - start_angle_rad) * sweep_rad.signum();
            d = d.rem_euclid(tau);
            if d <= sweep_rad.abs() && sweep_rad != 0.0 {
                dist(&path.point_at(d / sweep_rad.abs()))
            } else {
                dist(&start).min(dist(&end))
            }
        }
    }
}

/// `distance2_to` on an arc in its plane (the other axes fixed), without an angle: whether
/// `q` lies within the sweep is read from the cross products with the radii to its ends.
fn planar_arc_distance2(path: &SegPath, q: &AxesMm, axes: usize) -> f64 {
    let SegPath::Arc {
        start,
        end,
        center,
        plane,
        radius_mm,
        sweep_rad,
        ..
    } = *path
    else {
        unreachable!("planar_arc_distance2 on a line");
    };
    let (a, b) = plane.axes();
    let sign = sweep_rad.signum();
    let radius = |p: &AxesMm| (p[a] - center[a], p[b] - center[b]);
    let (u, v, w) = (radius(&start), radius(&end), radius(q));
    // Positive where `y` lies ahead of `x` in the sweep's direction, within a half turn.
    let ahead = |x: (f64, f64), y: (f64, f64)| (x.0 * y.1 - x.1 * y.0) * sign;
    let turn = sweep_rad.abs();
    let within = if turn >= std::f64::consts::TAU - 1e-9 {
        true
    } else if turn <= std::f64::consts::PI {
        ahead(u, w) >= 0.0 && ahead(w, v) >= 0.0
    } else {
        // (Outside only in the rest of the circle, less than a half turn.)
        !(ahead(v, w) > 0.0 && ahead(w, u) > 0.0)
    };
    let dist = |p: &AxesMm| (0..axes).map(|ax| (q[ax] - p[ax]).powi(2)).sum::<f64>();
    if !within {
        return dist(&start).min(dist(&end));
    }
    let off_plane: f64 = (0..axes)
        .filter(|&ax| ax != a && ax != b)
        .map(|ax| (q[ax] - start[ax]).powi(2))
        .sum();
    (w.0.hypot(w.1) - radius_mm).powi(2) + off_plane
}

impl Interpolator {
    /// The next raw arc length of the time-optimal braking from track `t` (its own setpoint
    /// once at rest), with the path limits of the segment it lies on.
    fn jbox_brake_next(&self, t: &Track, share: f64) -> f64 {
        let (s0, v, a) = (t.back(0), t.speed_mm_s(), t.accel_mm_s2());
        if v <= REST_MM_S && a.abs() <= REST_MM_S / TS_S {
            return s0;
        }
        // (A hair inside the limits: the last tick's speed, rounded to 0, then keeps them.)
        let lim = &self.jbox_brake;
        let share = share * BRAKE_SHARE;
        let (a_max, j) = (lim.a_mm_s2 * share, lim.j_mm_s3 * share);
        let v_next = v + stop_accel(v, a, a_max, j) * TS_S;
        if v_next <= REST_MM_S {
            s0
        } else {
            s0 + v_next * TS_S
        }
    }

    /// Brakes from track `t` as `jbox_brake_next` does with `share` of the limits until the
    /// raw position rests and the axis filter has settled (`2n + 1` ticks at rest), checking
    /// every tick: where it rests, or why not (a limit; the tick's `TICK_CHECKS` checks or
    /// `PROOF_TICKS` ticks run out).
    fn jbox_brake(
        &self,
        mut t: Track,
        (feed, share): (&Feed, f64),
        checks: &mut usize,
    ) -> Result<f64, Unproven> {
        let mut settle = 0;
        for _ in 0..PROOF_TICKS {
            let s0 = t.back(0);
            let s = self.jbox_brake_next(&t, share);
            let resting = s == s0 && t.speed_mm_s() == 0.0;
            if resting {
                settle += 1;
                if settle > 2 * t.n {
                    return Ok(s0);
                }
            }
            if !self.jbox_advance(&mut t, s, feed, checks) {
                return Err(Unproven::Limit);
            }
            if *checks > TICK_CHECKS {
                return Err(Unproven::Budget);
            }
        }
        Err(Unproven::Budget)
    }

    /// A step to `s_try` from track `t` and a braking after it to rest: where that rests.
    fn jbox_proven(&self, t: &Track, s_try: f64, feed: &Feed, checks: &mut usize) -> Option<Found> {
        let mut next = *t;
        if !self.jbox_advance(&mut next, s_try, feed, checks) {
            return None;
        }
        let s = next.back(0);
        // (A braking at the path's full A and P meets the axes' limits on a curve, where the
        // normal acceleration takes part of them: the gentler ones then.)
        for share in BRAKE_SHARES {
            match self.jbox_brake(next, (feed, share), checks) {
                Ok(rest_s) => return Some(Found { s, rest_s, share }),
                Err(Unproven::Budget) => return None,
                Err(Unproven::Limit) => {}
            }
        }
        None
    }

    /// The farthest raw arc length the path's limits allow next from track `t`: the feed's
    /// step (above the feed, after the override was lowered or while holding, the step of the
    /// time-optimal approach to it), the path's acceleration and jerk, and the stop point.
    fn jbox_top(&self, t: &Track, feed: &Feed) -> f64 {
        let (s0, v, a) = (t.back(0), t.speed_mm_s(), t.accel_mm_s2());
        let lim = self.jbox_slots[self.idx(t.k)].limits;
        let brake = &self.jbox_brake;
        let f = if feed.braking {
            0.0
        } else {
            self.jbox_soft(t.k)
        };
        let reach = if v <= f * (1.0 + 1e-12) {
            f
        } else {
            (v + stop_accel(v - f, a, brake.a_mm_s2, brake.j_mm_s3) * TS_S).max(f)
        };
        let (s1, s2) = (t.back(1), t.back(2));
        (s0 + reach * TS_S)
            .min(self.jbox_stop_mm)
            .min(2.0 * s0 - s1 + lim.a_mm_s2 * TS_S * TS_S)
            .min(3.0 * s0 - 3.0 * s1 + s2 + lim.j_mm_s3 * TS_S.powi(3))
    }

    /// The farthest proven raw arc length up to `hi`, from `lo` (the kept braking's, proven):
    /// `hi` itself, then a guess (`jbox_guess`, the fraction of the way that follows what
    /// the last ticks found), then halving; `RUNS` proofs at most.
    fn jbox_search(&mut self, t: &Track, (lo, hi): (f64, f64), feed: &Feed) -> Option<Found> {
        if hi <= lo {
            return None;
        }
        let (mut found, mut at, mut top) = (None, lo, hi);
        // (One count for the tick: the proofs share `TICK_CHECKS`.)
        let mut checks = 0;
        for run in 0..RUNS {
            let m = match run {
                0 => hi,
                1 => lo + self.jbox_guess.clamp(GUESS_MIN, GUESS_MAX) * (hi - lo),
                _ => 0.5 * (at + top),
            };
            match self.jbox_proven(t, m, feed, &mut checks) {
                Some(f) => {
                    found = Some(f);
                    at = m;
                    if run == 0 {
                        break;
                    }
                }
                None => top = m,
            }
        }
        self.jbox_guess = ((at - lo) / (hi - lo) + GUESS_STEP).min(1.0);
        found
    }

    /// The raw step of this tick by the box: the farthest proven setpoint, else the kept
    /// braking's next one. At rest with a step wanted and none proven for `REFUSE_TICKS`,
    /// the motion is handed to the envelope (`jbox_refused`, from the next tick at rest).
    /// Returns the caps (hard, feed) met, as `advance_raw` does.
    pub(super) fn jbox_step(&mut self, accel_mm_s2: f64) -> (f64, f64) {
        let head = *self.seg(self.raw_seg);
        let braking = matches!(self.state, InterpState::Holding | InterpState::Stopping);
        // (Every segment carries the same axes' limits: the configuration's.)
        for ax in 0..self.axes {
            let (acc, jerk) = (&head.axis_box.accel_mm_s2, &head.axis_box.jerk);
            self.jbox_axis_room[ax] = (
                acc.axis(ax) * TS_S * TS_S * (1.0 + ROUNDING),
                jerk.axis(ax) * TS_S.powi(3) * (1.0 + ROUNDING),
            );
        }
        let t = self.jbox_track();
        // (Steps never pass a stop point: the one ahead of the raw position holds for every
        // proof of this tick.)
        self.jbox_stop_mm = self.jbox_stop_ahead(t.k, t.back(0));
        let v = t.speed_mm_s();
        if v == 0.0 && t.accel_mm_s2() == 0.0 {
            // (The braking's limits hold from rest to rest: the braking of a proof is the
            // kept one only if it is computed alike in every tick after.)
            self.jbox_brake = PathLimits::of(&head);
            self.jbox_brake_share = 1.0;
        }
        let soft_here = self.jbox_soft(t.k);
        let feed = Feed {
            over: if soft_here > 0.0 {
                v / soft_here
            } else {
                f64::INFINITY
            },
            braking,
        };
        let lo = self.jbox_snap(&t, self.jbox_brake_next(&t, self.jbox_brake_share));
        let hi = self.jbox_top(&t, &feed);
        let s0 = t.back(0);
        let s = match self.jbox_search(&t, (lo, hi), &feed) {
            Some(found) => {
                self.jbox_rest_s = found.rest_s;
                self.jbox_brake_share = found.share;
                found.s
            }
            None => lo,
        };
        let at_rest = v == 0.0 && t.accel_mm_s2() == 0.0;
        if at_rest && s <= s0 && hi > s0 + 1e-9 && !braking {
            self.jbox_idle_ticks += 1;
            if self.jbox_idle_ticks >= REFUSE_TICKS {
                self.jbox_refused = true;
                self.jbox_refused_s = s0;
            }
        } else {
            self.jbox_idle_ticks = 0;
        }
        self.advance_raw_by(&head, accel_mm_s2, (s - s0).max(0.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::block::{ArcDir, Plane};

    /// The distance to a plane arc without an angle is the one through its angle
    /// (`distance2_to` on a helix whose other axes do not move), on arcs of every sweep.
    #[test]
    fn a_plane_arc_s_distance_needs_no_angle() {
        let mut seed = 7u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..20_000 {
            let c = AxesMm([next() * 10.0, next() * 10.0, 3.0, 0.0, 0.0, 0.0]);
            let r = 0.01 + next() * 5.0;
            let (a0, a1) = (next() * 6.3, next() * 6.3);
            let at = |phi: f64| {
                AxesMm([
                    c[0] + r * phi.cos(),
                    c[1] + r * phi.sin(),
                    3.0,
                    0.0,
                    0.0,
                    0.0,
                ])
            };
            let dir = if next() < 0.5 {
                ArcDir::Ccw
            } else {
                ArcDir::Cw
            };
            let arc = SegPath::arc(at(a0), at(a1), c, Plane::G17, dir);
            let q = AxesMm([
                c[0] + (next() - 0.5) * 4.0 * r,
                c[1] + (next() - 0.5) * 4.0 * r,
                3.0 + (next() - 0.5) * 0.1,
                0.0,
                0.0,
                0.0,
            ]);
            let fast = planar_arc_distance2(&arc, &q, 3);
            let SegPath::Arc {
                start_angle_rad,
                sweep_rad,
                ..
            } = arc
            else {
                unreachable!()
            };
            let phi = (q[1] - c[1]).atan2(q[0] - c[0]);
            let d =
                ((phi - start_angle_rad) * sweep_rad.signum()).rem_euclid(std::f64::consts::TAU);
            let dist = |p: &AxesMm| (0..3).map(|ax| (q[ax] - p[ax]).powi(2)).sum::<f64>();
            let slow = if d <= sweep_rad.abs() {
                dist(&arc.point_at(d / sweep_rad.abs()))
            } else {
                dist(&arc.start()).min(dist(&arc.end()))
            };
            assert!(
                (fast.sqrt() - slow.sqrt()).abs() <= 1e-9 * (1.0 + r),
                "{fast} {slow}"
            );
        }
    }
}
