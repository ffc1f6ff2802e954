//! The digital I/O of a simulated CiA 402 drive: inputs 0x60FD (limit switches, home switch,
//! the manufacturer's bits; set from outside) sent in TPDO2 when mapped, outputs 0x60FE:1
//! taken from RPDO2 when mapped (applied at SYNC, like its RPDO1). A part of
//! [`crate::can_node::CanNode`].

use hal::canopen::cia401::{self, DRIVE_INPUTS_MAPPING, DRIVE_OUTPUTS_MAPPING};
use hal::canopen::sdo::abort;
use hal::canopen::{Frame, cob};

use crate::pdo_objects::PdoObjects;

#[derive(Clone, Debug)]
pub struct DriveIo {
    /// 0x60FD, as the drive's terminals read (a test or `input NODE BIT 0|1` sets it).
    pub inputs: u32,
    /// 0x60FE:1, as last applied.
    pub outputs: u32,
    tpdo2: PdoObjects,
    rpdo2: PdoObjects,
    latched: Option<u32>,
}

impl DriveIo {
    pub fn new(id: u8) -> DriveIo {
        DriveIo {
            inputs: 0,
            outputs: 0,
            tpdo2: PdoObjects::unmapped(cob::TPDO2 + u16::from(id)),
            rpdo2: PdoObjects::unmapped(cob::RPDO2 + u16::from(id)),
            latched: None,
        }
    }

    /// NMT reset: the PDO2 objects return to unmapped (the terminals keep their values).
    pub fn reset_communication(&mut self, id: u8) {
        let keep = (self.inputs, self.outputs);
        *self = DriveIo::new(id);
        (self.inputs, self.outputs) = keep;
    }

    /// RPDO2 received in NMT operational: latched for the next SYNC.
    pub fn on_rpdo2(&mut self, id: u8, payload: &[u8]) {
        if self.rpdo2.active(cob::RPDO2 + u16::from(id), 1) {
            self.latched = cia401::decode_u32(payload);
        }
    }

    /// SYNC in NMT operational: the latched outputs apply; TPDO2 answers if mapped.
    pub fn on_sync(&mut self, id: u8, out: &mut Vec<Frame>) {
        if let Some(v) = self.latched.take() {
            self.outputs = v;
        }
        let cob_id = cob::TPDO2 + u16::from(id);
        if self.tpdo2.active(cob_id, 1) && self.tpdo2.is_sync() {
            out.push(cia401::encode_u32(cob_id, self.inputs));
        }
    }

    /// An SDO write of one of its objects; `None` when the object is not an I/O one.
    pub fn write(&mut self, index: u16, sub: u8, v: u32) -> Option<Result<(), u32>> {
        Some(match (index, sub) {
            (0x1801, _) => self.tpdo2.write_comm(sub, v),
            (0x1401, _) => self.rpdo2.write_comm(sub, v),
            (0x1A01, _) => self.tpdo2.write_map(sub, v, |e| e == DRIVE_INPUTS_MAPPING),
            (0x1601, _) => self.rpdo2.write_map(sub, v, |e| e == DRIVE_OUTPUTS_MAPPING),
            (0x60FE, 1) => {
                self.outputs = v;
                Ok(())
            }
            (0x60FD, 0) => Err(abort::READ_ONLY),
            (0x60FD | 0x60FE, _) => Err(abort::NO_SUBINDEX),
            _ => return None,
        })
    }

    /// An SDO read of one of its objects; `None` when the object is not an I/O one.
    pub fn read(&self, index: u16, sub: u8) -> Option<Result<(u32, u8), u32>> {
        Some(match (index, sub) {
            (0x1801, _) => self.tpdo2.read(true, sub),
            (0x1401, _) => self.rpdo2.read(true, sub),
            (0x1A01, _) => self.tpdo2.read(false, sub),
            (0x1601, _) => self.rpdo2.read(false, sub),
            (0x60FD, 0) => Ok((self.inputs, 4)),
            (0x60FE, 0) => Ok((1, 1)),
            (0x60FE, 1) => Ok((self.outputs, 4)),
            (0x60FD | 0x60FE, _) => Err(abort::NO_SUBINDEX),
            _ => return None,
        })
    }
}
