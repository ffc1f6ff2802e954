//! Speed criteria of the envelope velocity (SPEC §7.2), as pure functions.
//!
//! Angles are the turn between tangents (0 = straight on, π = reversal), radians.

use crate::units::TS_S;

/// Dynamic criterion (R385): vm = am·Ts / (2·sin(α/2)): the velocity step at the junction,
/// taken within one tick, is an acceleration of at most `am`.
///
/// Block-length correction 8.R385 (**decided**): with reference length `ref_len_mm` > 0 and
/// mean adjacent block length L below it, vm is scaled by √(L/ref). Reason: am was tuned on a
/// test polyline of blocks of length ref; on a polyline of the same turn per block but
/// shorter blocks the curvature is α/L, and the same centripetal acceleration v²·α/L allows
/// √(L/ref) of the speed. Longer blocks are not corrected upwards.
pub fn dynamic_mm_s(am_mm_s2: f64, turn_rad: f64, ref_len_mm: f64, len_mm: f64) -> f64 {
    let s = (turn_rad / 2.0).sin();
    if s <= 1e-12 {
        return f64::INFINITY;
    }
    let vm = am_mm_s2 * TS_S / (2.0 * s);
    if ref_len_mm > 0.0 && len_mm < ref_len_mm {
        vm * (len_mm / ref_len_mm).sqrt()
    } else {
        vm
    }
}

/// Accuracy criterion (R384 d1..4): vm = Lm / (Ts·tan(α/2)). `lm_um` = 0 turns it off.
/// For α ≥ 180° the junction is a reversal and the speed must be zero.
pub fn accuracy_mm_s(lm_um: f64, turn_rad: f64) -> f64 {
    if lm_um <= 0.0 {
        return f64::INFINITY;
    }
    let t = (turn_rad / 2.0).tan();
    if t <= 1e-12 {
        return f64::INFINITY;
    }
    if !t.is_finite() || t > 1e12 {
        return 0.0;
    }
    lm_um * 1e-3 / (TS_S * t)
}

/// The turn between two unit tangents, kept as |t1 − t0| = 2·sin(α/2) and |t1 + t0| =
/// 2·cos(α/2): exact for tiny angles and free of trigonometric calls.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Turn {
    pub chord: f64,
    pub sum: f64,
}

impl Turn {
    /// No turn: |t1 − t0| = 0, |t1 + t0| = 2.
    pub const STRAIGHT: Turn = Turn {
        chord: 0.0,
        sum: 2.0,
    };

    pub fn between(t0: &crate::units::AxesMm, t1: &crate::units::AxesMm, axes: usize) -> Turn {
        Turn {
            chord: (*t1 - *t0).norm(axes),
            sum: (*t1 + *t0).norm(axes),
        }
    }

    /// Dynamic criterion vm = am·Ts / (2·sin(α/2)) without the length correction.
    pub fn dynamic_mm_s(&self, am_mm_s2: f64) -> f64 {
        if self.chord <= 1e-12 {
            f64::INFINITY
        } else {
            am_mm_s2 * TS_S / self.chord
        }
    }

    /// [`Turn::dynamic_mm_s`] with the length correction of [`dynamic_mm_s`]: ×√(len/ref)
    /// for blocks shorter than the reference length.
    pub fn dynamic_len_mm_s(&self, am_mm_s2: f64, ref_len_mm: f64, len_mm: f64) -> f64 {
        let vm = self.dynamic_mm_s(am_mm_s2);
        if ref_len_mm > 0.0 && len_mm < ref_len_mm {
            vm * (len_mm / ref_len_mm).sqrt()
        } else {
            vm
        }
    }

    /// Accuracy criterion vm = Lm / (Ts·tan(α/2)); `lm_um` = 0 turns it off.
    pub fn accuracy_mm_s(&self, lm_um: f64) -> f64 {
        if lm_um <= 0.0 || self.chord <= 1e-12 {
            f64::INFINITY
        } else {
            lm_um * 1e-3 * self.sum / (TS_S * self.chord)
        }
    }
}

/// Curvature cap v ≤ √(a/κ) (SPEC §7.2 physics note), κ in 1/mm.
pub fn curvature_mm_s(a_mm_s2: f64, curvature_per_mm: f64) -> f64 {
    if curvature_per_mm <= 1e-15 {
        f64::INFINITY
    } else {
        (a_mm_s2 / curvature_per_mm).sqrt()
    }
}

/// Geometric criterion on arcs (R232 d1..4): the chord of one tick deviates from the circle by
/// (v·Ts)²/(8R) ≤ e, so v ≤ √(8·R·e)/Ts.
pub fn arc_chord_mm_s(radius_mm: f64, chord_um: f64) -> f64 {
    if chord_um <= 0.0 {
        f64::INFINITY
    } else {
        (8.0 * radius_mm * chord_um * 1e-3).sqrt() / TS_S
    }
}

/// Jerk cap on a circle: the axis jerk of uniform circular motion is v³/R², so v ≤ ∛(J·R²).
pub fn arc_jerk_mm_s(jerk_mm_s3: f64, radius_mm: f64) -> f64 {
    if jerk_mm_s3.is_finite() {
        (jerk_mm_s3 * radius_mm * radius_mm).cbrt()
    } else {
        f64::INFINITY
    }
}

/// Axis smoothing filter (parabolic profile, see `docs/planner.md` §"Axis jerk"): the
/// setpoints are the path positions averaged twice over `T = n·Ts`. With u(t) the path
/// velocity vector, the filtered axes have
/// - jerk  = (u(t) − 2u(t−T) + u(t−2T)) / T²,
/// - accel = mean over T of (u(t) − u(t−T)) / T,
/// - and lie within v·|Δt|·T/6 of a corner (mean absolute deviation T/3 of the kernel) and
///   v²κT²/12 inside a circle (variance T²/6 of the kernel).
///
/// Sampling the unit tangent at the path points a distance h = v·T apart around a junction
/// turns these into speed limits; [`FilterWindow`] holds those tangents.
#[derive(Clone, Copy, Debug)]
pub struct FilterWindow {
    /// Tangents at −h, just before the junction, just after it, and at +h.
    pub before: crate::units::AxesMm,
    pub end: crate::units::AxesMm,
    pub start: crate::units::AxesMm,
    pub after: crate::units::AxesMm,
}

impl FilterWindow {
    /// Whether speed `v` (mm/s) keeps, on every axis, the jerk of the filtered setpoints within
    /// `jerk_budget` (per axis, mm/s³) when the path acceleration is at most `a_mm_s2`, their
    /// acceleration within `accel_budget` (per axis), and their distance from the corner within
    /// `lm_mm` (0 = no accuracy limit). `t_s` = filter time T.
    #[allow(clippy::too_many_arguments)]
    pub fn allows(
        &self,
        v: f64,
        a_mm_s2: f64,
        t_s: f64,
        axes: usize,
        jerk_budget: &[f64],
        accel_budget: &[f64],
        lm_mm: f64,
    ) -> bool {
        let mut d1_norm = [0.0f64; 3];
        for i in 0..axes {
            let d1a = (self.end[i] - self.before[i]).abs();
            let d1b = (self.after[i] - self.start[i]).abs();
            let dc = (self.start[i] - self.end[i]).abs();
            let mid = self.after[i] + self.before[i];
            let d2 = (mid - 2.0 * self.end[i])
                .abs()
                .max((mid - 2.0 * self.start[i]).abs());
            // Second difference of u over lag T: v·Δ²t plus the speed change over T times
            // the direction changes it meets. Around the junction the interpolator keeps the
            // speed within v (its cap zone), so that change is at most min(a·T, v).
            let dv = (a_mm_s2 * t_s).min(v);
            if v * d2 + dv * (d1a + d1b + dc) > jerk_budget[i] * t_s * t_s {
                return false;
            }
            if v * d1a.max(d1b).max(dc) > accel_budget[i] * t_s {
                return false;
            }
            d1_norm[0] += d1a * d1a;
            d1_norm[1] += d1b * d1b;
            d1_norm[2] += dc * dc;
        }
        let d1 = d1_norm.iter().fold(0.0f64, |m, x| m.max(x.sqrt()));
        lm_mm <= 0.0 || v * d1 * t_s / 6.0 <= lm_mm
    }
}

/// Inside an arc of radius R with the axis filter of time `t_s`: the per-axis jerk of circular
/// motion with path acceleration a is at most v³/R² + 3·v·a/R on top of the path jerk (kept
/// within `jerk_budget`), and the filter pulls the setpoints v²T²/(12R) inwards (kept within
/// `lm_mm`, 0 = off). Returns the largest speed within both.
pub fn arc_filtered_mm_s(
    radius_mm: f64,
    a_mm_s2: f64,
    jerk_budget_mm_s3: f64,
    t_s: f64,
    lm_mm: f64,
) -> f64 {
    let k = 1.0 / radius_mm;
    let mut v = f64::INFINITY;
    if lm_mm > 0.0 && t_s > 0.0 {
        v = (12.0 * lm_mm * radius_mm).sqrt() / t_s;
    }
    if jerk_budget_mm_s3.is_finite() {
        // f(v) = v³κ² + 3vaκ is increasing: bisect f(v) = budget.
        let f = |v: f64| v * v * v * k * k + 3.0 * v * a_mm_s2 * k;
        let mut hi = (jerk_budget_mm_s3 * radius_mm * radius_mm).cbrt();
        let mut lo = 0.0;
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if f(mid) <= jerk_budget_mm_s3 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        v = v.min(lo);
    }
    v
}

/// Minimum block duration: v ≤ L / t_min (0 = off).
pub fn min_duration_mm_s(len_mm: f64, t_min_s: f64) -> f64 {
    if t_min_s > 0.0 {
        len_mm / t_min_s
    } else {
        f64::INFINITY
    }
}

/// R395 time criterion of the linear profile (SPEC §7.2, seed 004 A6.3): a block that would
/// take less than `limit_s` at the junction speeds `v_flat` keeps them through the block;
/// a longer one may rise towards F and fall again inside it (**decided**: the block's time
/// at the speeds it would keep, the manual's "longer blocks would run unnecessarily
/// slowly"). A flat speed of zero is never kept.
pub fn rise_allowed_linear(len_mm: f64, v_flat: f64, limit_s: f64) -> bool {
    v_flat <= 1e-9 || len_mm / v_flat >= limit_s
}

/// R395 time criterion of the parabolic profile (SPEC §7.3): whether rising inside a block of length `len_mm` from and back to
/// `v_flat` towards `v_top` (acceleration `a`) saves more than `limit_s` over keeping
/// `v_flat` through the block. A flat speed of zero is never kept.
pub fn rise_pays_off(len_mm: f64, v_flat: f64, v_top: f64, a: f64, limit_s: f64) -> bool {
    if v_flat <= 1e-9 || v_top <= v_flat {
        return v_flat <= 1e-9;
    }
    let t_flat = len_mm / v_flat;
    // Triangle or trapezoid from v_flat up to the peak and back.
    let v_peak = v_top.min((v_flat * v_flat + a * len_mm).sqrt());
    let ramp_len = (v_peak * v_peak - v_flat * v_flat) / a;
    let t_rise = 2.0 * (v_peak - v_flat) / a + (len_mm - ramp_len).max(0.0) / v_peak;
    t_flat - t_rise > limit_s
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn dynamic_criterion_matches_formula() {
        // am = 1000 mm/s², α = 90°: vm = 1000·0.004/(2·sin 45°) = 2.828 mm/s.
        let v = dynamic_mm_s(1000.0, PI / 2.0, 0.0, 1.0);
        assert!((v - 4.0 / (2.0 * (PI / 4.0).sin())).abs() < 1e-12);
        assert_eq!(dynamic_mm_s(1000.0, 0.0, 0.0, 1.0), f64::INFINITY);
        // Correction: a quarter of the reference length halves the speed.
        let c = dynamic_mm_s(1000.0, PI / 2.0, 0.2, 0.05);
        assert!((c / v - 0.5).abs() < 1e-12);
        assert_eq!(dynamic_mm_s(1000.0, PI / 2.0, 0.2, 1.0), v);
    }

    #[test]
    fn accuracy_criterion_matches_formula() {
        // Lm = 8 µm, α = 10°: 0.008/(0.004·tan 5°) = 22.86 mm/s.
        let v = accuracy_mm_s(8.0, 10f64.to_radians());
        assert!((v - 0.008 / (0.004 * 5f64.to_radians().tan())).abs() < 1e-9);
        assert_eq!(accuracy_mm_s(0.0, 1.0), f64::INFINITY);
        assert!(accuracy_mm_s(8.0, PI) < 1e-9);
    }

    #[test]
    fn turn_forms_agree_with_the_angle_forms() {
        use crate::units::AxesMm;
        for deg in [0.01f64, 1.0, 10.0, 90.0, 170.0] {
            let a = deg.to_radians();
            let t0 = AxesMm([1.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
            let t1 = AxesMm([a.cos(), a.sin(), 0.0, 0.0, 0.0, 0.0]);
            let t = Turn::between(&t0, &t1, 3);
            let d = dynamic_mm_s(1000.0, a, 0.0, 1.0);
            let l = accuracy_mm_s(8.0, a);
            assert!((t.dynamic_mm_s(1000.0) / d - 1.0).abs() < 1e-9, "{deg}");
            assert!((t.accuracy_mm_s(8.0) / l - 1.0).abs() < 1e-9, "{deg}");
        }
    }

    #[test]
    fn filter_window_limits_an_isolated_corner() {
        use crate::units::AxesMm;
        // 90° corner X → Y: |Δt| = 1 on both axes. Jerk: v·1 + min(a·T, v)·1 ≤ B·T²;
        // accuracy: v·√2·T/6 ≤ Lm.
        let x = AxesMm([1.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        let y = AxesMm([0.0, 1.0, 0.0, 0.0, 0.0, 0.0]);
        let w = FilterWindow {
            before: x,
            end: x,
            start: y,
            after: y,
        };
        let (t, b, a) = (0.008, 20_000.0, 1000.0);
        let budget = [b; 6];
        let wide = [1e9; 6];
        // Jerk alone: 2v ≤ B·T² (v < a·T) → v ≤ 0.64 mm/s.
        let v_j = b * t * t / 2.0;
        assert!(w.allows(v_j * 0.999, a, t, 3, &budget, &wide, 0.0));
        assert!(!w.allows(v_j * 1.001, a, t, 3, &budget, &wide, 0.0));
        // Accuracy alone: v ≤ 6·Lm/(√2·T).
        let lm = 0.004;
        let v_l = 6.0 * lm / (2f64.sqrt() * t);
        assert!(w.allows(v_l * 0.999, a, t, 3, &wide, &wide, lm));
        assert!(!w.allows(v_l * 1.001, a, t, 3, &wide, &wide, lm));
        // Straight on: no limit.
        let s = FilterWindow {
            before: x,
            end: x,
            start: x,
            after: x,
        };
        assert!(s.allows(1e6, a, t, 3, &budget, &budget, lm));
    }

    #[test]
    fn arc_under_the_axis_filter() {
        // R = 10, a = 0: v³/R² = B → v = ∛(B·R²); accuracy v²T²/(12R) = Lm.
        let v = arc_filtered_mm_s(10.0, 0.0, 20_000.0, 0.008, 0.0);
        assert!((v - (20_000.0f64 * 100.0).cbrt()).abs() < 1e-6);
        let v = arc_filtered_mm_s(10.0, 0.0, f64::INFINITY, 0.008, 0.004);
        assert!((v * v * 0.008 * 0.008 / 120.0 - 0.004).abs() < 1e-12);
        // Acceleration on the arc costs speed.
        assert!(arc_filtered_mm_s(10.0, 500.0, 20_000.0, 0.008, 0.0) < 125.0);
    }

    #[test]
    fn rise_criterion() {
        // 0.1 mm at 10 mm/s takes 10 ms; rising cannot save 500 ms.
        assert!(!rise_pays_off(0.1, 10.0, 100.0, 1000.0, 0.5));
        // 100 mm at 1 mm/s takes 100 s; rising saves almost all of it.
        assert!(rise_pays_off(100.0, 1.0, 100.0, 1000.0, 0.5));
        assert!(rise_pays_off(100.0, 0.0, 100.0, 1000.0, 0.5));
        // Linear profile: 1.03 mm at 2 mm/s takes 0.515 s, over R395's 0.5 s: it rises.
        assert!(rise_allowed_linear(1.03, 2.0, 0.5));
        assert!(!rise_allowed_linear(0.9, 2.0, 0.5));
        assert!(rise_allowed_linear(0.1, 0.0, 0.5));
    }
}
