//! `[kr]`: constant cutting speed (KŘR) and the spindle gear ranges.

use serde::Deserialize;

use super::InvalidConfig;

/// How the controlling axis of constant cutting speed (R67) is programmed (SPEC §6,
/// docs/lathe.md). Machine coordinates (setpoints, soft limits, `home_mm`, jog) are always
/// the radius: the true travel of the slide.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum RadiusInputConfig {
    /// Diameter programming (lathes): the axis's program words, its absolute arc centres and
    /// its TAB0.KOR lengths are diameters, halved by the interpreter; the status and the DRO
    /// show it as a diameter. The KŘR radius is the axis position.
    Diameter,
    /// The axis is programmed as a radius, like every other axis (mills; the default).
    #[default]
    Radius,
}

/// `[kr]`: constant cutting speed and the spindle gear ranges.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct KrSection {
    #[serde(default)]
    pub radius_input: RadiusInputConfig,
    /// Gear ranges in order (gear 1 first).
    #[serde(default = "default_gears")]
    pub gears: Vec<GearConfig>,
}

impl Default for KrSection {
    fn default() -> Self {
        KrSection {
            radius_input: RadiusInputConfig::default(),
            gears: default_gears(),
        }
    }
}

/// One spindle gear range.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct GearConfig {
    /// P: spindle speed at full output, rpm.
    pub max_rpm: f64,
    /// U: output value at speed P, 1..32767 (7FFFh).
    #[serde(default = "default_output_range")]
    pub output_range: u16,
    /// M code selecting this range (M41..M44 by convention).
    #[serde(default)]
    pub m_code: Option<u16>,
}

fn default_output_range() -> u16 {
    0x7FFF
}

fn default_gears() -> Vec<GearConfig> {
    vec![GearConfig {
        max_rpm: 6000.0,
        output_range: 0x7FFF,
        m_code: Some(41),
    }]
}

impl KrSection {
    /// `[[kr.gears]]`: positive top speed, output within the DAC range.
    pub fn validate(&self) -> Result<(), InvalidConfig> {
        for (i, g) in self.gears.iter().enumerate() {
            if !(g.max_rpm.is_finite() && g.max_rpm > 0.0) {
                return Err(InvalidConfig::BadValue {
                    key: format!("kr.gears[{i}].max_rpm"),
                    detail: format!("{} must be a positive speed", g.max_rpm),
                });
            }
            if !(1..=0x7FFF).contains(&g.output_range) {
                return Err(InvalidConfig::BadValue {
                    key: format!("kr.gears[{i}].output_range"),
                    detail: format!("{} is outside 1..32767", g.output_range),
                });
            }
        }
        Ok(())
    }
}
