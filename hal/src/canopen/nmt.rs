//! NMT commands (COB-ID 0) and the NMT states that heartbeats report (COB-ID 0x700 + node).

use super::{Frame, cob};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Command {
    Start = 0x01,
    Stop = 0x02,
    EnterPreOperational = 0x80,
    ResetNode = 0x81,
    ResetCommunication = 0x82,
}

impl Command {
    pub fn from_byte(b: u8) -> Option<Command> {
        Some(match b {
            0x01 => Command::Start,
            0x02 => Command::Stop,
            0x80 => Command::EnterPreOperational,
            0x81 => Command::ResetNode,
            0x82 => Command::ResetCommunication,
            _ => return None,
        })
    }
}

/// NMT states as a heartbeat carries them.
pub mod state {
    pub const BOOT_UP: u8 = 0x00;
    pub const STOPPED: u8 = 0x04;
    pub const OPERATIONAL: u8 = 0x05;
    pub const PRE_OPERATIONAL: u8 = 0x7F;
}

/// A command for `node` (0 = all nodes).
pub fn command(cmd: Command, node: u8) -> Frame {
    Frame::new(cob::NMT, &[cmd as u8, node])
}

pub fn heartbeat(node: u8, state: u8) -> Frame {
    Frame::new(cob::HEARTBEAT + u16::from(node), &[state])
}

/// Operator-readable name of a heartbeat state.
pub fn state_name(s: u8) -> &'static str {
    match s & 0x7F {
        state::BOOT_UP => "boot-up",
        state::STOPPED => "stopped",
        state::OPERATIONAL => "operational",
        state::PRE_OPERATIONAL => "pre-operational",
        _ => "unknown state",
    }
}
