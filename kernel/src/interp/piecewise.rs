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

use super::Interpolator;
use crate::units::TS_S;

/// Capacity of the window of accelerations and of the points of E within one tick (segments
/// within 2·W and within W); a tick that would need more uses the exact curve alone.
pub(super) const PIECEWISE_SLOTS: usize = 1024;

/// Caps looked at per tick at most (the cost of a tick): past them the walk assumes a stop,
/// which no cap farther can be below (its R = c² + 2·E is at least 2·E there).
const PIECEWISE_CAPS: usize = 128;

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

impl Interpolator {
    /// The piecewise limits (hard, soft) of this tick where the exact ones (`exact`) are below
    /// this tick's speed, each at most that speed (elsewhere 0: not needed). `here`: the
    /// limits before any cap ahead (`caps_here`). Walks at most to the first stop point, and
    /// only as far as a cap could still bring a needed limit below this tick's speed. `None`
    /// where the windows do not fit their slots.
    pub(super) fn piecewise_limits(
        &mut self,
        accel_mm_s2: f64,
        braking: bool,
        here: (f64, f64),
        exact: (f64, f64),
    ) -> Option<Piecewise> {
        let v_now = self.raw_v_mm_s;
        let need = (exact.0 < v_now, exact.1 < v_now);
        // The window of ã: a braking tick covers at most v_now·Ts (it never runs faster than
        // this one). Not v_up·Ts: v_up grows with the head's acceleration, so a tick entering
        // a segment of higher acceleration would widen the window, lower ã and make the curve
        // fall by more than a tick's acceleration (a random dense path: 26.5 → 21.3 mm/s).
        let w = v_now * TS_S;
        let (mut hard, mut soft) = (Smallest::NONE, Smallest::NONE);
        // Monotonic deque of (segment, end distance, acceleration): the smallest acceleration
        // of the segments from the frontier back to W before the segment `j` evaluated.
        let (mut q_front, mut q_len) = (0usize, 0usize);
        let mut frontier = self.raw_seg;
        let mut front_start = -self.raw_in_seg_mm;
        let mut points = 0usize;
        let mut stop_seen = false;
        let mut e = 0.0;
        let mut g_up = f64::INFINITY;
        let mut j = self.raw_seg;
        let mut start_j = -self.raw_in_seg_mm;
        while j < self.len {
            let end_j = start_j + self.ahead[self.idx(j)].length_mm;
            // Frontier: every segment starting within W after segment j's end.
            while !stop_seen && frontier < self.len && front_start <= end_j + w {
                let seg = &self.ahead[self.idx(frontier)];
                let a = if frontier == self.raw_seg {
                    accel_mm_s2
                } else {
                    self.walk_accel(seg, braking)
                };
                let end = front_start + seg.length_mm;
                while q_len > 0 && self.pw_deque[(q_front + q_len - 1) % PIECEWISE_SLOTS].2 >= a {
                    q_len -= 1;
                }
                if q_len == PIECEWISE_SLOTS {
                    return None;
                }
                self.pw_deque[(q_front + q_len) % PIECEWISE_SLOTS] = (frontier, end, a);
                q_len += 1;
                // (A tick never crosses a stop point: nothing after it is in any window.)
                stop_seen = seg.v_end_mm_s == 0.0 || frontier + 1 == self.len;
                frontier += 1;
                front_start = end;
            }
            while q_len > 1 && self.pw_deque[q_front].1 < start_j - w {
                q_front = (q_front + 1) % PIECEWISE_SLOTS;
                q_len -= 1;
            }
            let a_j = self.pw_deque[q_front].2;
            e += a_j * (end_j - start_j.max(0.0));
            if start_j <= w {
                if points == PIECEWISE_SLOTS {
                    return None;
                }
                self.pw_points[points] = (end_j, e, a_j);
                points += 1;
            } else if g_up.is_infinite() {
                // G at this tick's speed: a cap with R above it allows that speed.
                g_up = v_now * v_now + 2.0 * self.e_at(points, v_now * TS_S);
            }
            let seg = &self.ahead[self.idx(j)];
            let next = (j + 1 < self.len).then(|| &self.ahead[self.idx(j + 1)]);
            let (hard_cap, soft_cap, _) = self.caps_at_end(seg, next, 0.0);
            hard.add(hard_cap, end_j, e);
            soft.add(soft_cap, end_j, e);
            // Every cap farther has R ≥ 2·E: none can lower a needed limit below this tick's
            // speed once 2·E reaches both its smallest R so far and G(v_now).
            let bound = |needed: bool, s: &Smallest| if needed { s.r.min(g_up) } else { 0.0 };
            let reach = bound(need.0, &hard).max(bound(need.1, &soft));
            if hard_cap == 0.0 || 2.0 * e >= reach {
                // (At a stop point the walk ends too.)
                break;
            }
            if j + 1 - self.raw_seg >= PIECEWISE_CAPS {
                hard.add(0.0, end_j, e);
                soft.add(0.0, end_j, e);
                break;
            }
            start_j = end_j;
            j += 1;
        }
        let inv = |needed: bool, s: &Smallest, here: f64| {
            if needed {
                s.direct.min(self.g_inverse(points, s.r, v_now)).min(here)
            } else {
                0.0
            }
        };
        Some(Piecewise {
            hard: inv(need.0, &hard, here.0),
            soft: inv(need.1, &soft, here.1),
        })
    }

    /// E(0..x) from the first `points` points (end distance, E at it, acceleration on it).
    fn e_at(&self, points: usize, x: f64) -> f64 {
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
    fn g_inverse(&self, points: usize, r: f64, v_top: f64) -> f64 {
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
