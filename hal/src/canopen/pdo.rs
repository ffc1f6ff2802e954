//! The fixed process-data layout this master configures (one RPDO and one TPDO per drive,
//! synchronous, every SYNC), and the SDO writes that map it. Axis drives run in cyclic
//! synchronous position mode (CSP), a spindle drive in cyclic synchronous velocity mode (CSV);
//! both layouts are a 16-bit control/status word and one 32-bit value, so the frames have the
//! same shape and [`Rpdo`]/[`Tpdo`] serve both.

use super::{Frame, cob};

/// RPDO1 mapping in CSP: controlword 0x6040 (16 bit), target position 0x607A (32 bit).
pub const RPDO1_MAPPING: [u32; 2] = [0x6040_0010, 0x607A_0020];
/// TPDO1 mapping in CSP: statusword 0x6041 (16 bit), position actual value 0x6064 (32 bit).
pub const TPDO1_MAPPING: [u32; 2] = [0x6041_0010, 0x6064_0020];
/// RPDO1 mapping in CSV: controlword 0x6040 (16 bit), target velocity 0x60FF (32 bit).
pub const RPDO1_CSV_MAPPING: [u32; 2] = [0x6040_0010, 0x60FF_0020];
/// TPDO1 mapping in CSV: statusword 0x6041 (16 bit), velocity actual value 0x606C (32 bit).
pub const TPDO1_CSV_MAPPING: [u32; 2] = [0x6041_0010, 0x606C_0020];
/// Payload length of both PDOs.
pub const LEN: usize = 6;

/// CiA 402 modes of operation (0x6060) this master uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OpMode {
    /// Cyclic synchronous position (axes).
    Csp,
    /// Cyclic synchronous velocity (spindle).
    Csv,
}

impl OpMode {
    /// Value of 0x6060.
    pub fn code(self) -> u8 {
        match self {
            OpMode::Csp => 8,
            OpMode::Csv => 9,
        }
    }

    pub fn from_code(code: u32) -> Option<OpMode> {
        match code {
            8 => Some(OpMode::Csp),
            9 => Some(OpMode::Csv),
            _ => None,
        }
    }

    pub fn rpdo_mapping(self) -> [u32; 2] {
        match self {
            OpMode::Csp => RPDO1_MAPPING,
            OpMode::Csv => RPDO1_CSV_MAPPING,
        }
    }

    pub fn tpdo_mapping(self) -> [u32; 2] {
        match self {
            OpMode::Csp => TPDO1_MAPPING,
            OpMode::Csv => TPDO1_CSV_MAPPING,
        }
    }
}

/// Master → drive, once per tick after SYNC.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rpdo {
    pub controlword: u16,
    /// Target position 0x607A in CSP, target velocity 0x60FF in CSV (drive units).
    pub target_increments: i32,
}

impl Rpdo {
    pub fn encode(&self, node: u8) -> Frame {
        let mut d = [0u8; LEN];
        d[..2].copy_from_slice(&self.controlword.to_le_bytes());
        d[2..].copy_from_slice(&self.target_increments.to_le_bytes());
        Frame::new(cob::RPDO1 + u16::from(node), &d)
    }

    pub fn decode(payload: &[u8]) -> Option<Rpdo> {
        let p: &[u8; LEN] = payload.try_into().ok()?;
        Some(Rpdo {
            controlword: u16::from_le_bytes([p[0], p[1]]),
            target_increments: i32::from_le_bytes([p[2], p[3], p[4], p[5]]),
        })
    }
}

/// Drive → master, once per SYNC.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tpdo {
    pub statusword: u16,
    /// Position actual value 0x6064 in CSP, velocity actual value 0x606C in CSV.
    pub position_increments: i32,
}

impl Tpdo {
    pub fn encode(&self, node: u8) -> Frame {
        let mut d = [0u8; LEN];
        d[..2].copy_from_slice(&self.statusword.to_le_bytes());
        d[2..].copy_from_slice(&self.position_increments.to_le_bytes());
        Frame::new(cob::TPDO1 + u16::from(node), &d)
    }

    /// `None` for a payload of the wrong length (a badly mapped or corrupt PDO).
    pub fn decode(payload: &[u8]) -> Option<Tpdo> {
        let p: &[u8; LEN] = payload.try_into().ok()?;
        Some(Tpdo {
            statusword: u16::from_le_bytes([p[0], p[1]]),
            position_increments: i32::from_le_bytes([p[2], p[3], p[4], p[5]]),
        })
    }
}

/// SYNC without counter.
pub fn sync() -> Frame {
    Frame::new(cob::SYNC, &[])
}

/// The SDO writes that set up both PDOs of `node` for `mode`: disable, clear the mapping, map,
/// set transmission type 1 (synchronous, every SYNC), enable (CiA 301 §7.5.2.35 procedure).
/// Each entry is (index, subindex, value, size in bytes).
pub fn mapping_writes(node: u8, mode: OpMode) -> [(u16, u8, u32, u8); 14] {
    let n = u32::from(node);
    const DISABLED: u32 = 0x8000_0000;
    let (rpdo, tpdo) = (mode.rpdo_mapping(), mode.tpdo_mapping());
    [
        (0x1400, 1, DISABLED | (0x200 + n), 4),
        (0x1600, 0, 0, 1),
        (0x1600, 1, rpdo[0], 4),
        (0x1600, 2, rpdo[1], 4),
        (0x1600, 0, 2, 1),
        (0x1400, 2, 1, 1),
        (0x1400, 1, 0x200 + n, 4),
        (0x1800, 1, DISABLED | (0x180 + n), 4),
        (0x1A00, 0, 0, 1),
        (0x1A00, 1, tpdo[0], 4),
        (0x1A00, 2, tpdo[1], 4),
        (0x1A00, 0, 2, 1),
        (0x1800, 2, 1, 1),
        (0x1800, 1, 0x180 + n, 4),
    ]
}
