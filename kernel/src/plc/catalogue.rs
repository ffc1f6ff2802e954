//! The cell catalogue of PLC memory area 1: every cell's name, address, unit, access, range and
//! meaning (SPEC §6 table; AKRR_CNTR and DYNAM_SET addresses are our choice, see `docs/plc.md`).

/// Who may write a cell.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Access {
    /// Written by the controller every tick (the `ACT_*` cells); the PLC side only reads it.
    ReadOnly,
    /// Written by the PLC side (the API); takes effect on the next tick.
    ReadWrite,
}

/// Unit of a cell's raw double-word value.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CellUnit {
    /// Millimetres per minute.
    MmPerMin,
    /// Thousandths of a revolution per minute (1/1000 rpm).
    MilliRpm,
    /// Eighths of a micrometre (1/8 µm; 8000 per mm).
    EighthMicron,
    /// Raw spindle output value, 0..7FFFh of the full output range.
    OutputValue,
    /// Bit field (AKRR_CNTR).
    Bits,
    /// Plain index (DYNAM_SET).
    Index,
}

impl CellUnit {
    /// Unit as a machinist reads it.
    pub fn symbol(self) -> &'static str {
        match self {
            CellUnit::MmPerMin => "mm/min",
            CellUnit::MilliRpm => "1/1000 rpm",
            CellUnit::EighthMicron => "1/8 µm",
            CellUnit::OutputValue => "0..7FFFh",
            CellUnit::Bits => "bits",
            CellUnit::Index => "index",
        }
    }
}

/// Identifies one cell; the discriminant is the cell's index in [`CATALOGUE`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum CellId {
    AkrrActV = 0,
    AkrrActSmax,
    AkrrActDist,
    AkrrActVcorr,
    AkrrActR,
    AkrrActP,
    AkrrActU,
    AkrrActS,
    AkrrActOut,
    AkrrV,
    AkrrSmax,
    AkrrDist,
    AkrrVcorr,
    AkrrCntr,
    DynamSet,
    IoInLo,
    IoInHi,
    IoOutLo,
    IoOutHi,
}

/// Number of cells in the area.
pub const CELL_COUNT: usize = 19;

impl CellId {
    /// Index of the cell in [`CATALOGUE`] and in the area's storage.
    pub const fn index(self) -> usize {
        self as usize
    }

    /// Catalogue entry of this cell.
    pub fn info(self) -> &'static CellInfo {
        &CATALOGUE[self.index()]
    }
}

/// Largest spindle output value (SPEC §6: 0..7FFFh).
pub const OUTPUT_MAX: i32 = 0x7FFF;

/// Largest cutting speed the PLC may set: what `S99999` in 0.1 m/min means (9999.9 m/min).
pub const PLC_V_MAX_MM_MIN: i32 = 9_999_900;

/// Largest speed limit the PLC may set: 99999 rpm, the largest `S` word.
pub const PLC_SMAX_MAX_MILLI_RPM: i32 = 99_999_000;

/// Largest radius correction the PLC may set: ±1000 mm in 1/8 µm.
pub const PLC_DIST_MAX_EIGHTH_UM: i32 = 8_000_000;

/// Bits of AKRR_CNTR (SPEC §6). Bits 6..31 must be zero.
pub mod cntr {
    /// Bit 0: cutting speed from AKRR_V (else from G96/G97 + S).
    pub const EXT_AKRR_V: u32 = 1 << 0;
    /// Bit 1: speed limit from AKRR_SMAX (else from G76).
    pub const EXT_AKRR_SMAX: u32 = 1 << 1;
    /// Bit 2: radius correction AKRR_DIST in use.
    pub const EXT_AKRR_DIST: u32 = 1 << 2;
    /// Bit 3: cutting speed correction AKRR_VCORR in use.
    pub const EXT_AKRR_VCORR: u32 = 1 << 3;
    /// Bit 4: the PLC activates KŘR (else G96/G97 do).
    pub const EXT_AKRR_REQ: u32 = 1 << 4;
    /// Bit 5: compute at the carriage, without offsets and origin shifts.
    pub const EXT_AKRR_SUPORT: u32 = 1 << 5;
    /// All defined bits.
    pub const ALL: u32 = 0x3F;
}

/// One catalogue entry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CellInfo {
    pub id: CellId,
    pub name: &'static str,
    /// Byte address in memory area 1 (double words, 4 bytes apart).
    pub address: u32,
    pub unit: CellUnit,
    pub access: Access,
    /// Smallest value the cell may hold.
    pub min: i32,
    /// Largest value the cell may hold.
    pub max: i32,
    pub description: &'static str,
}

const fn cell(
    id: CellId,
    name: &'static str,
    address: u32,
    unit: CellUnit,
    access: Access,
    (min, max): (i32, i32),
    description: &'static str,
) -> CellInfo {
    CellInfo {
        id,
        name,
        address,
        unit,
        access,
        min,
        max,
        description,
    }
}

use Access::{ReadOnly, ReadWrite};
use CellUnit::*;

/// Every cell of memory area 1, in address order (SPEC §6 table; A1ACh..A1C0h are ours).
pub const CATALOGUE: [CellInfo; CELL_COUNT] = [
    cell(
        CellId::AkrrActV,
        "AKRR_ACT_V",
        0xA178,
        MmPerMin,
        ReadOnly,
        (0, i32::MAX),
        "actual cutting speed (from G96/G97 or the PLC), before AKRR_VCORR; 0 when KŘR is off",
    ),
    cell(
        CellId::AkrrActSmax,
        "AKRR_ACT_SMAX",
        0xA17C,
        MilliRpm,
        ReadOnly,
        (0, i32::MAX),
        "actual spindle speed limit (G76 or the PLC); 0 = none",
    ),
    cell(
        CellId::AkrrActDist,
        "AKRR_ACT_DIST",
        0xA180,
        EighthMicron,
        ReadOnly,
        (i32::MIN, i32::MAX),
        "actual radius correction (PLC only); 0 unless EXT_AKRR_DIST",
    ),
    cell(
        CellId::AkrrActVcorr,
        "AKRR_ACT_VCORR",
        0xA184,
        MmPerMin,
        ReadOnly,
        (i32::MIN, i32::MAX),
        "actual cutting speed correction (PLC only); 0 unless EXT_AKRR_VCORR",
    ),
    cell(
        CellId::AkrrActR,
        "AKRR_ACT_R",
        0xA188,
        EighthMicron,
        ReadOnly,
        (0, i32::MAX),
        "actual radius the speed is computed for (after AKRR_DIST)",
    ),
    cell(
        CellId::AkrrActP,
        "AKRR_ACT_P",
        0xA18C,
        MilliRpm,
        ReadOnly,
        (0, i32::MAX),
        "maximum speed P of the gear range in use",
    ),
    cell(
        CellId::AkrrActU,
        "AKRR_ACT_U",
        0xA190,
        OutputValue,
        ReadOnly,
        (0, OUTPUT_MAX),
        "output range U of the gear range in use",
    ),
    cell(
        CellId::AkrrActS,
        "AKRR_ACT_S",
        0xA194,
        MilliRpm,
        ReadOnly,
        (0, i32::MAX),
        "actual computed spindle speed (KŘR or S), independent of M3/M4/M5",
    ),
    cell(
        CellId::AkrrActOut,
        "AKRR_ACT_OUT",
        0xA198,
        OutputValue,
        ReadOnly,
        (0, OUTPUT_MAX),
        "actual computed spindle output Ux = n/P·U",
    ),
    cell(
        CellId::AkrrV,
        "AKRR_V",
        0xA19C,
        MmPerMin,
        ReadWrite,
        (0, PLC_V_MAX_MM_MIN),
        "cutting speed set by the PLC (used when EXT_AKRR_V)",
    ),
    cell(
        CellId::AkrrSmax,
        "AKRR_SMAX",
        0xA1A0,
        MilliRpm,
        ReadWrite,
        (0, PLC_SMAX_MAX_MILLI_RPM),
        "spindle speed limit set by the PLC (used when EXT_AKRR_SMAX; 0 = none)",
    ),
    cell(
        CellId::AkrrDist,
        "AKRR_DIST",
        0xA1A4,
        EighthMicron,
        ReadWrite,
        (-PLC_DIST_MAX_EIGHTH_UM, PLC_DIST_MAX_EIGHTH_UM),
        "radius correction set by the PLC, added to the radius (used when EXT_AKRR_DIST)",
    ),
    cell(
        CellId::AkrrVcorr,
        "AKRR_VCORR",
        0xA1A8,
        MmPerMin,
        ReadWrite,
        (-PLC_V_MAX_MM_MIN, PLC_V_MAX_MM_MIN),
        "cutting speed correction set by the PLC, added to the cutting speed (used when \
         EXT_AKRR_VCORR)",
    ),
    cell(
        CellId::AkrrCntr,
        "AKRR_CNTR",
        0xA1AC,
        Bits,
        ReadWrite,
        (0, cntr::ALL as i32),
        "KŘR control bits: 0 EXT_AKRR_V, 1 EXT_AKRR_SMAX, 2 EXT_AKRR_DIST, 3 EXT_AKRR_VCORR, \
         4 EXT_AKRR_REQ, 5 EXT_AKRR_SUPORT",
    ),
    cell(
        CellId::DynamSet,
        "DYNAM_SET",
        0xA1B0,
        Index,
        ReadWrite,
        (0, 3),
        "dynamic parameter set selected by the PLC: 0..3 = set 1..4 (SPEC §7.4)",
    ),
    cell(
        CellId::IoInLo,
        "IO_IN_LO",
        0xA1B4,
        Bits,
        ReadOnly,
        (i32::MIN, i32::MAX),
        "the machine's inputs 0..31 in their function's sense, bit k = input k (docs/io.md)",
    ),
    cell(
        CellId::IoInHi,
        "IO_IN_HI",
        0xA1B8,
        Bits,
        ReadOnly,
        (i32::MIN, i32::MAX),
        "the machine's inputs 32..63, bit k = input 32 + k (docs/io.md)",
    ),
    cell(
        CellId::IoOutLo,
        "IO_OUT_LO",
        0xA1BC,
        Bits,
        ReadOnly,
        (i32::MIN, i32::MAX),
        "the machine's outputs 0..31 as sent this tick, bit k = output k (docs/io.md)",
    ),
    cell(
        CellId::IoOutHi,
        "IO_OUT_HI",
        0xA1C0,
        Bits,
        ReadOnly,
        (i32::MIN, i32::MAX),
        "the machine's outputs 32..63 (docs/io.md)",
    ),
];

/// Catalogue entry at a byte address.
pub fn by_address(address: u32) -> Option<&'static CellInfo> {
    CATALOGUE.iter().find(|c| c.address == address)
}

/// Catalogue entry by name (case-insensitive, as a machinist may type it).
pub fn by_name(name: &str) -> Option<&'static CellInfo> {
    CATALOGUE
        .iter()
        .find(|c| c.name.eq_ignore_ascii_case(name.trim()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_match_their_catalogue_rows_and_addresses_are_dwords() {
        for (i, c) in CATALOGUE.iter().enumerate() {
            assert_eq!(c.id.index(), i, "{}", c.name);
            assert_eq!(c.address % 4, 0, "{}", c.name);
            assert!(c.min <= c.max, "{}", c.name);
        }
        // Address order, 4 bytes apart, no holes: A178h..A1C0h.
        for w in CATALOGUE.windows(2) {
            assert_eq!(w[1].address, w[0].address + 4);
        }
    }

    #[test]
    fn lookups() {
        assert_eq!(by_address(0xA194).unwrap().name, "AKRR_ACT_S");
        assert_eq!(by_name("akrr_cntr").unwrap().address, 0xA1AC);
        assert!(by_address(0xA179).is_none());
        assert!(by_name("AKRR_NOPE").is_none());
    }
}
