//! `[probe]`: how the machine probes (docs/setup.md, "Probing"): the feeds of the two
//! touches, the back-off between them, how far a probing move looks, the ball's radius, and
//! where the tool setter is. The probe itself is an input with `function = "probe"`
//! (docs/io.md).
//!
//! ```toml
//! [probe]
//! search_feed_mm_min = 300
//! latch_feed_mm_min = 50
//! [probe.setter]
//! x_mm = -40
//! y_mm = 50
//! z_mm = -20          # its top, as a tool of length 0 reads it (machine coordinates)
//! clearance_z_mm = 0  # Z rises here before moving over the setter
//! ```

use serde::Deserialize;

use super::InvalidConfig;

/// `[probe]` section.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ProbeSection {
    /// Feed of the first touch, which finds the surface, mm/min.
    #[serde(default = "default_search")]
    pub search_feed_mm_min: f64,
    /// Feed of the second touch, whose position is taken, mm/min: the position is sampled
    /// once per bus period, so it is within this feed × the period (docs/setup.md).
    #[serde(default = "default_latch")]
    pub latch_feed_mm_min: f64,
    /// Back-off after the first touch and after the second, mm.
    #[serde(default = "default_backoff")]
    pub backoff_mm: f64,
    /// How far a workflow's probing move looks for the surface, mm.
    #[serde(default = "default_travel")]
    pub max_travel_mm: f64,
    /// Radius of the probe's ball, mm: an edge is a ball radius beyond where the centre
    /// stopped.
    #[serde(default = "default_ball")]
    pub ball_radius_mm: f64,
    /// The tool setter; unset on a real machine: the tool-setter workflow is refused.
    #[serde(default)]
    pub setter: Option<SetterConfig>,
}

/// `[probe.setter]`: where the tool setter is, machine coordinates.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SetterConfig {
    pub x_mm: f64,
    pub y_mm: f64,
    /// Its top face as a tool of length 0 touches it.
    pub z_mm: f64,
    /// Z rises to this before X and Y move over the setter.
    pub clearance_z_mm: f64,
}

fn default_search() -> f64 {
    300.0
}
fn default_latch() -> f64 {
    50.0
}
fn default_backoff() -> f64 {
    1.0
}
fn default_travel() -> f64 {
    50.0
}
fn default_ball() -> f64 {
    2.0
}

impl Default for ProbeSection {
    fn default() -> Self {
        ProbeSection {
            search_feed_mm_min: default_search(),
            latch_feed_mm_min: default_latch(),
            backoff_mm: default_backoff(),
            max_travel_mm: default_travel(),
            ball_radius_mm: default_ball(),
            setter: None,
        }
    }
}

impl ProbeSection {
    /// Positive feeds, back-off and travel (the back-off shorter than the travel), a ball
    /// radius of 0 or more, finite setter coordinates.
    pub fn validate(&self) -> Result<(), InvalidConfig> {
        let bad = |key: &str, v: f64, what: &str| InvalidConfig::BadValue {
            key: format!("probe.{key}"),
            detail: format!("{v} must be {what}"),
        };
        for (key, v) in [
            ("search_feed_mm_min", self.search_feed_mm_min),
            ("latch_feed_mm_min", self.latch_feed_mm_min),
            ("backoff_mm", self.backoff_mm),
            ("max_travel_mm", self.max_travel_mm),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(bad(key, v, "a positive number"));
            }
        }
        if self.backoff_mm >= self.max_travel_mm {
            return Err(bad(
                "backoff_mm",
                self.backoff_mm,
                "shorter than probe.max_travel_mm",
            ));
        }
        if !(self.ball_radius_mm.is_finite() && self.ball_radius_mm >= 0.0) {
            return Err(bad("ball_radius_mm", self.ball_radius_mm, "0 or more"));
        }
        if let Some(s) = &self.setter {
            for (key, v) in [
                ("setter.x_mm", s.x_mm),
                ("setter.y_mm", s.y_mm),
                ("setter.z_mm", s.z_mm),
                ("setter.clearance_z_mm", s.clearance_z_mm),
            ] {
                if !v.is_finite() {
                    return Err(bad(key, v, "a number"));
                }
            }
        }
        Ok(())
    }
}
