//! `[sim]`: the simulated drives (bus kind `sim`).

use serde::Deserialize;

use super::InvalidConfig;

/// Parameters of the simulated drives (bus kind `sim`).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SimConfig {
    /// Position-loop gain of the simulated drives, 1/s.
    #[serde(default = "default_kv")]
    pub kv_per_s: f64,
    /// Following-error window, mm.
    #[serde(default = "default_window")]
    pub following_window_mm: f64,
    /// Acceleration of the simulated spindle, rpm/s (0: it reaches its setpoint at once).
    #[serde(default)]
    pub spindle_ramp_rpm_s: f64,
    /// Length of the simulated tool below the carriage's Z, mm (the probe's tip is there).
    #[serde(default)]
    pub tool_length_mm: f64,
    /// The workpiece the probe touches: a box, machine coordinates (docs/setup.md).
    #[serde(default = "default_workpiece_min")]
    pub workpiece_min_mm: [f64; 3],
    #[serde(default = "default_workpiece_max")]
    pub workpiece_max_mm: [f64; 3],
    /// Bores through the workpiece.
    #[serde(default = "default_bores")]
    pub bores: Vec<SimCylinderConfig>,
    /// The simulated tool setter (its top at `top_mm`).
    #[serde(default = "default_setter")]
    pub tool_setter: SimCylinderConfig,
}

/// A vertical cylinder of the simulated machine: a bore, or the tool setter.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SimCylinderConfig {
    pub x_mm: f64,
    pub y_mm: f64,
    pub diameter_mm: f64,
    /// The setter's top face (a bore goes through the workpiece: not used).
    #[serde(default)]
    pub top_mm: f64,
}

/// The simulated workpiece: X 0..100, Y 0..100, its top at Z -10 (issue #47).
fn default_workpiece_min() -> [f64; 3] {
    [0.0, 0.0, -60.0]
}
fn default_workpiece_max() -> [f64; 3] {
    [100.0, 100.0, -10.0]
}
/// One bore of 20 mm at its centre.
fn default_bores() -> Vec<SimCylinderConfig> {
    vec![SimCylinderConfig {
        x_mm: 50.0,
        y_mm: 50.0,
        diameter_mm: 20.0,
        top_mm: 0.0,
    }]
}
/// The tool setter beside the workpiece: 20 mm across at X -40 Y 50, its top at Z -20 (the
/// default `[probe.setter]` of the simulated machine).
pub fn default_setter() -> SimCylinderConfig {
    SimCylinderConfig {
        x_mm: -40.0,
        y_mm: 50.0,
        diameter_mm: 20.0,
        top_mm: -20.0,
    }
}

fn default_kv() -> f64 {
    30.0
}
fn default_window() -> f64 {
    50.0
}

impl Default for SimConfig {
    fn default() -> Self {
        SimConfig {
            kv_per_s: default_kv(),
            following_window_mm: default_window(),
            spindle_ramp_rpm_s: 0.0,
            tool_length_mm: 0.0,
            workpiece_min_mm: default_workpiece_min(),
            workpiece_max_mm: default_workpiece_max(),
            bores: default_bores(),
            tool_setter: default_setter(),
        }
    }
}

impl SimConfig {
    /// Positive loop gain and window, a spindle ramp of 0 or more.
    pub fn validate(&self) -> Result<(), InvalidConfig> {
        for (key, v) in [
            ("sim.kv_per_s", self.kv_per_s),
            ("sim.following_window_mm", self.following_window_mm),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(InvalidConfig::BadValue {
                    key: key.to_string(),
                    detail: format!("{v} must be a positive number"),
                });
            }
        }
        let ramp = self.spindle_ramp_rpm_s;
        if !(ramp.is_finite() && ramp >= 0.0) {
            return Err(InvalidConfig::BadValue {
                key: "sim.spindle_ramp_rpm_s".into(),
                detail: format!("{ramp} must be 0 (at once) or a positive number"),
            });
        }
        self.validate_workpiece()
    }

    fn validate_workpiece(&self) -> Result<(), InvalidConfig> {
        let bad = |key: &str, detail: String| {
            Err(InvalidConfig::BadValue {
                key: format!("sim.{key}"),
                detail,
            })
        };
        if !self.tool_length_mm.is_finite() {
            return bad(
                "tool_length_mm",
                format!("{} must be a number", self.tool_length_mm),
            );
        }
        let (lo, hi) = (self.workpiece_min_mm, self.workpiece_max_mm);
        if (0..3).any(|k| !(lo[k].is_finite() && hi[k].is_finite() && lo[k] < hi[k])) {
            return bad(
                "workpiece_max_mm",
                format!("{hi:?} must be above workpiece_min_mm {lo:?} on every axis"),
            );
        }
        for (key, c) in self
            .bores
            .iter()
            .map(|c| ("bores", c))
            .chain([("tool_setter", &self.tool_setter)])
        {
            let finite = [c.x_mm, c.y_mm, c.top_mm].iter().all(|v| v.is_finite());
            if !(finite && c.diameter_mm.is_finite() && c.diameter_mm > 0.0) {
                return bad(key, format!("{c:?} needs numbers and a positive diameter"));
            }
        }
        Ok(())
    }
}
