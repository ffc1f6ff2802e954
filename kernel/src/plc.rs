//! PLC memory area 1: the AKRR_* cells of constant cutting speed, AKRR_CNTR and DYNAM_SET
//! (SPEC §6, §7.4). Issue #7. Every cell is documented in `docs/plc.md`.
//!
//! Two sides use the area:
//! - the **controller** (the RT thread) writes the `ACT_*` cells every tick through
//!   [`PlcArea::set_act`] and reads the PLC inputs *in force* through [`PlcArea::input`];
//! - the **PLC side** (the API) reads every cell by address or name and writes the input cells.
//!   A write is validated first ([`PlcWrite::new`], [`PlcWrite::by_name`]): unknown cells, the
//!   read-only `ACT_*` cells and out-of-range values are refused with a [`PlcError`] and change
//!   nothing. A valid write is *staged* and takes effect when the controller calls
//!   [`PlcArea::begin_tick`] at the start of the next tick (SPEC §6: inputs act on the next tick).
//!
//! The area is a small `Copy` value without heap storage, so the RT thread can own it, publish a
//! copy in its status snapshot, and receive validated [`PlcWrite`]s through its command ring.

mod catalogue;

pub use catalogue::{
    Access, CATALOGUE, CELL_COUNT, CellId, CellInfo, CellUnit, OUTPUT_MAX, PLC_DIST_MAX_EIGHTH_UM,
    PLC_SMAX_MAX_MILLI_RPM, PLC_V_MAX_MM_MIN, by_address, by_name, cntr,
};

/// Why the PLC side's read or write was refused. Nothing was changed.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum PlcError {
    #[error("there is no PLC cell at address {address:X}h in memory area 1")]
    UnknownAddress { address: u32 },
    #[error("there is no PLC cell named \"{name}\" in memory area 1")]
    UnknownName { name: String },
    #[error(
        "{name} ({address:X}h) is written by the controller every tick and cannot be written \
         by the PLC"
    )]
    ReadOnly { name: &'static str, address: u32 },
    #[error("{value} is out of range for {name} ({address:X}h): allowed {min} to {max} {unit}")]
    OutOfRange {
        name: &'static str,
        address: u32,
        value: i64,
        min: i32,
        max: i32,
        unit: &'static str,
    },
}

/// A validated write of the PLC side: an input cell and a value within its range.
/// Build it with [`PlcWrite::new`] or [`PlcWrite::by_name`]; apply it with [`PlcArea::stage`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlcWrite {
    cell: CellId,
    value: i32,
}

impl PlcWrite {
    /// Validates a write of `value` to the cell at byte `address`.
    pub fn new(address: u32, value: i64) -> Result<PlcWrite, PlcError> {
        let info = by_address(address).ok_or(PlcError::UnknownAddress { address })?;
        Self::check(info, value)
    }

    /// Validates a write of `value` to the cell called `name` (case-insensitive).
    pub fn by_name(name: &str, value: i64) -> Result<PlcWrite, PlcError> {
        let info = by_name(name).ok_or_else(|| PlcError::UnknownName {
            name: name.to_string(),
        })?;
        Self::check(info, value)
    }

    fn check(info: &'static CellInfo, value: i64) -> Result<PlcWrite, PlcError> {
        if info.access == Access::ReadOnly {
            return Err(PlcError::ReadOnly {
                name: info.name,
                address: info.address,
            });
        }
        if value < i64::from(info.min) || value > i64::from(info.max) {
            return Err(PlcError::OutOfRange {
                name: info.name,
                address: info.address,
                value,
                min: info.min,
                max: info.max,
                unit: info.unit.symbol(),
            });
        }
        Ok(PlcWrite {
            cell: info.id,
            // In range of an i32 field, checked above.
            value: value as i32,
        })
    }

    pub fn cell(&self) -> CellId {
        self.cell
    }

    pub fn value(&self) -> i32 {
        self.value
    }
}

/// Memory area 1: the value of every cell in force, and the PLC writes staged for the next tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlcArea {
    /// Values in force, indexed by [`CellId::index`].
    cells: [i32; CELL_COUNT],
    /// Values written by the PLC side since the last [`PlcArea::begin_tick`].
    staged: [i32; CELL_COUNT],
    /// Bit `i` set: `staged[i]` holds a write not yet in force.
    staged_mask: u32,
}

impl Default for PlcArea {
    fn default() -> Self {
        Self::new()
    }
}

impl PlcArea {
    /// All cells zero (power-on): KŘR controlled by the program, dynamic set 1.
    pub const fn new() -> Self {
        PlcArea {
            cells: [0; CELL_COUNT],
            staged: [0; CELL_COUNT],
            staged_mask: 0,
        }
    }

    // ---- PLC side (API) -------------------------------------------------------------------

    /// Stages a validated write; it takes effect at the next [`PlcArea::begin_tick`]. A later
    /// write to the same cell before that tick replaces the earlier one.
    pub fn stage(&mut self, write: PlcWrite) {
        let i = write.cell.index();
        self.staged[i] = write.value;
        self.staged_mask |= 1 << i;
    }

    /// Validates and stages a write by address; on error nothing changes.
    pub fn write(&mut self, address: u32, value: i64) -> Result<(), PlcError> {
        self.stage(PlcWrite::new(address, value)?);
        Ok(())
    }

    /// Validates and stages a write by name; on error nothing changes.
    pub fn write_by_name(&mut self, name: &str, value: i64) -> Result<(), PlcError> {
        self.stage(PlcWrite::by_name(name, value)?);
        Ok(())
    }

    /// Value of the cell at byte `address`: for input cells the last value the PLC wrote (even
    /// if it takes effect only at the next tick), for `ACT_*` cells the controller's last value.
    pub fn read(&self, address: u32) -> Result<i32, PlcError> {
        let info = by_address(address).ok_or(PlcError::UnknownAddress { address })?;
        Ok(self.latest(info.id))
    }

    /// Value of the cell called `name`; see [`PlcArea::read`].
    pub fn read_by_name(&self, name: &str) -> Result<i32, PlcError> {
        let info = by_name(name).ok_or_else(|| PlcError::UnknownName {
            name: name.to_string(),
        })?;
        Ok(self.latest(info.id))
    }

    /// Last value written to a cell by its writer (staged or in force).
    pub fn latest(&self, cell: CellId) -> i32 {
        let i = cell.index();
        if self.staged_mask & (1 << i) != 0 {
            self.staged[i]
        } else {
            self.cells[i]
        }
    }

    /// Every cell with its catalogue entry and latest value, in address order.
    pub fn list(&self) -> impl Iterator<Item = (&'static CellInfo, i32)> + '_ {
        CATALOGUE.iter().map(|c| (c, self.latest(c.id)))
    }

    // ---- controller side (RT thread) ------------------------------------------------------

    /// Start of a tick: the PLC writes staged since the last tick take effect now.
    pub fn begin_tick(&mut self) {
        let mut mask = self.staged_mask;
        while mask != 0 {
            let i = mask.trailing_zeros() as usize;
            self.cells[i] = self.staged[i];
            mask &= mask - 1;
        }
        self.staged_mask = 0;
    }

    /// Value in force of a cell (what the controller computes with in this tick).
    pub fn input(&self, cell: CellId) -> i32 {
        self.cells[cell.index()]
    }

    /// AKRR_CNTR bits in force.
    pub fn cntr(&self) -> u32 {
        self.input(CellId::AkrrCntr) as u32 & cntr::ALL
    }

    /// Dynamic parameter set in force, 1..=4 (DYNAM_SET 0..3, SPEC §7.4).
    pub fn dynam_set(&self) -> u8 {
        self.input(CellId::DynamSet).clamp(0, 3) as u8 + 1
    }

    /// Controller writes an `ACT_*` cell. Values outside the cell's range are saturated to it
    /// (the controller computes within range; this keeps the area valid if it ever did not).
    /// Writes to input cells are ignored: those belong to the PLC side.
    pub fn set_act(&mut self, cell: CellId, value: i32) {
        let info = cell.info();
        if info.access == Access::ReadOnly {
            self.cells[cell.index()] = value.clamp(info.min, info.max);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn staged_write_takes_effect_at_next_tick() {
        let mut a = PlcArea::new();
        a.write(0xA19C, 90_000).unwrap();
        assert_eq!(a.input(CellId::AkrrV), 0);
        assert_eq!(a.read(0xA19C), Ok(90_000));
        a.begin_tick();
        assert_eq!(a.input(CellId::AkrrV), 90_000);
    }

    #[test]
    fn dynam_set_maps_to_set_number() {
        let mut a = PlcArea::new();
        assert_eq!(a.dynam_set(), 1);
        a.write_by_name("DYNAM_SET", 3).unwrap();
        a.begin_tick();
        assert_eq!(a.dynam_set(), 4);
    }

    #[test]
    fn set_act_saturates_and_ignores_inputs() {
        let mut a = PlcArea::new();
        a.set_act(CellId::AkrrActOut, 0x9000);
        assert_eq!(a.input(CellId::AkrrActOut), OUTPUT_MAX);
        a.set_act(CellId::AkrrV, 5);
        assert_eq!(a.input(CellId::AkrrV), 0);
    }
}
