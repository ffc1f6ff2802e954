//! Tangential acceleration of a line next to turning junctions as a function of the highest
//! speed the line runs at (linear profile, issue #16).
//!
//! Per axis k the tangential share a_t·d_k and the normal acceleration of the turns N_k must
//! stay within the axis limit a_k. The normal acceleration of a turn passed at speed v is
//! v·T_k/Ts (T_k the turn per tick, a component of the tangent change within the tick window);
//! the window shrinks with v, so T_k measured at the fastest a tick touching the junction runs
//! (v_ref) bounds it for every slower speed: N_k(v) ≤ q_k·min(v, v_ref). A line whose speed
//! stays below v may therefore use a(v) = min_k (a_k − N_k(v))/d_k: the slower it runs, the
//! more of every axis is left for its ramp. The planner knows the highest speed of a line
//! from its end speeds (braking to the next junction, accelerating from the last), so the
//! acceleration follows the planned speeds instead of the junction caps.

use crate::units::{MAX_AXES, TS_S};

/// The turns near a junction passed at its cap, as the lines on either side see them.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct JunctionTurns {
    /// Per axis: the turn of the tangent per tick within the tick window, 1/s (N_k(v) ≤
    /// normal_k·min(v, v_ref)).
    pub(super) normal_per_s: [f64; MAX_AXES],
    /// Per axis: the turns per tick at half the window, 1/s (N_k(v_ref/2) ≤
    /// half_k·v_ref/2): between lines the absolute turns within h (Σ|Δu_k|·(1 − d/h)),
    /// which N_k(w), convex in w, lets the lines use below v_ref (issue #32); elsewhere
    /// `normal_per_s` (the chord).
    pub(super) half_per_s: [f64; MAX_AXES],
    /// Per axis: the junction's own turn per tick, |Δu_k|/Ts, where `normal_per_s` is the
    /// absolute turns between lines (which count it with weight 1); 0 elsewhere. The cap
    /// takes no acceleration step margin on it: a tick point weighs it by at most the step
    /// that crosses or ends on the junction, which the interpolator keeps within the cap.
    pub(super) own_per_s: [f64; MAX_AXES],
    /// Per axis: the largest tangent component the ticks near the junction move along.
    pub(super) dir: [f64; MAX_AXES],
    /// The fastest a tick touching the junction runs, mm/s.
    pub(super) v_ref_mm_s: f64,
    /// The speed the turns are passed at (N_k(v) ≤ normal_k·min(v, v_turn)), mm/s: v_ref,
    /// or the junction's cap where it is alone in the ticks touching it (issue #32). The
    /// second difference of the tick n crossing such a junction (a before it, b after,
    /// a + b = its step) is Δs_n·u_in + b·Δu, and of the next tick Δs_n+1·u_out + a·Δu:
    /// the turn weighs at most the crossing step, which the interpolator keeps within the
    /// cap (a faster tick ends a cap-tick before it); ticks one acceleration step faster
    /// next to it add nothing to the turn's share.
    pub(super) v_turn_mm_s: f64,
}

/// The normal acceleration of one end's turns on one axis, N(w)/d at tick speeds up to w:
/// the turns weigh Σ|Δu|·(w·Ts − d)⁺ at the junction, convex in w and 0 at w = 0, so below
/// v_ref it is at most the larger of its chords through N(v_ref/2) and N(v_ref), and above
/// v_ref (no tick touching the junction runs faster) it is N(v_ref). `q`, `q_half`: N/(w·d)
/// at v_ref and at v_ref/2, 1/s (q_half ≤ q).
#[inline(always)]
pub(super) fn normal_at(q: f64, q_half: f64, v_ref: f64, w: f64) -> f64 {
    if w >= v_ref {
        return q * v_ref;
    }
    let low = q_half * w;
    let high = (2.0 * q - q_half) * w - (q - q_half) * v_ref;
    if high > low { high } else { low }
}

#[derive(Clone, Copy, Debug, Default)]
pub(super) struct LineBudget {
    /// Per moving axis the turns see: a_k/d_k, mm/s².
    p: [f64; MAX_AXES],
    /// The smallest a_k/d_k of the moving axes no turn is seen on, mm/s².
    flat_mm_s2: f64,
    /// Per end (start, end) and axis: N(w)/(w·d_k) of that end's turns at v_ref and at
    /// v_ref/2, 1/s ([`normal_at`]).
    q: [[f64; MAX_AXES]; 2],
    q_half: [[f64; MAX_AXES]; 2],
    count: usize,
    /// Per end: speed above which its turns add no more normal acceleration (0 where it
    /// has none: a stop), mm/s.
    v_ref_mm_s: [f64; 2],
    /// Path acceleration of the axes moved (A = min a_k/|u_k|) and its share that is sound
    /// on its own (the normal acceleration within NORMAL_SHARE), mm/s².
    a_axes_mm_s2: f64,
    a_floor_mm_s2: f64,
    /// Path acceleration of the constants (R236 / set A), mm/s².
    base_mm_s2: f64,
    /// One tick's speed step at A: a tick may run that much faster than the continuous
    /// bound (its speed is chosen before it covers the distance), so the acceleration of a
    /// speed v is the one of v + margin.
    margin_mm_s: f64,
}

impl LineBudget {
    pub(super) fn new(a_axes_mm_s2: f64, a_floor_mm_s2: f64, base: f64) -> Self {
        LineBudget {
            p: [0.0; MAX_AXES],
            flat_mm_s2: f64::INFINITY,
            q: [[0.0; MAX_AXES]; 2],
            q_half: [[0.0; MAX_AXES]; 2],
            count: 0,
            v_ref_mm_s: [0.0; 2],
            a_axes_mm_s2,
            a_floor_mm_s2,
            base_mm_s2: base,
            margin_mm_s: a_axes_mm_s2 * TS_S,
        }
    }

    /// Adds an axis: its limit a_k, the largest tangent component d_k near the line, and
    /// per end the turns' normal terms (N_k(w) ≤ [`normal_at`] of `q` and `q_half` times
    /// d_k), 1/s.
    pub(super) fn add_axis(&mut self, a_k: f64, d_k: f64, q: [f64; 2], q_half: [f64; 2]) {
        if d_k <= 1e-12 {
            return;
        }
        if q[0] <= 0.0 && q[1] <= 0.0 {
            // (No turn on this axis: a constant, a term of its own would cost every call.)
            let p = a_k / d_k;
            if p < self.flat_mm_s2 {
                self.flat_mm_s2 = p;
            }
            return;
        }
        if self.count < MAX_AXES {
            let k = self.count;
            self.p[k] = a_k / d_k;
            for e in 0..2 {
                self.q[e][k] = q[e] / d_k;
                // (Convexity: at most the chord; guards the rounding of the sums.)
                self.q_half[e][k] = q_half[e].min(q[e]) / d_k;
            }
            self.count += 1;
        }
    }

    /// Sets the speed above which end `e`'s turns add no more (mm/s; 0: no turns there).
    pub(super) fn set_v_ref(&mut self, e: usize, v_ref_mm_s: f64) {
        self.v_ref_mm_s[e] = v_ref_mm_s;
    }

    /// Tangential acceleration the axes leave at speeds up to `v`, within [floor, A]
    /// (not capped by the constants: the stop set has its own).
    pub(super) fn tangential_at(&self, v: f64) -> f64 {
        let w = v + self.margin_mm_s;
        let a = self.left_by(0, w).min(self.left_by(1, w));
        a.min(self.a_axes_mm_s2).max(self.a_floor_mm_s2)
    }

    /// The acceleration at speeds up to `v` with the turns of end `e` alone (the other end
    /// as at a stop), with the line's directions of both ends (at most what that end's own
    /// budget leaves).
    pub(super) fn end_accel_at(&self, v: f64, e: usize) -> f64 {
        let a = self.left_by(e, v + self.margin_mm_s);
        self.base_mm_s2
            .min(a.min(self.a_axes_mm_s2).max(self.a_floor_mm_s2))
    }

    /// What end `e`'s turns leave of the axes at tick speeds up to `w`: min_k p_k − N_k(w)
    /// (and the axes without turns), mm/s².
    #[inline(always)]
    fn left_by(&self, e: usize, w: f64) -> f64 {
        // (Plain comparisons where the running value starts at ∞ or the flat axes': they
        // skip a NaN term as `min` does, at a quarter of the cost; this runs at every
        // commit.)
        let vr = self.v_ref_mm_s[e];
        let mut a = self.flat_mm_s2;
        for k in 0..self.count {
            let x = self.p[k] - normal_at(self.q[e][k], self.q_half[e][k], vr, w);
            if x < a {
                a = x;
            }
        }
        a
    }

    /// Highest tick speed the acceleration of speeds up to `v` covers (one tick's speed
    /// step above it), mm/s.
    pub(super) fn covered_mm_s(&self, v: f64) -> f64 {
        v + self.margin_mm_s
    }

    /// Path acceleration of the constants it was built with, mm/s².
    pub(super) fn base_mm_s2(&self) -> f64 {
        self.base_mm_s2
    }

    /// Path acceleration for feed moves at speeds up to `v`.
    pub(super) fn accel_at(&self, v: f64) -> f64 {
        self.base_mm_s2.min(self.tangential_at(v))
    }

    /// Highest speed v with v² ≤ v_from² + 2·L·a_lin(v): the fastest a line of length L can
    /// run while still braking to `v_from` at its end (or when accelerating from `v_from` at
    /// its start), with a_lin(v) ≤ a(v) the acceleration of each axis's turns taken linear
    /// in the speed and merged over both ends, N ≤ max_e q_e·min(w, max_e v_ref_e) (each
    /// end's chords lie below its q_e·w). The passes run this on every braking step, and
    /// its closed form has one root per axis; the segment then gets the chords' a(v) at the
    /// speed it is committed for, with that speed as its ceiling. (The chords in the passes
    /// as well cost the planner 25 % more and gained nothing on the reference paths: the
    /// lines that gain are the slow ones, whose speeds the junctions' caps set.) Closed
    /// form per axis: a_lin is the max of the floor and the min of linear functions of
    /// min(v, v_ref), and g(v) = v_from² + 2·L·a_lin(v) − v² falls with v, so the fixed point
    /// of a min (max) of terms is the min (max) of their fixed points.
    pub(super) fn reach_mm_s(&self, v_from: f64, length_mm: f64) -> f64 {
        let v2 = v_from * v_from;
        let constant = |a: f64| (v2 + 2.0 * length_mm * a.max(0.0)).sqrt();
        let hi = self.base_mm_s2.min(self.a_axes_mm_s2).min(self.flat_mm_s2);
        let mut v = constant(hi);
        let v_ref_mm_s = self.v_ref_mm_s[0].max(self.v_ref_mm_s[1]);
        // a(v) with min(v + margin, v_ref) = margin + min(v, v_ref − margin).
        let v_ref = (v_ref_mm_s - self.margin_mm_s).max(0.0);
        let margin = self.margin_mm_s.min(v_ref_mm_s);
        for k in 0..self.count {
            let q = self.q[0][k].max(self.q[1][k]);
            let p = self.p[k] - q * margin;
            let c = v2 + 2.0 * length_mm * (p - q * v_ref);
            let fk = if c >= v_ref * v_ref {
                c.sqrt()
            } else {
                let b = length_mm * q;
                -b + (b * b + v2 + 2.0 * length_mm * p).sqrt()
            };
            // (`v` starts finite, hi being at most the constants' acceleration, and only
            // takes smaller fk: a plain comparison skips a NaN fk as `min` does.)
            if fk < v {
                v = fk;
            }
        }
        v.max(constant(self.base_mm_s2.min(self.a_floor_mm_s2)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn budget() -> LineBudget {
        let mut b = LineBudget::new(800.0, 400.0, 1000.0);
        b.set_v_ref(0, 100.0);
        b.set_v_ref(1, 60.0);
        b.add_axis(800.0, 1.0, [0.0; 2], [0.0; 2]);
        b.add_axis(800.0, 0.3, [8.0, 6.0], [3.0, 6.0]);
        b
    }

    impl LineBudget {
        /// The acceleration `reach_mm_s` solves with: linear in the speed, ends merged.
        fn linear_accel_at(&self, v: f64) -> f64 {
            let v_ref = self.v_ref_mm_s[0].max(self.v_ref_mm_s[1]);
            let w = (v + self.margin_mm_s).min(v_ref);
            let mut a = self.flat_mm_s2;
            for k in 0..self.count {
                a = a.min(self.p[k] - self.q[0][k].max(self.q[1][k]) * w);
            }
            self.base_mm_s2
                .min(a.min(self.a_axes_mm_s2).max(self.a_floor_mm_s2))
        }
    }

    /// The chords bound what the ticks see: for turns |Δu_j| at distances d_j (the own at
    /// 0), N(w)·Ts² = Σ|Δu_j|·(w·Ts − d_j)⁺ at tick speeds up to w is convex in w, so the
    /// chords through N(v_ref/2) and N(v_ref) lie above it below v_ref, and N(v_ref) bounds
    /// it above (no tick touching the junction runs faster).
    #[test]
    fn the_chords_bound_the_weighted_turns_at_every_speed() {
        let n = |turns: &[(f64, f64)], w: f64| {
            turns
                .iter()
                .map(|&(du, d)| du * (w * TS_S - d).max(0.0))
                .sum::<f64>()
                / (TS_S * TS_S)
        };
        let cases: [&[(f64, f64)]; 4] = [
            &[(0.02, 0.0)],
            &[
                (0.01, 0.0),
                (0.01, 0.05),
                (0.01, 0.1),
                (0.01, 0.15),
                (0.01, 0.2),
            ],
            &[(0.0, 0.0), (0.3, 0.02), (0.001, 0.3)],
            &[(0.05, 0.0), (0.2, 0.39)],
        ];
        for turns in cases {
            let vr = 100.0;
            let q = n(turns, vr) / vr;
            let qh = n(turns, vr / 2.0) / (vr / 2.0);
            assert!(qh <= q * (1.0 + 1e-12), "{turns:?}");
            for i in 0..=300 {
                let w = vr * i as f64 / 200.0;
                let exact = n(turns, w.min(vr));
                let bound = normal_at(q, qh, vr, w);
                assert!(
                    bound >= exact * (1.0 - 1e-12) - 1e-9,
                    "{turns:?} {w}: {bound} < {exact}"
                );
                // ... and never above the linear form it replaces.
                assert!(
                    bound <= q * w.min(vr) * (1.0 + 1e-12) + 1e-9,
                    "{turns:?} {w}"
                );
            }
        }
    }

    /// The closed form is the fixed point: braking from the reach at a(reach) over L ends at
    /// v_from, and the acceleration is the one of that speed.
    #[test]
    fn reach_is_the_fixed_point_of_the_speed_dependent_acceleration() {
        let b = budget();
        // (Fixed points below the knots, between a knot and v_ref, and above, at both ends.)
        for (v_from, len) in [
            (0.0, 0.2),
            (20.0, 0.2),
            (60.0, 5.0),
            (90.0, 0.05),
            (0.0, 40.0),
            (0.0, 0.001),
            (5.0, 0.01),
            (25.0, 0.1),
            (40.0, 0.3),
            (48.0, 0.5),
            (70.0, 1.0),
            (100.0, 0.02),
        ] {
            let v = b.reach_mm_s(v_from, len);
            let rhs = (v_from * v_from + 2.0 * len * b.linear_accel_at(v)).sqrt();
            assert!(
                (v - rhs).abs() < 1e-9 * v.max(1.0),
                "{v_from} {len}: {v} vs {rhs}"
            );
            // The chords leave at least the linear bound.
            assert!(b.accel_at(v) >= b.linear_accel_at(v) * (1.0 - 1e-12));
        }
        // Slow lines get more of the axes than fast ones; the floor holds.
        assert!(b.accel_at(10.0) > b.accel_at(90.0));
        assert_eq!(b.accel_at(1e6), b.accel_at(100.0));
        assert!(b.accel_at(1e6) >= 400.0);
    }
}
