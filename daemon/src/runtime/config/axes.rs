//! `[[axes]]`: the machine axes in machine order (R0..R5): letter, dynamics, bus node, soft
//! limits, reference run.

use serde::Deserialize;

use super::InvalidConfig;

/// One `[[axes]]` entry. Its fields are the table's keys one to one (the file format is the
/// API; see the module doc of `config` for why they are not grouped).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AxisConfig {
    /// Axis letter used in programs (`X`, `Y`, `Z`, `U`...).
    pub name: char,
    /// Maximum axis speed, also the rapid speed, mm/min.
    #[serde(default = "default_v_max")]
    pub max_velocity_mm_min: f64,
    /// Maximum axis acceleration, mm/s².
    #[serde(default = "default_a_max")]
    pub max_accel_mm_s2: f64,
    /// Drive increments per mm (or per degree) for bus backends that talk increments.
    #[serde(default = "default_increments")]
    pub increments_per_mm: f64,
    /// Bus node id of the axis drive (CANopen node id, serial address).
    #[serde(default)]
    pub node_id: Option<u8>,
    /// Position at power-on of the simulated machine, mm.
    #[serde(default)]
    pub home_mm: f64,
    /// Soft limits (travel limits), machine coordinates, mm (degrees on a rotary axis).
    /// Programs, MDI and jogs never command the axis beyond them. Unset: no limit on that
    /// side (the axis is not protected there: docs/operator.md).
    #[serde(default)]
    pub soft_min_mm: Option<f64>,
    #[serde(default)]
    pub soft_max_mm: Option<f64>,
    /// Deceleration of this axis in an emergency stop (a fault of any axis), mm/s². Unset:
    /// `max_accel_mm_s2`. Each axis brakes on its own at this rate, not along the path.
    #[serde(default)]
    pub stop_decel_mm_s2: Option<f64>,
    /// Reference run (homing): `required` (incremental encoders: programs, MDI and continuous
    /// jogs are refused until the axis is homed) or `none` (absolute encoders; the default,
    /// so an existing configuration keeps working).
    #[serde(default)]
    pub homing: HomingMode,
    /// Machine coordinate of the home switch: the axis's position once it is found.
    #[serde(default)]
    pub reference_mm: f64,
    /// Direction of the switch search: -1 or +1.
    #[serde(default = "default_homing_direction")]
    pub homing_direction: i8,
    /// Search speed, mm/min (unset: 10 % of `max_velocity_mm_min`).
    #[serde(default)]
    pub homing_speed_mm_min: Option<f64>,
    /// Order of the reference run (lower first; unset: after the numbered axes, in machine
    /// order). Typically Z first, so the tool leaves the work before X and Y move.
    #[serde(default)]
    pub home_order: Option<u8>,
    /// Simulated machine only: where the home switch of this axis is, in the drive's power-on
    /// coordinates (pressed from there on in `homing_direction`). Unset: 5 mm from the
    /// power-on position in `homing_direction` ([`DEFAULT_SIM_HOME_SWITCH_MM`]), so a reference
    /// run on the simulated machine finds its switch at once, as on a real one.
    #[serde(default)]
    pub sim_home_switch_mm: Option<f64>,
    /// Rotary axis (SPEC §5, docs/lathe.md): encoder pulses per revolution. The axis is then
    /// positioned in degrees (its `_mm` settings are degrees), and F of a block that moves
    /// only rotary axes is in thousands of these pulses per minute. Unset: a linear axis.
    #[serde(default)]
    pub rotary_pulses_per_rev: Option<f64>,
    /// CANopen: homing method of the drive's reference run (0x6098, CiA 402). Unset: 21
    /// (home switch on the negative side) with `homing_direction = -1`, 19 (positive side)
    /// with +1; docs/buses.md#homing.
    #[serde(default)]
    pub can_homing_method: Option<i8>,
    /// CANopen: speed of the second homing phase, leaving the switch for the home position
    /// (0x6099:2), mm/min. Unset: a tenth of the search speed.
    #[serde(default)]
    pub homing_zero_speed_mm_min: Option<f64>,
    /// CANopen: acceleration of the drive's reference run (0x609A), mm/s². Unset:
    /// `max_accel_mm_s2`.
    #[serde(default)]
    pub homing_accel_mm_s2: Option<f64>,
}

/// Reference run of an axis.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum HomingMode {
    /// Absolute encoder, or the machine is referenced otherwise.
    #[default]
    None,
    /// The axis must be homed after power-on before it runs programs.
    Required,
}

/// Where the simulated machine's home switch is when `sim_home_switch_mm` is unset: this far
/// from the power-on position (`home_mm`) in `homing_direction`.
pub const DEFAULT_SIM_HOME_SWITCH_MM: f64 = 5.0;

impl AxisConfig {
    /// The simulated home switch of this axis (see `sim_home_switch_mm`).
    pub fn sim_home_switch_at_mm(&self) -> f64 {
        self.sim_home_switch_mm
            .unwrap_or(self.home_mm + DEFAULT_SIM_HOME_SWITCH_MM * f64::from(self.homing_direction))
    }
}

fn default_homing_direction() -> i8 {
    -1
}

fn default_v_max() -> f64 {
    kernel::plan::DEFAULT_AXIS_LIMITS.v_max_mm_s * 60.0
}
fn default_a_max() -> f64 {
    kernel::plan::DEFAULT_AXIS_LIMITS.a_max_mm_s2
}
fn default_increments() -> f64 {
    10_000.0
}

impl AxisConfig {
    /// Where a step from `here_mm` toward `target_mm` ends: at the soft limit it would pass
    /// (an axis standing beyond one stays where it is on that side).
    pub fn step_within_soft_limits(&self, here_mm: f64, target_mm: f64) -> f64 {
        let mut t = target_mm;
        if let Some(hi) = self.soft_max_mm {
            t = t.min(hi.max(here_mm));
        }
        if let Some(lo) = self.soft_min_mm {
            t = t.max(lo.min(here_mm));
        }
        t
    }

    /// Emergency-stop deceleration, mm/s².
    pub fn stop_decel(&self) -> f64 {
        self.stop_decel_mm_s2.unwrap_or(self.max_accel_mm_s2)
    }

    pub fn new(name: char) -> Self {
        AxisConfig {
            name,
            max_velocity_mm_min: default_v_max(),
            max_accel_mm_s2: default_a_max(),
            increments_per_mm: default_increments(),
            node_id: None,
            home_mm: 0.0,
            soft_min_mm: None,
            soft_max_mm: None,
            stop_decel_mm_s2: None,
            homing: HomingMode::None,
            reference_mm: 0.0,
            homing_direction: -1,
            homing_speed_mm_min: None,
            home_order: None,
            sim_home_switch_mm: None,
            rotary_pulses_per_rev: None,
            can_homing_method: None,
            homing_zero_speed_mm_min: None,
            homing_accel_mm_s2: None,
        }
    }

    /// Search speed of the reference run, mm/s.
    pub fn homing_speed_mm_s(&self) -> f64 {
        self.homing_speed_mm_min
            .unwrap_or(0.1 * self.max_velocity_mm_min)
            / 60.0
    }
}

pub(super) fn default_axes() -> Vec<AxisConfig> {
    ['X', 'Y', 'Z']
        .into_iter()
        .enumerate()
        .map(|(i, n)| AxisConfig {
            node_id: Some(i as u8 + 1),
            ..AxisConfig::new(n)
        })
        .collect()
}

/// `[[axes]]`: count, letters (once each) and positive dynamics.
pub fn validate(axes: &[AxisConfig]) -> Result<(), InvalidConfig> {
    if axes.is_empty() || axes.len() > kernel::MAX_AXES {
        return Err(InvalidConfig::BadValue {
            key: "axes".into(),
            detail: format!(
                "{} axes configured, between 1 and {} are supported",
                axes.len(),
                kernel::MAX_AXES
            ),
        });
    }
    for (i, a) in axes.iter().enumerate() {
        if !a.name.is_ascii_uppercase() {
            return Err(InvalidConfig::BadValue {
                key: format!("axes[{i}].name"),
                detail: format!("'{}' is not an axis letter A..Z", a.name),
            });
        }
        if !kernel::constants::AXIS_CODES.contains(&a.name) {
            return Err(InvalidConfig::BadValue {
                key: format!("axes[{i}].name"),
                detail: format!(
                    "'{}' is not one of the controller's axis letters {}",
                    a.name,
                    kernel::constants::AXIS_CODES.iter().collect::<String>()
                ),
            });
        }
        if axes[..i].iter().any(|b| b.name == a.name) {
            return Err(InvalidConfig::Duplicate {
                key: format!("axes[{i}].name"),
                detail: format!("axis {} appears twice", a.name),
            });
        }
        for (key, v) in [
            ("max_velocity_mm_min", a.max_velocity_mm_min),
            ("max_accel_mm_s2", a.max_accel_mm_s2),
            ("increments_per_mm", a.increments_per_mm),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(InvalidConfig::BadValue {
                    key: format!("axes[{i}].{key}"),
                    detail: format!("{v} must be a positive number"),
                });
            }
        }
        if let Some(p) = a.rotary_pulses_per_rev
            && !(p.is_finite() && p > 0.0)
        {
            return Err(InvalidConfig::BadValue {
                key: format!("axes[{i}].rotary_pulses_per_rev"),
                detail: format!("{p} must be a positive number of pulses"),
            });
        }
    }
    Ok(())
}

/// `[[axes]]`: power-on position, soft limits, reference run and stop deceleration of each
/// axis (checked after `[kr]` and `[storage]`, as before the split: the first mistake found
/// is the one reported).
pub fn validate_positions(axes: &[AxisConfig]) -> Result<(), InvalidConfig> {
    for (i, a) in axes.iter().enumerate() {
        if !a.home_mm.is_finite() {
            return Err(InvalidConfig::BadValue {
                key: format!("axes[{i}].home_mm"),
                detail: format!("{} is not a number", a.home_mm),
            });
        }
        validate_axis_safety(i, a)?;
    }
    Ok(())
}

/// Soft limits and the stop deceleration of axis `i`.
fn validate_axis_safety(i: usize, a: &AxisConfig) -> Result<(), InvalidConfig> {
    for (key, v) in [
        ("soft_min_mm", a.soft_min_mm),
        ("soft_max_mm", a.soft_max_mm),
    ] {
        if let Some(v) = v
            && !v.is_finite()
        {
            return Err(InvalidConfig::BadValue {
                key: format!("axes[{i}].{key}"),
                detail: format!("{v} is not a number"),
            });
        }
    }
    if let (Some(lo), Some(hi)) = (a.soft_min_mm, a.soft_max_mm)
        && lo >= hi
    {
        return Err(InvalidConfig::BadValue {
            key: format!("axes[{i}].soft_max_mm"),
            detail: format!("{hi} must be above soft_min_mm {lo}"),
        });
    }
    if a.homing_direction != 1 && a.homing_direction != -1 {
        return Err(InvalidConfig::BadValue {
            key: format!("axes[{i}].homing_direction"),
            detail: format!("{} must be -1 or 1", a.homing_direction),
        });
    }
    if let Some(v) = a.homing_speed_mm_min
        && !(v.is_finite() && v > 0.0 && v <= a.max_velocity_mm_min)
    {
        return Err(InvalidConfig::BadValue {
            key: format!("axes[{i}].homing_speed_mm_min"),
            detail: format!("{v} must be above 0 and at most max_velocity_mm_min"),
        });
    }
    if let Some(v) = a.homing_zero_speed_mm_min
        && !(v.is_finite() && v > 0.0 && v <= a.max_velocity_mm_min)
    {
        return Err(InvalidConfig::BadValue {
            key: format!("axes[{i}].homing_zero_speed_mm_min"),
            detail: format!("{v} must be above 0 and at most max_velocity_mm_min"),
        });
    }
    if let Some(v) = a.homing_accel_mm_s2
        && !(v.is_finite() && v > 0.0)
    {
        return Err(InvalidConfig::BadValue {
            key: format!("axes[{i}].homing_accel_mm_s2"),
            detail: format!("{v} must be a positive number"),
        });
    }
    if let Some(d) = a.stop_decel_mm_s2
        && !(d.is_finite() && d > 0.0)
    {
        return Err(InvalidConfig::BadValue {
            key: format!("axes[{i}].stop_decel_mm_s2"),
            detail: format!("{d} must be a positive number"),
        });
    }
    Ok(())
}
