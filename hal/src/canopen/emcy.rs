//! Emergency messages (COB-ID 0x80 + node): error code, error register, vendor bytes.

use super::{Frame, cob};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Emcy {
    /// CiA 301/402 error code; 0 means "error reset / no error".
    pub code: u16,
    /// Error register 0x1001.
    pub register: u8,
    pub vendor: [u8; 5],
}

impl Emcy {
    /// Decodes an EMCY payload; `None` when it is not 8 bytes.
    pub fn decode(payload: &[u8]) -> Option<Emcy> {
        if payload.len() != 8 {
            return None;
        }
        let mut vendor = [0u8; 5];
        vendor.copy_from_slice(&payload[3..8]);
        Some(Emcy {
            code: u16::from_le_bytes([payload[0], payload[1]]),
            register: payload[2],
            vendor,
        })
    }

    pub fn encode(&self, node: u8) -> Frame {
        let c = self.code.to_le_bytes();
        let v = self.vendor;
        Frame::new(
            cob::EMCY + u16::from(node),
            &[c[0], c[1], self.register, v[0], v[1], v[2], v[3], v[4]],
        )
    }
}

/// CiA 402 code for a following error.
pub const FOLLOWING_ERROR: u16 = 0x8611;

/// Operator text for common CiA 301/402 error codes, by exact code, then by class.
pub fn describe(code: u16) -> Option<&'static str> {
    Some(match code {
        0x2310 => "continuous overcurrent",
        0x2320 => "short circuit at the motor outputs",
        0x3210 => "DC link overvoltage",
        0x3220 => "DC link undervoltage",
        0x4210 => "drive overtemperature",
        0x4310 => "drive overtemperature",
        0x5441 => "safe torque off active",
        0x7305 => "encoder (incremental sensor 1) fault",
        0x8130 => "heartbeat of the controller lost",
        FOLLOWING_ERROR => "following error",
        0x8612 => "reference limit",
        0xFF00..=0xFFFF => "manufacturer-specific error",
        _ => match code >> 12 {
            0x1 => "generic error",
            0x2 => "current error",
            0x3 => "voltage error",
            0x4 => "temperature error",
            0x5 => "drive hardware error",
            0x6 => "drive software error",
            0x7 => "motor or encoder error",
            0x8 => "monitoring error",
            0x9 => "external error",
            _ => return None,
        },
    })
}
