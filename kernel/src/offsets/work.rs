//! Work offsets of the ISO dialect (G54..G59.3): nine coordinate systems, each an offset per
//! axis in mm, added to programmed positions (docs/language.md, "Tools and offsets in both
//! dialects"). The daemon keeps them in a file of its storage dir, the truth like TAB0.KOR;
//! the interpreter works on a copy (a `G10 L2/L20` changes that copy for the rest of the run).

use crate::units::{AxesMm, MAX_AXES};

/// G54, G55, G56, G57, G58, G59, G59.1, G59.2, G59.3.
pub const SYSTEMS: usize = 9;

/// The names of the systems in table order.
pub const SYSTEM_NAMES: [&str; SYSTEMS] = [
    "G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3",
];

/// The nine work offsets and which is selected at program start.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorkOffsets {
    /// Offset per system (index 0 = G54), mm per axis in the machine's axis order.
    pub systems: [AxesMm; SYSTEMS],
    /// The system in force at program start (0 = G54, LinuxCNC's power-on default).
    pub active: usize,
}

impl Default for WorkOffsets {
    fn default() -> Self {
        WorkOffsets {
            systems: [AxesMm::ZERO; SYSTEMS],
            active: 0,
        }
    }
}

impl WorkOffsets {
    /// The system named like `G55` or `G59.1` (case-insensitive).
    pub fn index_of(name: &str) -> Option<usize> {
        SYSTEM_NAMES
            .iter()
            .position(|n| n.eq_ignore_ascii_case(name.trim()))
    }

    /// Offset of system `k` for axis `axis` (0 when out of range).
    pub fn get(&self, k: usize, axis: usize) -> f64 {
        if k < SYSTEMS && axis < MAX_AXES {
            self.systems[k][axis]
        } else {
            0.0
        }
    }
}
