//! Digital I/O on the CAN bus: the objects and process data of CiA 401 generic I/O modules
//! (8-bit groups 0x6000 inputs, 0x6200 outputs, error mode 0x6206 and error values 0x6207),
//! and the drives' own digital inputs 0x60FD and outputs 0x60FE:1 (CiA 402), with the SDO
//! writes that map them. Shared by the master and the simulators.

use super::{Frame, cob};

/// Digital inputs, 8-bit groups, sub-index 1.. (CiA 401).
pub const INPUTS: u16 = 0x6000;
/// Digital outputs, 8-bit groups, sub-index 1.. (CiA 401).
pub const OUTPUTS: u16 = 0x6200;
/// Error mode of the outputs, per group: a set bit makes that output take its error value on
/// a device or communication fault (CiA 401).
pub const ERROR_MODE: u16 = 0x6206;
/// Error value of the outputs, per group (CiA 401).
pub const ERROR_VALUE: u16 = 0x6207;
/// A drive's digital inputs (CiA 402; 32 bits).
pub const DRIVE_INPUTS: u16 = 0x60FD;
/// A drive's digital outputs, physical outputs at sub-index 1 (CiA 402; 32 bits).
pub const DRIVE_OUTPUTS: u16 = 0x60FE;
/// The mapping entry of 0x60FD (32 bits).
pub const DRIVE_INPUTS_MAPPING: u32 = 0x60FD_0020;
/// The mapping entry of 0x60FE:1 (32 bits).
pub const DRIVE_OUTPUTS_MAPPING: u32 = 0x60FE_0120;
/// Most 8-bit groups one PDO carries (8 bytes): module bits 0..63.
pub const MAX_GROUPS: u8 = 8;
/// Transmission type "synchronous, every SYNC".
pub const SYNC_EVERY: u32 = 1;
/// Transmission type "event-driven": an RPDO is applied as it arrives.
pub const EVENT_DRIVEN: u32 = 0xFF;

const DISABLED: u32 = 0x8000_0000;

/// One SDO write of a plan: (index, subindex, value, size in bytes).
pub type Write = (u16, u8, u32, u8);

/// The groups needed to carry module bit `highest_bit` (bit b is in group b / 8 + 1).
pub fn groups_for(highest_bit: u8) -> u8 {
    highest_bit / 8 + 1
}

/// The mapping entry of 8-bit group `group` (sub-index, from 1) of `index`.
pub fn group_entry(index: u16, group: u8) -> u32 {
    (u32::from(index) << 16) | (u32::from(group) << 8) | 8
}

/// The group of a mapping entry `entry` of `index`, if it maps one 8-bit group of it.
pub fn entry_group(index: u16, entry: u32) -> Option<u8> {
    let group = ((entry >> 8) & 0xFF) as u8;
    (entry >> 16 == u32::from(index) && entry & 0xFF == 8 && group >= 1).then_some(group)
}

/// A PDO carrying the first `groups` groups of `bits` (group 1 in byte 0).
pub fn encode_groups(cob_id: u16, bits: u64, groups: u8) -> Frame {
    let bytes = bits.to_le_bytes();
    Frame::new(cob_id, &bytes[..usize::from(groups.min(MAX_GROUPS))])
}

/// The bits a PDO of groups carries (byte k is group k + 1).
pub fn decode_groups(payload: &[u8]) -> u64 {
    let mut b = [0u8; 8];
    let n = payload.len().min(8);
    b[..n].copy_from_slice(&payload[..n]);
    u64::from_le_bytes(b)
}

/// The 8-bit group `group` (from 1) of `bits`.
pub fn group_of(bits: u64, group: u8) -> u8 {
    (bits >> (8 * u32::from(group.saturating_sub(1)).min(7))) as u8
}

/// What a module is configured with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ModulePlan {
    pub node: u8,
    /// Groups of 0x6000 in TPDO1 (0: TPDO1 disabled).
    pub input_groups: u8,
    /// Groups of 0x6200 in RPDO1 (0: RPDO1 disabled).
    pub output_groups: u8,
    /// Error values of the outputs (module bit b), 0x6207.
    pub safe_outputs: u64,
}

/// The SDO writes that map a module's PDOs (CiA 301 procedure: disable, clear, map, set
/// count, transmission type, enable) and set the error mode and values of its outputs. TPDO1
/// is synchronous like the drives' (sampled at SYNC, read in the next tick); RPDO1 is
/// event-driven, so the outputs switch in the tick they are sent.
pub fn module_pdo_writes(p: &ModulePlan) -> Vec<Write> {
    let n = u32::from(p.node);
    let mut w = Vec::new();
    let tpdo_cob = u32::from(cob::TPDO1) + n;
    w.push((0x1800, 1, DISABLED | tpdo_cob, 4));
    if p.input_groups > 0 {
        w.push((0x1A00, 0, 0, 1));
        for g in 1..=p.input_groups {
            w.push((0x1A00, g, group_entry(INPUTS, g), 4));
        }
        w.push((0x1A00, 0, u32::from(p.input_groups), 1));
        w.push((0x1800, 2, SYNC_EVERY, 1));
        w.push((0x1800, 1, tpdo_cob, 4));
    }
    let rpdo_cob = u32::from(cob::RPDO1) + n;
    w.push((0x1400, 1, DISABLED | rpdo_cob, 4));
    if p.output_groups > 0 {
        w.push((0x1600, 0, 0, 1));
        for g in 1..=p.output_groups {
            w.push((0x1600, g, group_entry(OUTPUTS, g), 4));
        }
        w.push((0x1600, 0, u32::from(p.output_groups), 1));
        w.push((0x1400, 2, EVENT_DRIVEN, 1));
        w.push((0x1400, 1, rpdo_cob, 4));
    }
    for g in 1..=p.output_groups {
        w.push((ERROR_MODE, g, 0xFF, 1));
        w.push((ERROR_VALUE, g, u32::from(group_of(p.safe_outputs, g)), 1));
    }
    w
}

/// The SDO writes that map a drive's digital inputs 0x60FD into TPDO2 and its outputs
/// 0x60FE:1 into RPDO2 (synchronous, like its PDO1), for the ones it has points of.
pub fn drive_io_writes(node: u8, inputs: bool, outputs: bool) -> Vec<Write> {
    let n = u32::from(node);
    let mut w = Vec::new();
    let pdo = |w: &mut Vec<Write>, comm: u16, map: u16, cob_id: u32, entry: u32| {
        w.extend([
            (comm, 1, DISABLED | cob_id, 4),
            (map, 0, 0, 1),
            (map, 1, entry, 4),
            (map, 0, 1, 1),
            (comm, 2, SYNC_EVERY, 1),
            (comm, 1, cob_id, 4),
        ]);
    };
    if inputs {
        let cob_id = u32::from(cob::TPDO2) + n;
        pdo(&mut w, 0x1801, 0x1A01, cob_id, DRIVE_INPUTS_MAPPING);
    }
    if outputs {
        let cob_id = u32::from(cob::RPDO2) + n;
        pdo(&mut w, 0x1401, 0x1601, cob_id, DRIVE_OUTPUTS_MAPPING);
    }
    w
}

/// A drive's PDO2 (TPDO2 0x60FD, RPDO2 0x60FE:1): one 32-bit value.
pub fn encode_u32(cob_id: u16, value: u32) -> Frame {
    Frame::new(cob_id, &value.to_le_bytes())
}

/// The 32-bit value of a drive's PDO2; `None` for another length.
pub fn decode_u32(payload: &[u8]) -> Option<u32> {
    let p: [u8; 4] = payload.try_into().ok()?;
    Some(u32::from_le_bytes(p))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_and_entries() {
        assert_eq!((groups_for(0), groups_for(7), groups_for(8)), (1, 1, 2));
        assert_eq!(group_entry(INPUTS, 2), 0x6000_0208);
        assert_eq!(entry_group(OUTPUTS, 0x6200_0308), Some(3));
        assert_eq!(entry_group(OUTPUTS, 0x6000_0308), None);
        assert_eq!(entry_group(OUTPUTS, 0x6200_0310), None);
        let f = encode_groups(0x18A, 0x0003_0201, 2);
        assert_eq!(f.payload(), [0x01, 0x02]);
        assert_eq!(decode_groups(&[0x01, 0x82]), 0x8201);
        assert_eq!(group_of(0xAB_CD, 2), 0xAB);
    }

    #[test]
    fn module_plan_maps_the_groups_and_the_error_values() {
        let w = module_pdo_writes(&ModulePlan {
            node: 10,
            input_groups: 2,
            output_groups: 1,
            safe_outputs: 0b0000_0100,
        });
        for e in [
            (0x1A00, 2, 0x6000_0208, 4),
            (0x1A00, 0, 2, 1),
            (0x1800, 1, 0x18A, 4),
            (0x1600, 1, 0x6200_0108, 4),
            (0x1400, 2, 0xFF, 1),
            (0x6206, 1, 0xFF, 1),
            (0x6207, 1, 0b100, 1),
        ] {
            assert!(w.contains(&e), "missing {e:X?}");
        }
        assert!(!w.iter().any(|e| e.0 == 0x1600 && e.1 == 2));
    }
}
