//! A second braking curve for the look-ahead of the linear profile (issue #32): each cap is
//! braked for with the acceleration of each stretch of the way, not with the smallest one on
//! the whole way.
//!
//! The exact discrete-time curve of `Interpolator::v_brake` brakes with one acceleration; on a
//! dense curve the lines next to each turn keep as little as 20 % of theirs, so braking with
//! the smallest acceleration on the way started far too early. Here the speed w(x) from which
//! a cap c at distance d can still be reached is w(x)² = c² + 2·E(x..d), E the integral of
//! ã, where ã at a point is the smallest acceleration of the segments within one tick's
//! distance W = v_now·Ts of it (a tick's speed change is along the chords of the ticks around
//! it; a braking tick covers no more than this one, and W must not grow from tick to tick). This tick may run at v with v ≤ w(v·Ts): at the end of its own distance it is still
//! on the curve, so it never crosses a cap point faster than the cap. With G(v) = v² +
//! 2·E(0..v·Ts), that is G(v) ≤ c² + 2·E(0..d) =: R: one inversion of G for the smallest R
//! over the caps, no square root per cap.
//!
//! Why the speed never drops by more than the acceleration allows: if the last tick ran at
//! v_n ≤ w(x_n) (x_n its end), the next may run at w(x_n + v·Ts) and w² falls by
//! 2·∫ã ≤ 2·ã_min·v·Ts over that tick's distance, so the speed by at most ã_min·Ts, ã_min the
//! smallest acceleration of the segments the next tick covers (as when accelerating,
//! `Interpolator::accel_over_next_tick`). Where the exact limit is below this tick's speed,
//! the raw stage takes the higher of the two, but not above the speed it runs at: each keeps
//! every cap and falls by at most the acceleration of the tick, so their maximum does too,
//! and a tick still accelerates only where the exact curve allows it (see `speed_limits`).
//!
//! Cost (the tick's p99 on a dense curve): the walk is left as soon as its result certainly
//! cannot exceed the exact limits (`Settled`, from an upper bound of E), and the caps of a
//! group of slots that cannot lower the smallest R are not evaluated
//! (`piecewise_group_clear`); both give the result of the full walk bit for bit.

use super::Interpolator;
use super::ahead::GROUP;
use crate::units::TS_S;

/// Capacity of the window of accelerations and of the points of E within one tick (segments
/// within 2·W and within W); a tick that would need more uses the exact curve alone.
pub(super) const PIECEWISE_SLOTS: usize = 1024;

/// Caps looked at per tick at most (the cost of a tick): past them the walk assumes a stop,
/// which no cap farther can be below (its R = c² + 2·E is at least 2·E there).
pub(super) const PIECEWISE_CAPS: usize = 128;

/// The per-end budgets of a line split its stretches in the piecewise walk only where one
/// of them exceeds the line's budget by this factor (splitting every segment of a dense
/// curve, whose ends differ little, costs the walk).
const ENDS_MIN_GAIN: f64 = 1.01;

/// The limits of the piecewise curve, mm/s: hard, soft.
pub(super) struct Piecewise {
    pub hard: f64,
    pub soft: f64,
}

/// Smallest R = c² + 2·E over the caps beyond one tick at their own speed, and the smallest
/// cap within it.
struct Smallest {
    r: f64,
    direct: f64,
}

impl Smallest {
    const NONE: Smallest = Smallest {
        r: f64::INFINITY,
        direct: f64::INFINITY,
    };

    fn add(&mut self, cap: f64, d: f64, e: f64) {
        if cap * TS_S >= d {
            // A tick at the cap may cross its point: any speed up to the cap keeps it, and
            // G(v) ≤ R gives no more than the cap there.
            self.direct = self.direct.min(cap);
        } else {
            self.r = self.r.min(cap * cap + 2.0 * e);
        }
    }
}

/// What proves, before and while walking, that the piecewise limits cannot exceed the exact
/// ones (`Interpolator::piecewise_upper`): the walk is then left, and the raw stage keeps the
/// exact limits, as it does where the walk's result is below them.
pub(super) struct Settled {
    /// Per limit (hard, soft) a value of R at or below which the inversion gives less than
    /// the exact limit (−∞: none; ∞: the limit is not needed).
    pub(super) r: (f64, f64),
    /// The speeds below the exact limits whose G they are.
    v: (f64, f64),
    /// Upper bound of E at the end of the walk (`pw_hi`'s last).
    e_hi_end: f64,
}

impl Settled {
    /// Thresholds v² (G(v) ≥ v², E ≥ 0) below the exact limits by a margin that covers the
    /// rounding of `g_inverse` (its errors are a few ulps of the speeds and of a·Ts).
    pub(super) fn new(
        need: (bool, bool),
        exact: (f64, f64),
        v_now: f64,
        a_hi: f64,
        e_hi_end: f64,
    ) -> Self {
        let margin = 1e-9 * (v_now + a_hi * TS_S);
        let below = |needed: bool, exact: f64| {
            let v = exact * (1.0 - 1e-9) - margin;
            match (needed, v > 0.0) {
                (false, _) => (f64::INFINITY, 0.0),
                (true, true) => (v * v, v),
                (true, false) => (f64::NEG_INFINITY, 0.0),
            }
        };
        let (h, s) = (below(need.0, exact.0), below(need.1, exact.1));
        Settled {
            r: (h.0, s.0),
            v: (h.1, s.1),
            e_hi_end,
        }
    }

    /// Once E is known over this tick's distance: the thresholds G(v), lowered by 1e-9 for
    /// the rounding of E and G, where that is above v².
    pub(super) fn raise(&mut self, g: impl Fn(f64) -> f64) {
        let up = |r: f64, v: f64| {
            if r.is_finite() && v > 0.0 {
                r.max(g(v) * (1.0 - 1e-9))
            } else {
                r
            }
        };
        self.r = (up(self.r.0, self.v.0), up(self.r.1, self.v.1));
    }

    /// Whether the final R of both limits is at or below its threshold: the smallest R so
    /// far is, or 2·E at the walk's end is (every needed R is at most that, see
    /// `piecewise_upper`), by an upper bound of E there from E = `e` after a segment whose
    /// upper bound was `e_hi` (the rest of the upper bounds, with a margin for the rounding
    /// of their sums: at most `PIECEWISE_CAPS` terms of relative error 1.1e-16 each).
    fn holds(&self, hard_r: f64, soft_r: f64, e: f64, e_hi: f64) -> bool {
        let end = 2.0 * (e + (self.e_hi_end - e_hi) + 1e-12 * self.e_hi_end) * (1.0 + 1e-12);
        (hard_r <= self.r.0 || end <= self.r.0) && (soft_r <= self.r.1 || end <= self.r.1)
    }
}

/// A segment's stretches in the piecewise walk (`Interpolator::free_stretch`), mm from
/// the raw position: [start, lo) next to its start junction, [lo, hi) the middle, [hi, end]
/// next to its end junction.
#[derive(Clone, Copy)]
struct Stretches {
    lo: f64,
    hi: f64,
    /// The middle's acceleration: the line's free one, or None where it takes the budget
    /// (where every point has a junction within its ticks).
    middle_mm_s2: Option<f64>,
    /// With per-end budgets, the most the end stretches may take (the middle's acceleration,
    /// ∞ where the middle takes the budget); None: they take the budget.
    ends_top_mm_s2: Option<f64>,
}

impl Stretches {
    /// The middle's acceleration where `budget` is the segment's (never below it).
    fn middle(&self, budget: f64) -> f64 {
        self.middle_mm_s2.map_or(budget, |a| a.max(budget))
    }
}

/// The monotonic deque of the window of ã (end distance, acceleration; the smallest
/// acceleration of the segments from the frontier back to W before the segment evaluated)
/// and the frontier: the next segment to enter, where it starts, and whether a stop point
/// has entered (a tick never crosses one: nothing after it is in any window).
struct Window {
    front: usize,
    len: usize,
    frontier: usize,
    front_start: f64,
    stop_seen: bool,
}

/// The state of the piecewise walk.
struct Walk {
    need: (bool, bool),
    /// This tick's distance W = v_now·Ts, the window's half width.
    w: f64,
    hard: Smallest,
    soft: Smallest,
    /// E so far, and the points of E within W recorded in `pw_points`.
    e: f64,
    points: usize,
    /// G(v_now) once known (∞ before), and 2·E up to which a cap farther may still lower a
    /// needed limit: the larger of min(R, G(v_now)) over them.
    g_up: f64,
    reach: f64,
}

impl Walk {
    fn set_reach(&mut self) {
        let bound = |needed: bool, s: &Smallest| if needed { s.r.min(self.g_up) } else { 0.0 };
        self.reach = bound(self.need.0, &self.hard).max(bound(self.need.1, &self.soft));
    }
}

impl Interpolator {
    /// The piecewise limits (hard, soft) of this tick where the exact ones (`exact`) are below
    /// this tick's speed, each at most that speed (elsewhere 0: not needed). `here`: the
    /// limits before any cap ahead (`caps_here`). Walks at most to the first stop point, and
    /// only as far as a cap could still bring a needed limit below this tick's speed. `None`
    /// where the windows do not fit their slots, or where the result would certainly not be
    /// above the exact limits (`Settled`; the raw stage then keeps those, as it would).
    pub(super) fn piecewise_limits(
        &mut self,
        accel_mm_s2: f64,
        braking: bool,
        here: (f64, f64),
        exact: (f64, f64),
    ) -> Option<Piecewise> {
        let v_now = self.raw_v_mm_s;
        let need = (exact.0 < v_now, exact.1 < v_now);
        let (walked, a_hi) = self.piecewise_upper(accel_mm_s2, braking);
        let mut settled = Settled::new(need, exact, v_now, a_hi, self.pw_hi[walked - 1]);
        if self.pw_bounds && settled.holds(f64::INFINITY, f64::INFINITY, 0.0, 0.0) {
            #[cfg(test)]
            {
                self.pw_stats.0 += 1;
            }
            return None;
        }
        // The window of ã: a braking tick covers at most v_now·Ts (it never runs faster than
        // this one). Not v_up·Ts: v_up grows with the head's acceleration, so a tick entering
        // a segment of higher acceleration would widen the window, lower ã and make the curve
        // fall by more than a tick's acceleration (a random dense path: 26.5 → 21.3 mm/s).
        let mut walk = Walk {
            need,
            w: v_now * TS_S,
            hard: Smallest::NONE,
            soft: Smallest::NONE,
            e: 0.0,
            points: 0,
            g_up: f64::INFINITY,
            reach: 0.0,
        };
        walk.set_reach();
        self.piecewise_walk(&mut walk, &mut settled, walked, braking)?;
        let inv = |needed: bool, s: &Smallest, here: f64| {
            if needed {
                s.direct
                    .min(self.g_inverse(walk.points, s.r, v_now))
                    .min(here)
            } else {
                0.0
            }
        };
        Some(Piecewise {
            hard: inv(need.0, &walk.hard, here.0),
            soft: inv(need.1, &walk.soft, here.1),
        })
    }

    /// The walk of `piecewise_limits` over the caps; `None` where the windows do not fit or
    /// `settled` holds. The caps of a group of `GROUP` slots that cannot lower any needed R
    /// (`piecewise_group_clear`) are not evaluated: their R would not change the smallest.
    fn piecewise_walk(
        &mut self,
        walk: &mut Walk,
        settled: &mut Settled,
        walked: usize,
        braking: bool,
    ) -> Option<()> {
        let mut win = Window {
            front: 0,
            len: 0,
            frontier: self.raw_seg,
            front_start: -self.raw_in_seg_mm,
            stop_seen: false,
        };
        let mut caps_from = self.raw_seg;
        let mut j = self.raw_seg;
        let mut start_j = -self.raw_in_seg_mm;
        loop {
            let end_j = start_j + self.ahead[self.idx(j)].length_mm;
            if j >= caps_from
                && start_j > walk.w
                && self.pw_bounds
                && self.piecewise_group_clear(j, walk)
            {
                caps_from = j + GROUP;
                #[cfg(test)]
                {
                    self.pw_stats.1 += 1;
                }
            }
            let a_j = self.window_accel(&mut win, walk.w, start_j, end_j, walked, braking)?;
            self.walk_energy(walk, j, (start_j, end_j), walked, braking, a_j)?;
            if start_j > walk.w && walk.g_up.is_infinite() {
                // G at this tick's speed: a cap with R above it allows that speed.
                let v_now = self.raw_v_mm_s;
                walk.g_up = v_now * v_now + 2.0 * self.e_at(walk.points, v_now * TS_S);
                settled.raise(|v| v * v + 2.0 * self.e_at(walk.points, v * TS_S));
                walk.set_reach();
            }
            let offset = j - self.raw_seg;
            if j >= caps_from {
                let seg = &self.ahead[self.idx(j)];
                let next = (j + 1 < self.len).then(|| &self.ahead[self.idx(j + 1)]);
                let (hard_cap, soft_cap, _) = self.caps_at_end(seg, next, 0.0);
                walk.hard.add(hard_cap, end_j, walk.e);
                walk.soft.add(soft_cap, end_j, walk.e);
                walk.set_reach();
                if hard_cap == 0.0 {
                    // (At a stop point the walk ends.)
                    return Some(());
                }
            }
            if offset % 8 == 7
                && self.pw_bounds
                && settled.holds(walk.hard.r, walk.soft.r, walk.e, self.pw_hi[offset])
            {
                #[cfg(test)]
                {
                    self.pw_stats.0 += 1;
                }
                return None;
            }
            // Every cap farther has R ≥ 2·E: none can lower a needed limit below this tick's
            // speed once 2·E reaches both its smallest R so far and G(v_now).
            if 2.0 * walk.e >= walk.reach {
                return Some(());
            }
            if offset + 1 >= PIECEWISE_CAPS {
                walk.hard.add(0.0, end_j, walk.e);
                walk.soft.add(0.0, end_j, walk.e);
                return Some(());
            }
            start_j = end_j;
            j += 1;
        }
    }

    /// Adds segment `j`'s (from `span.0` to `span.1`) share of E to the walk: its free stretch
    /// in up to three parts, else at `a_j` throughout; points within W are recorded. `None`
    /// when the points do not fit.
    fn walk_energy(
        &mut self,
        walk: &mut Walk,
        j: usize,
        span: (f64, f64),
        walked: usize,
        braking: bool,
        a_j: f64,
    ) -> Option<()> {
        let (start_j, end_j) = span;
        let record = start_j <= walk.w;
        let Some(st) = self.free_stretch(j, start_j, end_j, walk.w, braking) else {
            walk.e += a_j * (end_j - start_j.max(0.0));
            return if record {
                self.walk_point(walk, end_j, a_j)
            } else {
                Some(())
            };
        };
        let (a_lo, a_hi) = match st.ends_top_mm_s2 {
            Some(top) => {
                let (a_lo, a_hi) = self.end_stretch_accels(j, start_j, end_j, walk.w, walked, a_j);
                let top = top.max(a_j);
                (a_lo.min(top), a_hi.min(top))
            }
            None => (a_j, a_j),
        };
        let parts = [(st.lo, a_lo), (st.hi, st.middle(a_j)), (end_j, a_hi)];
        let mut from = start_j;
        for (to, a) in parts {
            walk.e += a * (to - from.max(0.0)).max(0.0);
            if record && to > 0.0 {
                self.walk_point(walk, to, a)?;
            }
            from = to;
        }
        Some(())
    }

    /// Records the walk's point (distance `to`, E so far, acceleration `a`); `None` when full.
    fn walk_point(&mut self, walk: &mut Walk, to: f64, a: f64) -> Option<()> {
        if walk.points == PIECEWISE_SLOTS {
            return None;
        }
        self.pw_points[walk.points] = (to, walk.e, a);
        walk.points += 1;
        Some(())
    }

    /// ã of the segment from `start_j` to `end_j`: the smallest acceleration of the segments
    /// from W before its start to W after its end (the frontier moves on to every segment
    /// starting within W after `end_j`). The first `walked` segments' accelerations are those
    /// `piecewise_upper` kept. `None` where the deque does not fit its slots.
    fn window_accel(
        &mut self,
        win: &mut Window,
        w: f64,
        start_j: f64,
        end_j: f64,
        walked: usize,
        braking: bool,
    ) -> Option<f64> {
        while !win.stop_seen && win.frontier < self.len && win.front_start <= end_j + w {
            let seg = &self.ahead[self.idx(win.frontier)];
            let offset = win.frontier - self.raw_seg;
            let a = if offset < walked {
                self.pw_own[offset]
            } else {
                self.walk_accel(seg, braking)
            };
            let end = win.front_start + seg.length_mm;
            while win.len > 0 && self.pw_deque[(win.front + win.len - 1) % PIECEWISE_SLOTS].1 >= a {
                win.len -= 1;
            }
            if win.len == PIECEWISE_SLOTS {
                return None;
            }
            self.pw_deque[(win.front + win.len) % PIECEWISE_SLOTS] = (end, a);
            win.len += 1;
            win.stop_seen = seg.v_end_mm_s == 0.0 || win.frontier + 1 == self.len;
            win.frontier += 1;
            win.front_start = end;
        }
        while win.len > 1 && self.pw_deque[win.front].0 < start_j - w {
            win.front = (win.front + 1) % PIECEWISE_SLOTS;
            win.len -= 1;
        }
        Some(self.pw_deque[win.front].1)
    }

    /// Whether no cap at the ends of the `GROUP` segments from `j` (the first slot of a group,
    /// beyond this tick's distance W) can lower a needed smallest R: each cap is at least the
    /// group's lower bound c_lo (as in `group_clear`: the bounds hold for the slots pushed
    /// since the group's first) and each E from here on at least `walk.e`, so its R is at
    /// least c_lo² + 2·E (rounding is monotone); none is a stop (its R would be 2·E), and
    /// none counts as a direct cap below this tick's speed (cap·Ts ≥ d > W means cap >
    /// v_now, and the raw stage takes at most v_now of the piecewise limits).
    fn piecewise_group_clear(&self, j: usize, walk: &Walk) -> bool {
        if !self.idx(j).is_multiple_of(GROUP) || j + GROUP >= self.len {
            return false;
        }
        let g = &self.groups[self.idx(j) / GROUP];
        let next = &self.ahead[self.idx(j + GROUP)];
        let v_max = g.v_max_mm_s.min(next.v_max_mm_s);
        let end = if self.filtered() {
            g.v_end_mm_s
        } else {
            g.end_linear_mm_s
        };
        let hard_lo = end.min(v_max);
        if !(g.v_end_mm_s > 0.0 && hard_lo > 0.0) {
            return false;
        }
        let soft_lo = if g.feed_mm_s.is_nan() || next.rapid || next.per_rev_nominal_rpm > 0.0 {
            0.0
        } else {
            (g.feed_mm_s.min(next.feed_mm_s) * self.override_factor).min(v_max)
        };
        let clear = |needed: bool, lo: f64, s: &Smallest| !needed || lo * lo + 2.0 * walk.e >= s.r;
        clear(walk.need.0, hard_lo, &walk.hard) && clear(walk.need.1, soft_lo, &walk.soft)
    }

    /// An upper bound of E along the walk of `piecewise_limits`, into `pw_hi` (after each
    /// segment), and the segments' accelerations into `pw_own`; returns how many segments the
    /// walk may take and the largest acceleration on them. The walk ends at the latest at its
    /// `PIECEWISE_CAPS`-th cap or at the first stop point, where it adds a stop (R = 2·E
    /// there), or where 2·E reaches a needed R (not G(v_now) when that is above G(exact)):
    /// every needed R is then at most 2·E at its end. ã of a segment is at most the
    /// segment's own acceleration (its window holds it), so these sums over the same
    /// distances, in the same order, are at least the walk's E (rounding is monotone). On
    /// the dense circle most braking ticks ended on the assumed stop after `PIECEWISE_CAPS`
    /// caps, far below their exact limits (issue #32: 128 caps walked in vain, the ticks of
    /// the p99).
    fn piecewise_upper(&mut self, accel_mm_s2: f64, braking: bool) -> (usize, f64) {
        let (mut e_hi, mut a_hi) = (0.0, accel_mm_s2);
        let w = self.raw_v_mm_s * TS_S;
        let mut j = self.raw_seg;
        let mut start = -self.raw_in_seg_mm;
        loop {
            let seg = &self.ahead[self.idx(j)];
            let end = start + seg.length_mm;
            let a = if j == self.raw_seg {
                accel_mm_s2
            } else {
                self.walk_accel(seg, braking)
            };
            a_hi = a_hi.max(a);
            match self.free_stretch(j, start, end, w, braking) {
                Some(st) => {
                    let free = st.middle(a);
                    let (a_lo, a_end) = if st.ends_top_mm_s2.is_some() {
                        let (s, e) = self.end_budget_accels(&self.ahead[self.idx(j)]);
                        (a.max(s), a.max(e))
                    } else {
                        (a, a)
                    };
                    a_hi = a_hi.max(free).max(a_lo).max(a_end);
                    let mut from = start;
                    for (to, a) in [(st.lo, a_lo), (st.hi, free), (end, a_end)] {
                        e_hi += a * (to - from.max(0.0)).max(0.0);
                        from = to;
                    }
                }
                None => e_hi += a * (end - start.max(0.0)).max(0.0),
            }
            let offset = j - self.raw_seg;
            self.pw_hi[offset] = e_hi;
            self.pw_own[offset] = a;
            // (`caps_at_end`'s stop points, and the walk's last cap.)
            let moving = seg.v_end_mm_s > 0.0;
            if !moving || j + 1 >= self.len || offset + 1 >= PIECEWISE_CAPS {
                return (offset + 1, a_hi);
            }
            start = end;
            j += 1;
        }
    }

    /// The stretch of segment `j` (from `start` to `end`, mm from the raw position) where a
    /// braking tick may use the line's free acceleration, split into stretches with their
    /// accelerations. None where there is none (a line not longer than 3W, no free
    /// acceleration, or a feed hold or stop, which brake at their own rate). A tick's speed change at
    /// its tick point x_n is bounded by ã over its next step [x_n, x_n + W]; a junction
    /// within its two steps [x_n − W, x_n + W] limits it to the budget (the window's
    /// smallest acceleration), otherwise its second difference is the speed change along
    /// the line alone and the free acceleration holds (`Segment::free_accel_mm_s2`). So a
    /// point x may take it where no junction lies within [x − 2W, x + W]: from 2W after
    /// the line's start to W before its end (issue #32: the braking zones of the dense
    /// paths crossed the lines beside tight turns at the budget those turns leave). The
    /// walk and the upper bound of E (`piecewise_upper`) split a segment at the same
    /// points, so the bound still sums the same lengths.
    ///
    /// With per-end budgets (`Segment::accel_start_mm_s2`, `accel_end_mm_s2`, above the
    /// line's budget by more than `ENDS_MIN_GAIN`), the point x takes its start junction's
    /// budget where only that junction lies within [x − 2W, x + W] (from the line's start
    /// to W before its end), its end junction's where only that one does (from 2W after its
    /// start), the budget where both do and the free acceleration where neither does: the
    /// stretches [start, min(lo, hi)), [min, max(lo, hi)) with the free acceleration, or the
    /// budget where lo ≥ hi, and [max, end], with lo = start + 2W and hi = end − W (the end
    /// stretches take the ends' budgets, at most the middle stretch's acceleration). The
    /// stretches move with W, which falls from tick to tick while braking: the middle one
    /// grows into the end ones where lo < hi, the end ones into the middle one where lo ≥ hi.
    /// E must not fall when W does (the curve would fall by more than ã in a tick), so the
    /// stretch that grows must not have the lower acceleration (issue #32).
    fn free_stretch(
        &self,
        j: usize,
        start: f64,
        end: f64,
        w: f64,
        braking: bool,
    ) -> Option<Stretches> {
        // (A segment not longer than W has no point with at most one of its junctions
        // within [x − 2W, x + W]: not split.)
        if braking || end - start <= w {
            return None;
        }
        let (lo, hi) = (start + 2.0 * w, end - w);
        let seg = &self.ahead[self.idx(j)];
        let free = seg.free_accel_mm_s2;
        let gain = seg.accel_mm_s2 * ENDS_MIN_GAIN;
        if seg.accel_start_mm_s2 > gain || seg.accel_end_mm_s2 > gain {
            // (Where lo ≥ hi the middle stretch takes the budget: no middle acceleration.)
            let (a, b) = (lo.min(hi).max(start), lo.max(hi).min(end));
            let (middle, top) = if lo < hi {
                (Some(free), free)
            } else {
                (None, f64::INFINITY)
            };
            return Some(Stretches {
                lo: a,
                hi: b.max(a),
                middle_mm_s2: middle,
                ends_top_mm_s2: Some(top),
            });
        }
        if lo >= hi {
            return None;
        }
        (free > 0.0).then_some(Stretches {
            lo,
            hi,
            middle_mm_s2: Some(free),
            ends_top_mm_s2: None,
        })
    }

    /// The accelerations of the start and end stretches of segment `j` (from `start_j` to
    /// `end_j`, `free_stretch`) in the piecewise walk, each at least `a_j` (the window's
    /// smallest): a tick point x_n within W before a point of the start stretch lies in
    /// this line, where its steps touch no junction but the start one, or in a segment
    /// ending within W before the line; its acceleration is the start budget's or that
    /// segment's. Likewise the end stretch's tick points lie in this line, and their next
    /// steps reach the segments starting within W after it. Those segments take their own
    /// budgets (the ones `window_accel` takes).
    fn end_stretch_accels(
        &self,
        j: usize,
        start_j: f64,
        end_j: f64,
        w: f64,
        walked: usize,
        a_j: f64,
    ) -> (f64, f64) {
        let seg_a = |k: usize| {
            let offset = k - self.raw_seg;
            if offset < walked {
                self.pw_own[offset]
            } else {
                self.walk_accel(&self.ahead[self.idx(k)], false)
            }
        };
        let (mut a_lo, mut a_hi) = self.end_budget_accels(&self.ahead[self.idx(j)]);
        let (mut k, mut edge) = (j, start_j);
        while k > self.raw_seg && edge >= start_j - w {
            k -= 1;
            a_lo = a_lo.min(seg_a(k));
            edge -= self.ahead[self.idx(k)].length_mm;
        }
        let (mut k, mut edge) = (j, end_j);
        while self.ahead[self.idx(k)].v_end_mm_s > 0.0 && k + 1 < self.len && edge <= end_j + w {
            k += 1;
            a_hi = a_hi.min(seg_a(k));
            edge += self.ahead[self.idx(k)].length_mm;
        }
        (a_lo.max(a_j), a_hi.max(a_j))
    }

    /// The raw accelerations of segment `seg`'s start and end stretches from its per-end
    /// budgets (`Interpolator::end_raw_accel`).
    fn end_budget_accels(&self, seg: &super::ahead::Ahead) -> (f64, f64) {
        let end = |a: f64| self.end_raw_accel(a, seg.accel_mm_s2, seg.jerk_mm_s3);
        (end(seg.accel_start_mm_s2), end(seg.accel_end_mm_s2))
    }

    /// E(0..x) from the first `points` points (end distance, E at it, acceleration on it).
    pub(super) fn e_at(&self, points: usize, x: f64) -> f64 {
        let mut prev = 0.0;
        for &(end, e, a) in &self.pw_points[..points] {
            if x <= end {
                return e - a * (end - x);
            }
            prev = e;
        }
        prev
    }

    /// The largest v ≤ `v_top` with G(v) = v² + 2·E(0..v·Ts) ≤ `r`: per point E is linear,
    /// so on the stretch where v·Ts lies v = −ã·Ts + √((ã·Ts)² + r − 2·(e − ã·end)).
    pub(super) fn g_inverse(&self, points: usize, r: f64, v_top: f64) -> f64 {
        if !r.is_finite() {
            return v_top;
        }
        for &(end, e, a) in &self.pw_points[..points] {
            let v_end = end / TS_S;
            if v_end * v_end + 2.0 * e >= r {
                // v·Ts within this stretch: E(x) = e − a·(end − x).
                let k = a * TS_S;
                let c = r - 2.0 * (e - a * end);
                return (-k + (k * k + c).max(0.0).sqrt()).clamp(0.0, v_top);
            }
        }
        // Beyond the recorded stretch (past a stop point): no more distance.
        let e = points.checked_sub(1).map_or(0.0, |i| self.pw_points[i].1);
        (r - 2.0 * e).max(0.0).sqrt().min(v_top)
    }
}
