//! Bus selection: builds the configured [`hal::DriveBus`] backend.

use serde::Deserialize;

use super::config::{AxisConfig, SimConfig};

/// `[bus]` section of the configuration.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum BusConfig {
    /// The built-in simulated machine (default).
    #[default]
    Sim,
}

impl BusConfig {
    /// Checks the bus settings against the axes; the message names the key.
    pub fn validate(&self, _axes: &[AxisConfig]) -> Result<(), String> {
        match self {
            BusConfig::Sim => Ok(()),
        }
    }
}

/// Opens the configured bus for `axes`.
pub fn open_bus(
    bus: &BusConfig,
    axes: &[AxisConfig],
    sim: &SimConfig,
) -> Result<Box<dyn hal::DriveBus>, String> {
    match bus {
        BusConfig::Sim => {
            let params = sim::SimDriveParams {
                kv_per_s: sim.kv_per_s,
                following_window_mm: sim.following_window_mm,
                ..Default::default()
            };
            let start: Vec<f64> = axes.iter().map(|a| a.home_mm).collect();
            Ok(Box::new(sim::SimBus::new(params, &start)))
        }
    }
}
