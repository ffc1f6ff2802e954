//! `[planner]`: machine settings of the look-ahead planner.

use serde::Deserialize;

use super::InvalidConfig;

/// `[planner]`: machine settings of the look-ahead planner (docs/planner.md). The envelope
/// settings (continuity, criteria, dynamic sets) are machine constants, not keys here.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PlannerSection {
    /// Minimum block duration, ms (SPEC §7.2): a block runs no faster than its length over
    /// this time, and the automatic continuity rule (1.R97 = 2) makes a junction a stop when
    /// a block would be shorter. 0 (default) = off: the interpolator crosses several blocks
    /// per tick. 4 = the CNC8x9 behaviour.
    #[serde(default)]
    pub min_block_time_ms: f64,
}

impl PlannerSection {
    /// `planner.min_block_time_ms` within 0..1000 ms.
    pub fn validate(&self) -> Result<(), InvalidConfig> {
        let t = self.min_block_time_ms;
        if !(t.is_finite() && (0.0..=1000.0).contains(&t)) {
            return Err(InvalidConfig::BadValue {
                key: "planner.min_block_time_ms".into(),
                detail: format!("{t} is outside 0..1000 ms"),
            });
        }
        Ok(())
    }
}
