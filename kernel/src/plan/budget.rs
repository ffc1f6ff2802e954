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

#[derive(Clone, Copy, Debug, Default)]
pub(super) struct LineBudget {
    /// Per moving axis: (a_k/d_k, q_k/d_k) in mm/s² and 1/s.
    terms: [(f64, f64); MAX_AXES],
    count: usize,
    /// Speed above which the turns add no more normal acceleration, mm/s.
    v_ref_mm_s: f64,
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
    pub(super) fn new(v_ref_mm_s: f64, a_axes_mm_s2: f64, a_floor_mm_s2: f64, base: f64) -> Self {
        LineBudget {
            terms: [(0.0, 0.0); MAX_AXES],
            count: 0,
            v_ref_mm_s,
            a_axes_mm_s2,
            a_floor_mm_s2,
            base_mm_s2: base,
            margin_mm_s: a_axes_mm_s2 * TS_S,
        }
    }

    /// Adds an axis: its limit a_k, normal term q_k (N_k(v) ≤ q_k·min(v, v_ref)) and the
    /// largest tangent component d_k near the line.
    pub(super) fn add_axis(&mut self, a_k: f64, q_k: f64, d_k: f64) {
        if d_k > 1e-12 && self.count < MAX_AXES {
            self.terms[self.count] = (a_k / d_k, q_k / d_k);
            self.count += 1;
        }
    }

    /// Tangential acceleration the axes leave at speeds up to `v`, within [floor, A]
    /// (not capped by the constants: the stop set has its own).
    pub(super) fn tangential_at(&self, v: f64) -> f64 {
        let w = (v + self.margin_mm_s).min(self.v_ref_mm_s);
        // (Plain comparisons where the running value starts at ∞: they skip a NaN term as
        // `min` does, at a quarter of the cost; this runs on every braking step.)
        let mut a = f64::INFINITY;
        for &(p, q) in &self.terms[..self.count] {
            let x = p - q * w;
            if x < a {
                a = x;
            }
        }
        a.min(self.a_axes_mm_s2).max(self.a_floor_mm_s2)
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

    /// Highest speed v with v² ≤ v_from² + 2·L·a(v): the fastest a line of length L can run
    /// while still braking to `v_from` at its end (or when accelerating from `v_from` at its
    /// start). Closed form per term: a(v) is the max of the floor and the min of linear
    /// functions of min(v, v_ref), and g(v) = v_from² + 2·L·a(v) − v² falls with v, so the
    /// fixed point of a min (max) of terms is the min (max) of their fixed points.
    pub(super) fn reach_mm_s(&self, v_from: f64, length_mm: f64) -> f64 {
        let v2 = v_from * v_from;
        let constant = |a: f64| (v2 + 2.0 * length_mm * a.max(0.0)).sqrt();
        let hi = self.base_mm_s2.min(self.a_axes_mm_s2);
        let mut v = constant(hi);
        // a(v) with min(v + margin, v_ref) = margin + min(v, v_ref − margin).
        let v_ref = (self.v_ref_mm_s - self.margin_mm_s).max(0.0);
        let margin = self.margin_mm_s.min(self.v_ref_mm_s);
        for &(p, q) in &self.terms[..self.count] {
            let p = p - q * margin;
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
        let mut b = LineBudget::new(100.0, 800.0, 400.0, 1000.0);
        b.add_axis(800.0, 0.0, 1.0);
        b.add_axis(800.0, 8.0, 0.3);
        b
    }

    /// The closed form is the fixed point: braking from the reach at a(reach) over L ends at
    /// v_from, and the acceleration is the one of that speed.
    #[test]
    fn reach_is_the_fixed_point_of_the_speed_dependent_acceleration() {
        let b = budget();
        for (v_from, len) in [
            (0.0, 0.2),
            (20.0, 0.2),
            (60.0, 5.0),
            (90.0, 0.05),
            (0.0, 40.0),
        ] {
            let v = b.reach_mm_s(v_from, len);
            let rhs = (v_from * v_from + 2.0 * len * b.accel_at(v)).sqrt();
            assert!(
                (v - rhs).abs() < 1e-9 * v.max(1.0),
                "{v_from} {len}: {v} vs {rhs}"
            );
        }
        // Slow lines get more of the axes than fast ones; the floor holds.
        assert!(b.accel_at(10.0) > b.accel_at(90.0));
        assert_eq!(b.accel_at(1e6), b.accel_at(100.0));
        assert!(b.accel_at(1e6) >= 400.0);
    }
}
