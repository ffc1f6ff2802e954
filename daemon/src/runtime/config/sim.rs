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
        Ok(())
    }
}
