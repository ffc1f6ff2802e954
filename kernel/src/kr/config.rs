//! KŘR configuration: R67, R329 d3, R580 (SPEC §6) and the gear table (daemon's TOML config).

use super::s_word::SWordMode;
use crate::constants::{AXIS_CODES, Constants};
use crate::plc::OUTPUT_MAX;

/// Version of constant cutting speed, R580 decades 1..2 (SPEC §6).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KrVersion {
    /// `00`: old KŘR: computed in motion blocks only, no PLC control, no G76 limit.
    Old,
    /// `01`: version 2: always computed, PLC control, G76 limit, offsets act at once.
    V2,
}

/// How the controlling axis's position relates to the cutting radius (SPEC §6 **decide**).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RadiusInput {
    /// The axis is programmed and commanded as a diameter (usual on lathes: `X300` = Ø300):
    /// radius = |x| / 2.
    Diameter,
    /// The axis position is the radius: radius = |x|.
    Radius,
}

/// One gear range of the spindle (SPEC §6).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gear {
    /// P: spindle speed at full output of this range, rpm.
    pub max_rpm: f64,
    /// U: output value at speed P, 1..=7FFFh (AKRR_ACT_U).
    pub output_range: u16,
    /// M code selecting this range (e.g. 44), if the machine selects it by program.
    pub m_code: Option<u16>,
}

/// Why a KŘR configuration was refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum KrConfigError {
    #[error(
        "R67 = {0}: the controlling axis of constant cutting speed must be the code of an axis \
         configured in R0..R5 (1 = X, 2 = Y, 3 = Z, 4 = U, 5 = V, 6 = W, 7 = A, 8 = B, 9 = C); \
         R67 may not be 0 even when KŘR is not used"
    )]
    R67(f64),
    #[error("R329 decade 3 = {0}: allowed are 0 standard, 1 swap G96/G97, 2 S in m/min, 3 both")]
    R329Decade3(u8),
    #[error(
        "R580 = {0}: unknown KŘR version; use 0 for the old KŘR or 0.001 (decades 1..2 = 01) \
         for version 2"
    )]
    R580(f64),
    #[error("the spindle gear table is empty: configure at least one gear range")]
    NoGears,
    #[error("gear range {gear}: maximum speed P = {max_rpm} rpm must be above 0")]
    GearMaxRpm { gear: usize, max_rpm: f64 },
    #[error("gear range {gear}: output range U = {output_range} must be 1..32767 (7FFFh)")]
    GearOutputRange { gear: usize, output_range: u16 },
    #[error("gear ranges {first} and {second} are both selected by M{m_code}")]
    GearMCode {
        first: usize,
        second: usize,
        m_code: u16,
    },
    #[error("more than 255 gear ranges configured")]
    TooManyGears,
}

/// What KŘR reads from the machine constants (R67, R329 d3, R580), decoded once per job.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KrConstants {
    /// Controlling axis (R67), 0-based machine axis index.
    pub controlling_axis: usize,
    pub version: KrVersion,
    pub s_word: SWordMode,
}

impl KrConstants {
    /// Decodes R67, R329 decade 3 and R580; refuses values the manual does not define.
    pub fn from_constants(c: &Constants) -> Result<Self, KrConfigError> {
        Ok(KrConstants {
            controlling_axis: controlling_axis(c)?,
            s_word: SWordMode::from_constants(c)?,
            version: version_of(c)?,
        })
    }
}

/// Everything KŘR needs to know about the machine.
#[derive(Clone, Debug, PartialEq)]
pub struct KrConfig {
    /// Controlling axis (R67), 0-based machine axis index.
    pub controlling_axis: usize,
    pub radius_input: RadiusInput,
    pub version: KrVersion,
    pub s_word: SWordMode,
    /// Gear ranges; gear number `g` (1-based, as in [`crate::block::Spindle::gear`]) is
    /// `gears[g - 1]`.
    pub gears: Vec<Gear>,
}

impl KrConfig {
    /// Builds the configuration from the machine constants, how the controlling axis is
    /// programmed, and the gear table.
    pub fn from_constants(
        c: &Constants,
        radius_input: RadiusInput,
        gears: Vec<Gear>,
    ) -> Result<Self, KrConfigError> {
        let k = KrConstants::from_constants(c)?;
        let cfg = KrConfig {
            controlling_axis: k.controlling_axis,
            radius_input,
            version: k.version,
            s_word: k.s_word,
            gears,
        };
        cfg.check_gears()?;
        Ok(cfg)
    }

    /// The part of the configuration that comes from the constants.
    pub fn constants(&self) -> KrConstants {
        KrConstants {
            controlling_axis: self.controlling_axis,
            version: self.version,
            s_word: self.s_word,
        }
    }

    /// Takes the constants' part from `k` (a job's snapshot), keeping the gear table. `Copy`
    /// and allocation-free: the RT thread applies it when a job starts.
    pub fn set_constants(&mut self, k: KrConstants) {
        self.controlling_axis = k.controlling_axis;
        self.version = k.version;
        self.s_word = k.s_word;
    }

    fn check_gears(&self) -> Result<(), KrConfigError> {
        if self.gears.is_empty() {
            return Err(KrConfigError::NoGears);
        }
        if self.gears.len() > 255 {
            return Err(KrConfigError::TooManyGears);
        }
        for (i, g) in self.gears.iter().enumerate() {
            let gear = i + 1;
            if !(g.max_rpm.is_finite() && g.max_rpm > 0.0) {
                return Err(KrConfigError::GearMaxRpm {
                    gear,
                    max_rpm: g.max_rpm,
                });
            }
            if g.output_range == 0 || i32::from(g.output_range) > OUTPUT_MAX {
                return Err(KrConfigError::GearOutputRange {
                    gear,
                    output_range: g.output_range,
                });
            }
            if let Some(m) = g.m_code
                && let Some(j) = self.gears[..i].iter().position(|o| o.m_code == Some(m))
            {
                return Err(KrConfigError::GearMCode {
                    first: j + 1,
                    second: gear,
                    m_code: m,
                });
            }
        }
        Ok(())
    }

    /// Gear range `number` (1-based); 0 (no gear selected yet) means gear 1, the power-on gear.
    pub fn gear(&self, number: u8) -> Option<&Gear> {
        self.gears.get(usize::from(number.max(1)) - 1)
    }

    /// Gear number (1-based) that M code `m` selects, for the program interpreter.
    pub fn gear_for_m(&self, m: u16) -> Option<u8> {
        gear_for_m_code(&self.gears, m)
    }
}

/// Gear number (1-based) that M code `m` selects in `gears`. An empty table (no machine
/// configuration: unit tests, tools) keeps the convention M41..M44 = ranges 1..4.
pub fn gear_for_m_code(gears: &[Gear], m: u16) -> Option<u8> {
    if gears.is_empty() {
        return (41..=44).contains(&m).then(|| (m - 40) as u8);
    }
    gears
        .iter()
        .position(|g| g.m_code == Some(m))
        .map(|i| (i + 1) as u8)
}

/// R67 holds the axis code (as R0..R5 do, [`AXIS_CODES`]: 1 = X ... 9 = C) of the controlling
/// axis; its machine index is where R0..R5 name that axis (SPEC §6).
fn controlling_axis(c: &Constants) -> Result<usize, KrConfigError> {
    let bad = || KrConfigError::R67(c.get(67));
    let letter = controlling_axis_letter(c).ok_or_else(bad)?;
    c.axis_names()
        .iter()
        .position(|&a| a == letter)
        .ok_or_else(bad)
}

/// Letter of the controlling axis R67 names (SPEC §6), `None` when R67 is not an axis code.
/// The interpreter uses it to pick the length offset of that axis for KŘR at the tool tip.
pub fn controlling_axis_letter(c: &Constants) -> Option<char> {
    let m = c.milli(67);
    if m % 1000 != 0 || !(1..=AXIS_CODES.len() as i64).contains(&(m / 1000)) {
        return None;
    }
    Some(AXIS_CODES[(m / 1000 - 1) as usize])
}

/// R580 decades 1..2 (SPEC §6): `00` old, `01` version 2. The manual also says "set the value 1
/// into R580", so `R580 = 1` is accepted for version 2 as well; anything else is refused.
fn version_of(c: &Constants) -> Result<KrVersion, KrConfigError> {
    let v = c.get(580);
    if v == 1.0 {
        return Ok(KrVersion::V2);
    }
    match (
        c.is_negative(580),
        c.field_digits(580, 3, 8),
        c.field_digits(580, 1, 2),
    ) {
        (false, 0, 0) => Ok(KrVersion::Old),
        (false, 0, 1) => Ok(KrVersion::V2),
        _ => Err(KrConfigError::R580(v)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // The configuration read through the public API (with the manual's gear example) is
    // tested in kernel/tests/kr_examples.rs; here only what is private.
    fn consts_r580(r580: f64) -> Constants {
        let mut c = Constants::new();
        c.set(580, r580);
        c
    }

    #[test]
    fn r580_versions() {
        let v = |r580| version_of(&consts_r580(r580));
        assert_eq!(v(0.0), Ok(KrVersion::Old));
        assert_eq!(v(0.001), Ok(KrVersion::V2));
        assert_eq!(v(1.0), Ok(KrVersion::V2));
        assert_eq!(v(0.002), Err(KrConfigError::R580(0.002)));
        assert_eq!(v(10.0), Err(KrConfigError::R580(10.0)));
    }
}
