//! Planner settings: machine axis limits plus the continuity and envelope-velocity settings
//! read from the R constants (SPEC §7).

use crate::constants::Constants;
use crate::units::{AxesMm, MAX_AXES};

/// Velocity profile of the envelope velocity (2.R338, SPEC §7.2 / §7.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Profile {
    /// 2.R338 = 1 (and, **decided**, 0): acceleration-limited, speed changes linearly.
    Linear,
    /// 2.R338 = 2: jerk-limited, speed follows parabolas.
    Parabolic,
}

/// How G23 junctions are judged smooth (1.R97, SPEC §7.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ContinuityRule {
    /// 1.R97 = 1 (and 0): the junction is smooth iff the next block has G23 and is a feed move.
    Manual,
    /// 1.R97 = 2: additionally the tangent angle must be below R39 and both blocks must last at
    /// least the minimum block duration.
    Automatic,
}

/// Converts the parabolic ramp P of a dynamic set to a path jerk (SPEC §7.3): with
/// T = 1.478·√(F/P) s (F in mm/min) for a pure-parabola ramp, J = 4·P/(60·1.478²) mm/s³.
pub fn jerk_from_p_mm_s3(p: f64) -> f64 {
    4.0 * p / (60.0 * 1.478 * 1.478)
}

/// One dynamic parameter set (SPEC §7.4): limits of the envelope velocity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DynamicSet {
    /// Linear ramp A: maximum path acceleration, mm/s².
    pub accel_mm_s2: f64,
    /// Path jerk from the parabolic ramp P, mm/s³ (`INFINITY`: no jerk limit).
    pub jerk_mm_s3: f64,
    /// Accuracy criterion Lm, µm (0 = off), SPEC §7.2 (R384 d1..4).
    pub accuracy_um: f64,
    /// Speed-drop percentage for the diagnostics (R384 d5..6).
    pub drop_percent: f64,
    /// Dynamic criterion am, mm/s² (R385 d1..7; 0 = use the axis limits).
    pub overload_mm_s2: f64,
    /// Reference block length of the dynamic-criterion correction (8.R385 = 1..4), mm; 0 = off.
    pub overload_ref_len_mm: f64,
    /// Centripetal acceleration on arcs, mm/s² (R411 new form or R232 d5..8 old form).
    pub centripetal_mm_s2: f64,
}

/// Envelope-velocity and continuity settings (SPEC §7), from the R constants.
///
/// Reading of the constants (**decided**): constants the manual gives in an integer unit
/// (µm, ms, mm/s², the ramp P) are read as their digit string, as every example in the
/// manual shows: R384 = 0.008 → Lm 8 µm, R385 = 10.000 → am 10000 mm/s² (the manual's graph
/// spans am = 2000..32000), R395 = 0.500 → 500 ms, R407 = 50.000 → P = 50000 (range
/// 10000..150000), R408 = 0.600 → A = 600 mm/s², R411 = 4.000 → 4000/10 = 400 mm/s².
/// Constants in mm or degrees (R39, R382, R383) and R52/R236/R237 (mm/s²) are read as values.
#[derive(Clone, Debug, PartialEq)]
pub struct Envelope {
    pub profile: Profile,
    pub rule: ContinuityRule,
    /// R39: largest tangent angle of an automatically smooth junction, degrees.
    pub smooth_angle_deg: f64,
    /// R52: path acceleration without continuity (G98/G24), mm/s².
    pub accel_stop_mm_s2: f64,
    /// R236: path acceleration during continuity (0 in the constant → R52), mm/s².
    pub accel_cont_mm_s2: f64,
    /// R237: rapid acceleration, mm/s².
    pub accel_rapid_mm_s2: f64,
    /// R232 d1..4: largest chord deviation per tick on arcs, µm (0 = off).
    pub arc_chord_um: f64,
    /// R382: a block shorter than this breaks continuity, mm (`None` = off).
    pub break_len_mm: Option<f64>,
    /// R383: a line shorter than this is merged into its predecessor, mm (`None` = off).
    pub merge_len_mm: Option<f64>,
    /// R395: rise inside a block only if that saves more than this, s.
    pub rise_time_s: f64,
    /// Dynamic sets 1..4 (index 0..3), already completed by the set-1 fallback rule (§7.4).
    pub sets: [DynamicSet; 4],
    /// Rapid and stop set (R430..R432): acceleration and jerk for G0 and for STOP.
    pub rapid_accel_mm_s2: f64,
    pub rapid_jerk_mm_s3: f64,
}

/// Machine limits and settings of the planner.
#[derive(Clone, Debug, PartialEq)]
pub struct PlannerConfig {
    /// Number of axes in use.
    pub axes: usize,
    /// Per-axis maximum velocity (also the rapid speed), mm/s.
    pub axis_v_max_mm_s: [f64; MAX_AXES],
    /// Per-axis maximum acceleration, mm/s².
    pub axis_a_max_mm_s2: [f64; MAX_AXES],
    /// Per-axis maximum jerk, mm/s³ (used by the parabolic profile).
    pub axis_j_max_mm_s3: [f64; MAX_AXES],
    /// Minimum block duration, s (SPEC §7.2; the manual's 4 ms by default). 0 lets short
    /// blocks run at the programmed feed where the other criteria allow, since the
    /// interpolator crosses several blocks within one tick.
    pub min_block_time_s: f64,
    /// Look-ahead window, blocks (SPEC §7.2: 500).
    pub lookahead_blocks: usize,
    /// Axis smoothing filter of the parabolic profile, ticks per stage (1 = none): keeps the
    /// per-axis jerk bounded where the path turns (see [`axis_filter_ticks_for`]).
    pub axis_filter_ticks: usize,
    pub envelope: Envelope,
}

/// Longest axis smoothing filter, ticks per stage.
pub const AXIS_FILTER_MAX_TICKS: usize = 16;

/// Length of the axis smoothing filter (parabolic profile, **decided**, `docs/planner.md`):
/// a corner of turn |Δt| crossed at v is limited by the axis jerk to v·|Δt| ≤ B·T²
/// (B = corner share of the axis jerk) and by the accuracy Lm to v·|Δt| ≤ 3·(Lm/2)/T; the
/// filter time T = ∛(1.5·Lm/B) makes both equal, which gives the fastest corners. Without an
/// accuracy criterion 4 ticks. At least 2 ticks.
pub fn axis_filter_ticks_for(lm_um: f64, corner_jerk_mm_s3: f64) -> usize {
    let t = if lm_um > 0.0 && corner_jerk_mm_s3.is_finite() && corner_jerk_mm_s3 > 0.0 {
        (1.5 * lm_um * 1e-3 / corner_jerk_mm_s3).cbrt()
    } else {
        4.0 * crate::units::TS_S
    };
    ((t / crate::units::TS_S).round() as usize).clamp(2, AXIS_FILTER_MAX_TICKS)
}

/// Limits of one machine axis, as a machine configuration gives them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisLimits {
    pub v_max_mm_s: f64,
    pub a_max_mm_s2: f64,
}

/// Limits of an axis the daemon's configuration does not set (`[[axes]]` without
/// `max_velocity_mm_min` / `max_accel_mm_s2`): 12000 mm/min, 800 mm/s².
pub const DEFAULT_AXIS_LIMITS: AxisLimits = AxisLimits {
    v_max_mm_s: 200.0,
    a_max_mm_s2: 800.0,
};

/// Axis jerk per unit of axis acceleration, 1/s: the machine configuration has no jerk
/// setting, so an axis's jerk limit is 50·a (a/J = 20 ms).
pub const AXIS_JERK_PER_ACCEL_PER_S: f64 = 50.0;

impl PlannerConfig {
    /// The planner configuration of a machine: what `cncd` runs, and what the planner bench
    /// runs (one function, so the figures are the daemon's). Per-axis velocity, acceleration
    /// and jerk (50·a) from `axes`; the minimum block duration (SPEC §7.2, 0 = off); the
    /// envelope settings from the machine constants when there is a constants file.
    ///
    /// Without constants (or where a constant is 0) the path-level accelerations and jerks
    /// are unbounded, so only the axes a move actually moves limit it (A = min over axes with
    /// u_i ≠ 0 of a_i/|u_i|, issue #24): an axis that does not move never slows a move down.
    pub fn for_machine(
        axes: &[AxisLimits],
        min_block_time_s: f64,
        constants: Option<&Constants>,
    ) -> Self {
        let n = axes.len().min(MAX_AXES);
        let mut cfg = PlannerConfig::uniform(n, f64::INFINITY, f64::INFINITY);
        for (i, a) in axes.iter().take(MAX_AXES).enumerate() {
            cfg.axis_v_max_mm_s[i] = a.v_max_mm_s;
            cfg.axis_a_max_mm_s2[i] = a.a_max_mm_s2;
            cfg.axis_j_max_mm_s3[i] = AXIS_JERK_PER_ACCEL_PER_S * a.a_max_mm_s2;
        }
        cfg.min_block_time_s = min_block_time_s.max(0.0);
        match constants {
            Some(c) => cfg.with_constants(c),
            None => cfg,
        }
    }

    /// Limits with the same velocity and acceleration on the first `axes` axes, and defaults
    /// for everything else: linear profile, manual continuity, R39 = 60°, dynamic criterion
    /// at the axis acceleration, accuracy criterion 10 µm, jerk 50·a per axis, 4 ms minimum
    /// block duration, 500 blocks of look-ahead.
    pub fn uniform(axes: usize, v_max_mm_s: f64, a_max_mm_s2: f64) -> Self {
        let set = DynamicSet {
            accel_mm_s2: a_max_mm_s2,
            jerk_mm_s3: 50.0 * a_max_mm_s2,
            accuracy_um: 10.0,
            drop_percent: 20.0,
            overload_mm_s2: a_max_mm_s2,
            overload_ref_len_mm: 0.0,
            centripetal_mm_s2: a_max_mm_s2,
        };
        PlannerConfig {
            axes,
            axis_v_max_mm_s: [v_max_mm_s; MAX_AXES],
            axis_a_max_mm_s2: [a_max_mm_s2; MAX_AXES],
            axis_j_max_mm_s3: [50.0 * a_max_mm_s2; MAX_AXES],
            min_block_time_s: 0.004,
            lookahead_blocks: 500,
            axis_filter_ticks: 1,
            envelope: Envelope {
                profile: Profile::Linear,
                rule: ContinuityRule::Manual,
                smooth_angle_deg: 60.0,
                accel_stop_mm_s2: a_max_mm_s2,
                accel_cont_mm_s2: a_max_mm_s2,
                accel_rapid_mm_s2: a_max_mm_s2,
                arc_chord_um: 0.0,
                break_len_mm: None,
                merge_len_mm: None,
                rise_time_s: 0.0,
                sets: [set; 4],
                rapid_accel_mm_s2: a_max_mm_s2,
                rapid_jerk_mm_s3: 50.0 * a_max_mm_s2,
            },
        }
    }

    /// Replaces the envelope settings by those of the R constants (SPEC §7), keeping the axis
    /// limits. Accelerations from the constants are path values and are further capped by the
    /// axis limits when planning.
    pub fn with_constants(mut self, c: &Constants) -> Self {
        self.envelope = Envelope::from_constants(c, &self);
        self.axis_filter_ticks = match self.envelope.profile {
            Profile::Linear => 1,
            Profile::Parabolic => {
                let j = self.axis_j_max_mm_s3[..self.axes.max(1)]
                    .iter()
                    .fold(f64::INFINITY, |m, v| m.min(*v));
                axis_filter_ticks_for(self.envelope.sets[0].accuracy_um, j * super::NORMAL_SHARE)
            }
        };
        self
    }

    /// Time of one stage of the axis smoothing filter, s (0 without the filter).
    pub fn axis_filter_s(&self) -> f64 {
        if self.axis_filter_ticks > 1 {
            self.axis_filter_ticks as f64 * crate::units::TS_S
        } else {
            0.0
        }
    }

    /// Largest path speed and acceleration along `dir` (unit vector) that keep every axis
    /// within its own limit.
    pub fn path_limits(&self, dir: &AxesMm) -> (f64, f64) {
        let mut v = f64::INFINITY;
        let mut a = f64::INFINITY;
        for i in 0..self.axes {
            let c = dir[i].abs();
            if c > 1e-12 {
                v = v.min(self.axis_v_max_mm_s[i] / c);
                a = a.min(self.axis_a_max_mm_s2[i] / c);
            }
        }
        (v, a)
    }

    /// Largest path jerk along `dir` that keeps every axis within its jerk limit.
    pub fn path_jerk(&self, dir: &AxesMm) -> f64 {
        let mut j = f64::INFINITY;
        for i in 0..self.axes {
            let c = dir[i].abs();
            if c > 1e-12 {
                j = j.min(self.axis_j_max_mm_s3[i] / c);
            }
        }
        j
    }

    /// Smallest jerk limit of the axes that move along `dir`.
    pub fn iso_jerk(&self, dir: &AxesMm) -> f64 {
        let mut m = f64::INFINITY;
        for i in 0..self.axes {
            if dir[i].abs() > 1e-12 {
                m = m.min(self.axis_j_max_mm_s3[i]);
            }
        }
        m
    }

    /// Smallest acceleration limit of the axes that move in `a` or `b`: an isotropic bound
    /// used for accelerations normal to the path, whose direction the planner does not track.
    pub fn iso_accel(&self, a: &AxesMm, b: &AxesMm) -> f64 {
        let mut m = f64::INFINITY;
        for i in 0..self.axes {
            if a[i].abs() > 1e-12 || b[i].abs() > 1e-12 {
                m = m.min(self.axis_a_max_mm_s2[i]);
            }
        }
        m
    }
}

/// Value of a constant, or `None` when zero (a zero value in a set falls back to set 1).
fn nonzero(v: f64) -> Option<f64> {
    (v != 0.0).then_some(v)
}

impl Envelope {
    /// Reads SPEC §7 settings from the constants. Dynamic-set entries that refer to program
    /// parameters (control word d2..d6 = 1) are not resolvable here and fall back to set 1.
    pub fn from_constants(c: &Constants, cfg: &PlannerConfig) -> Envelope {
        // A constant left at 0 means "the axis limits": unbounded at path level, so each move
        // is limited by the axes it moves only (issue #24).
        let a_axes = f64::INFINITY;
        let j_axes = f64::INFINITY;
        // Only the old centripetal form needs a finite acceleration (a percentage of R52).
        let a_slowest = cfg.axis_a_max_mm_s2[..cfg.axes.max(1)]
            .iter()
            .fold(f64::INFINITY, |m, v| m.min(*v));
        let profile = if c.decade(338, 2) == 2 {
            Profile::Parabolic
        } else {
            Profile::Linear
        };
        let rule = if c.decade(97, 1) == 2 {
            ContinuityRule::Automatic
        } else {
            ContinuityRule::Manual
        };
        let accel_stop = nonzero(c.get(52).abs()).unwrap_or(a_axes);
        let accel_cont = nonzero(c.get(236).abs()).unwrap_or(accel_stop);
        let accel_rapid = nonzero(c.get(237).abs()).unwrap_or(accel_stop);
        let len_setting = |r: u16| (!c.is_negative(r)).then(|| c.get(r)).filter(|v| *v > 0.0);
        // R395 in ms, 0 → 500 ms.
        let rise_ms = nonzero(c.field_digits(395, 1, 8) as f64).unwrap_or(500.0);
        // Global (set-less) criteria: R384, R385, R232.
        // R232 d5..8 old form: percent of √(R·a) (**decided**: v ≤ p/100·√(R·R52), i.e. a
        // centripetal acceleration of (p/100)²·R52). 0 = off.
        let old_ref = nonzero(c.get(52).abs()).unwrap_or(a_slowest);
        let old_centripetal = |pct: f64| {
            if pct > 0.0 {
                (pct / 100.0).powi(2) * old_ref
            } else {
                f64::INFINITY
            }
        };
        let global = DynamicSet {
            accel_mm_s2: accel_cont,
            jerk_mm_s3: j_axes,
            accuracy_um: c.field_digits(384, 1, 4) as f64,
            drop_percent: c.field_digits(384, 5, 6) as f64,
            overload_mm_s2: nonzero(c.field_digits(385, 1, 7) as f64).unwrap_or(a_axes),
            overload_ref_len_mm: ref_len(c.decade(385, 8)),
            centripetal_mm_s2: old_centripetal(c.field_digits(232, 5, 8) as f64),
        };
        let sets = dynamic_sets(c, global, &old_centripetal);
        // Rapid and stop set R430..R432 (control, P, A); falls back to set 1 / R237.
        let (mut rapid_a, mut rapid_j) = (accel_rapid, sets[0].jerk_mm_s3);
        if c.decade(430, 1) == 1 {
            if let Some(p) = nonzero(c.field_digits(431, 1, 7) as f64) {
                rapid_j = jerk_from_p_mm_s3(p * p_scale(c, 431));
            }
            if let Some(a) = nonzero(c.field_digits(432, 1, 8) as f64) {
                rapid_a = a;
            }
        } else if c.decade(406, 1) == 1 {
            rapid_a = sets[0].accel_mm_s2;
        }
        Envelope {
            profile,
            rule,
            smooth_angle_deg: c.get(39).abs(),
            accel_stop_mm_s2: accel_stop,
            accel_cont_mm_s2: accel_cont,
            accel_rapid_mm_s2: accel_rapid,
            arc_chord_um: c.field_digits(232, 1, 4) as f64,
            break_len_mm: len_setting(382),
            merge_len_mm: len_setting(383),
            rise_time_s: rise_ms / 1000.0,
            sets,
            rapid_accel_mm_s2: rapid_a,
            rapid_jerk_mm_s3: rapid_j,
        }
    }
}

/// Reference block length of the 8.R385 correction, mm (0 = off).
fn ref_len(d: u8) -> f64 {
    match d {
        1 => 1.0,
        2 => 0.5,
        3 => 0.1,
        4 => 0.05,
        _ => 0.0,
    }
}

/// Scale of the parabolic ramp P of constant `r` (8.Rxxx = 2, 3: 1/100, 1/1000).
fn p_scale(c: &Constants, r: u16) -> f64 {
    match c.decade(r, 8) {
        2 => 0.01,
        3 => 0.001,
        _ => 1.0,
    }
}

/// The dynamic sets 1..4 (R406..R429, SPEC §7.4): set 1 completes from the global constants,
/// sets 2..4 from set 1; a disabled set is set 1; set 1 disabled → the global values for all.
fn dynamic_sets(
    c: &Constants,
    global: DynamicSet,
    old_centripetal: &dyn Fn(f64) -> f64,
) -> [DynamicSet; 4] {
    // Reads set k (0-based); `None` for a disabled set.
    let read_set = |k: u16| -> Option<[Option<f64>; 6]> {
        let base = 406 + 6 * k;
        if c.decade(base, 1) != 1 {
            return None;
        }
        // d2..d6 = 1: value is a reference to a program parameter (not resolvable here).
        let direct = |i: u32| c.decade(base, i + 1) == 0;
        let p = nonzero(c.field_digits(base + 1, 1, 7) as f64)
            .filter(|_| direct(1))
            .map(|p| jerk_from_p_mm_s3(p * p_scale(c, base + 1)));
        let a = nonzero(c.field_digits(base + 2, 1, 8) as f64).filter(|_| direct(2));
        let acc = nonzero(c.field_digits(base + 3, 1, 4) as f64).filter(|_| direct(3));
        let drop = nonzero(c.field_digits(base + 3, 5, 6) as f64).filter(|_| direct(3));
        let over = nonzero(c.field_digits(base + 4, 1, 7) as f64).filter(|_| direct(4));
        let cen = if !direct(5) {
            None
        } else if c.decade(base + 5, 8) == 1 {
            nonzero(c.field_digits(base + 5, 1, 7) as f64 / 10.0)
        } else {
            nonzero(c.field_value(base + 5, 1, 7)).map(old_centripetal)
        };
        Some([p, a, acc, drop, over, cen])
    };
    let mut sets = [global; 4];
    if let Some(s1) = read_set(0) {
        let merge = |s: [Option<f64>; 6], base: &DynamicSet, r_over: u16| DynamicSet {
            jerk_mm_s3: s[0].unwrap_or(base.jerk_mm_s3),
            accel_mm_s2: s[1].unwrap_or(base.accel_mm_s2),
            accuracy_um: s[2].unwrap_or(base.accuracy_um),
            drop_percent: s[3].unwrap_or(base.drop_percent),
            overload_mm_s2: s[4].unwrap_or(base.overload_mm_s2),
            overload_ref_len_mm: if s[4].is_some() {
                ref_len(c.decade(r_over, 8))
            } else {
                base.overload_ref_len_mm
            },
            centripetal_mm_s2: s[5].unwrap_or(base.centripetal_mm_s2),
        };
        // Set 1 completes from the global constants; sets 2..4 from set 1 (SPEC §7.4).
        let set1 = merge(s1, &global, 410);
        sets[0] = set1;
        for k in 1..4u16 {
            sets[k as usize] = match read_set(k) {
                Some(s) => merge(s, &set1, 410 + 6 * k),
                None => set1,
            };
        }
    }
    sets
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jerk_reading_matches_both_manual_formulas() {
        // T = 1.478·√(F/P) for a pure-parabola ramp to F: T = 2·√(v/J).
        let (f_mm_min, p) = (6000.0, 50_000.0);
        let j = jerk_from_p_mm_s3(p);
        let t = 2.0 * (f_mm_min / 60.0 / j).sqrt();
        assert!((t - 1.478 * (f_mm_min / p).sqrt()).abs() < 1e-9);
        // Peak acceleration of that ramp equals √(F·P/1966) (the linear-part threshold).
        let a_peak = (f_mm_min / 60.0 * j).sqrt();
        assert!((a_peak / (f_mm_min * p / 1966.0).sqrt() - 1.0).abs() < 1e-3);
    }

    #[test]
    fn sets_fall_back_to_set_one() {
        let mut c = Constants::new();
        c.set(338, 0.020); // 2.R338 = 2
        c.set(406, 0.001); // 1.R406 = 1: sets in use
        c.set(407, 50.000); // P = 50000 (digit reading)
        c.set(408, 0.300); // A = 300 mm/s²
        c.set(409, 200.008); // Lm 8 µm, drop 20 %
        c.set(412, 0.001); // set 2 enabled, only A given
        c.set(414, 0.100);
        let cfg = PlannerConfig::uniform(3, 200.0, 1000.0).with_constants(&c);
        let e = &cfg.envelope;
        assert_eq!(e.profile, Profile::Parabolic);
        assert_eq!(e.sets[0].accel_mm_s2, 300.0);
        assert_eq!(e.sets[0].accuracy_um, 8.0);
        assert_eq!(e.sets[0].drop_percent, 20.0);
        assert_eq!(e.sets[1].accel_mm_s2, 100.0);
        assert_eq!(e.sets[1].jerk_mm_s3, e.sets[0].jerk_mm_s3);
        assert_eq!(e.sets[2], e.sets[0]); // disabled set 3 → set 1
        assert!((e.sets[0].jerk_mm_s3 - jerk_from_p_mm_s3(50_000.0)).abs() < 1e-9);
    }
}
