//! Stage 2, jerk filter (parabolic profile, SPEC §7.3): the commanded arc length is the mean
//! of the last `m` raw arc lengths. Its jerk is exactly (a(n) − a(n−m))/(m·Ts), a(n) the raw
//! acceleration of tick n; the raw stage keeps |a(n) − a(n−m)| ≤ J·m·Ts (the *coast gap*:
//! after a tick that accelerates it brakes only `m` ticks later, and after braking it
//! accelerates only `m` ticks later), so m = ⌈a/(J·Ts)⌉ suffices and a filtered trapezoid is
//! the ideal jerk-limited (7-phase) profile. Without the gap a raw step from +a to −a would
//! need m = 2a/(J·Ts), which made every ramp 50 % longer (issue #16).

use super::{ARRIVE_EPS_MM, FILTER_MAX_TICKS, Interpolator};
use crate::plan::Segment;
use crate::units::TS_S;

impl Interpolator {
    /// Pushes this tick's raw arc length and local caps into the filter history.
    pub(super) fn record(&mut self, cap: f64, feed: f64) {
        let s = self.raw_s();
        let prev = self.hist_raw_s_mm[self.hist_newest];
        self.hist_newest = (self.hist_newest + 1) % FILTER_MAX_TICKS;
        self.hist_raw_s_mm[self.hist_newest] = s;
        self.hist_cap_mm_s[self.hist_newest] = cap;
        self.hist_feed_mm_s[self.hist_newest] = feed;
        self.hist_raw_slot[self.hist_newest] = self.idx(self.raw_seg);
        if s == prev {
            self.still_ticks = (self.still_ticks + 1).min(FILTER_MAX_TICKS);
        } else {
            self.still_ticks = 0;
        }
        // Rounding of the arc lengths (a few ulp of s per difference) is not an acceleration.
        let noise_mm_s2 = 1e-6 + 16.0 * f64::EPSILON * s.abs() / (TS_S * TS_S);
        if self.raw_accel_back(0) > noise_mm_s2 {
            self.ticks_since_accel = 0;
        } else {
            self.ticks_since_accel = (self.ticks_since_accel + 1).min(FILTER_MAX_TICKS);
        }
    }

    /// Raw acceleration of the tick `back` ticks before the newest recorded one, mm/s²
    /// (second difference of the raw arc lengths, what the filter averages).
    fn raw_accel_back(&self, back: usize) -> f64 {
        let s = |j: usize| {
            self.hist_raw_s_mm[(self.hist_newest + 2 * FILTER_MAX_TICKS - j) % FILTER_MAX_TICKS]
        };
        (s(back) - 2.0 * s(back + 1) + s(back + 2)) / (TS_S * TS_S)
    }

    /// Range of the raw acceleration of the next tick on `head`, as (largest deceleration,
    /// largest acceleration), mm/s², within `a`: the filtered jerk (a(n) − a(n−m))/(m·Ts)
    /// stays ≤ J. Linear profile (no jerk limit): ±a.
    pub(super) fn jerk_accel_window(&self, a: f64, head: &Segment) -> (f64, f64) {
        let j = head.jerk_mm_s3;
        if !j.is_finite() {
            return (a, f64::INFINITY);
        }
        let m = self.jerk_filter_ticks;
        let a_m = j * m as f64 * TS_S;
        let a_old = self.raw_accel_back(m - 1);
        ((a_m - a_old).clamp(0.0, a), (a_m + a_old).max(0.0))
    }

    /// Coast gap for the braking model of the raw stage, ticks after the next one during which
    /// it may not brake at full deceleration: (if the next tick does not accelerate, if it
    /// does). A tick that accelerates forbids full braking `m` ticks later
    /// (`jerk_accel_window`), so a speed is safe when coasting through the gap and braking
    /// after it meets every cap (`Interpolator::v_brake` with `coast`). Linear: no gap.
    pub(super) fn coast_gaps(&self, head: &Segment) -> (f64, f64) {
        if !head.jerk_mm_s3.is_finite() {
            return (0.0, 0.0);
        }
        let m = self.jerk_filter_ticks;
        let now = (m - 1).saturating_sub(self.ticks_since_accel);
        (now as f64, m as f64)
    }

    /// Whether a filter (jerk or axis, the parabolic profile) stands between the raw speed and
    /// the setpoints; without one the raw ticks are the setpoints (linear profile).
    pub(super) fn filtered(&self) -> bool {
        self.jerk_filter_ticks > 1 || self.axis_window_ticks > 1
    }

    /// Ticks before and after a speed cap during which the raw speed stays within it (0: only
    /// at the cap). The jerk filter averages raw speeds over `m` ticks, so its speed at a
    /// point is within a cap if the raw speed was over the `m + 1` ticks around it; the axis
    /// filter takes path speeds from 2n ticks before to 2n ticks after a turn, and the
    /// planner's corner limits count on all of them being within the junction speed.
    pub(super) fn cap_zone_ticks(&self) -> usize {
        if !self.filtered() {
            return 0;
        }
        let axis = if self.axis_window_ticks > 1 {
            2 * self.axis_window_ticks
        } else {
            0
        };
        self.jerk_filter_ticks + 1 + axis
    }

    /// Smallest cap (hard, feed) recorded over the last `cap_zone_ticks` ticks.
    pub(super) fn behind_caps(&self) -> (f64, f64) {
        let zone = self.cap_zone_ticks();
        if zone == 0 {
            return (f64::INFINITY, f64::INFINITY);
        }
        let mut cap = f64::INFINITY;
        let mut feed = f64::INFINITY;
        for j in 0..zone {
            let i = (self.hist_newest + FILTER_MAX_TICKS - j) % FILTER_MAX_TICKS;
            cap = cap.min(self.hist_cap_mm_s[i]);
            feed = feed.min(self.hist_feed_mm_s[i]);
        }
        (cap, feed)
    }

    /// Filter stage: the commanded arc length is the mean of the last `m` raw arc lengths.
    /// Returns whether the program's last segment was completed.
    pub(super) fn follow(&mut self) -> bool {
        let s_raw = self.hist_raw_s_mm[self.hist_newest];
        let mut lag_sum = 0.0;
        for j in 0..self.jerk_filter_ticks {
            let i = (self.hist_newest + FILTER_MAX_TICKS - j) % FILTER_MAX_TICKS;
            lag_sum += s_raw - self.hist_raw_s_mm[i];
        }
        let s_f = (s_raw - lag_sum / self.jerk_filter_ticks as f64).max(self.filtered_s_mm);
        self.filtered_v_mm_s = (s_f - self.filtered_s_mm) / TS_S;
        self.filtered_s_mm = s_f;
        let mut program_end = false;
        let keep_from = self.jbox_keep_from_s();
        // Drop segments the commanded position has left (never the raw one, nor one the
        // jerk-limited box still reads).
        while self.len > 0 {
            let i = self.idx(0);
            let seg = self.buf[i];
            let end = self.seg_start_s_mm[i] + seg.length_mm;
            let raw_done = self.raw_seg > 0
                || (self.raw_at_stop
                    && self.len == 1
                    && self.settled()
                    && self.last_may_leave(&seg));
            if s_f >= end - ARRIVE_EPS_MM && raw_done && end <= keep_from {
                self.path_pos = seg.path.end();
                self.last_seq = seg.seq;
                self.last_n = seg.n;
                self.last_line = seg.line;
                self.last_spindle = seg.spindle_after.unwrap_or(seg.spindle);
                self.last_rapid = seg.rapid;
                program_end |= seg.last;
                self.head = (self.head + 1) % super::BUFFER_SEGMENTS;
                self.floor_accel_mm_s2
                    .remove(seg.accel_mm_s2.min(seg.stop_accel_mm_s2));
                self.floor_jerk_mm_s3.remove(seg.jerk_mm_s3);
                self.len -= 1;
                self.raw_seg = self.raw_seg.saturating_sub(1);
                if self.len == 0 {
                    self.raw_in_seg_mm = 0.0;
                }
                continue;
            }
            // (The segment the commanded position lies on: the first one left, with
            // segments the box reads kept behind it.)
            let mut j = 0;
            while j < self.raw_seg
                && s_f >= self.seg_start_s_mm[self.idx(j)] + self.seg(j).length_mm - ARRIVE_EPS_MM
            {
                j += 1;
            }
            let (i, seg) = (self.idx(j), *self.seg(j));
            let local = s_f - self.seg_start_s_mm[i];
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
                && self.raw_seg == j
                && self.filtered_v_mm_s == 0.0
                && local >= seg.length_mm - ARRIVE_EPS_MM;
            self.last_spindle = match (at_stop, seg.spindle_after) {
                (false, _) => seg.spindle,
                (true, _) if self.len > j + 1 => self.buf[self.idx(j + 1)].spindle,
                (true, after) => after.unwrap_or(seg.spindle),
            };
            self.last_rapid = seg.rapid;
            break;
        }
        program_end
    }
}

/// Time of the ideal jerk-limited (7-phase S-curve) move of `l_mm` from rest to rest with
/// speed `v`, acceleration `a` and jerk `j`, s: the closed form, with the peak speed found by
/// bisection when `v` is not reached. Not used by the interpolator: the reference its tests
/// (kernel and daemon level) compare the filtered profile against.
pub fn ideal_jerk_limited_move_s(l_mm: f64, v_mm_s: f64, a_mm_s2: f64, j_mm_s3: f64) -> f64 {
    // Time and distance of a ramp from rest to `vp`.
    let ramp = |vp: f64| {
        let t = if vp >= a_mm_s2 * a_mm_s2 / j_mm_s3 {
            vp / a_mm_s2 + a_mm_s2 / j_mm_s3
        } else {
            2.0 * (vp / j_mm_s3).sqrt()
        };
        (t, vp * t / 2.0)
    };
    let (t_v, d_v) = ramp(v_mm_s);
    if 2.0 * d_v <= l_mm {
        return 2.0 * t_v + (l_mm - 2.0 * d_v) / v_mm_s;
    }
    let (mut lo, mut hi) = (0.0, v_mm_s);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if 2.0 * ramp(mid).1 <= l_mm {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    2.0 * ramp(lo).0
}
