//! CANopen (CiA 301) for CiA 402 drives: frame encodings in small modules, the cyclic
//! [`master::CanOpenMaster`] (a state machine that talks to the bus only through [`CanPort`]),
//! and the SocketCAN port in [`socket`].

pub mod emcy;
pub mod master;
pub mod nmt;
pub mod pdo;
pub mod sdo;
pub mod socket;

pub use master::{
    CanOpenConfig, CanOpenMaster, FaultReaction, HomingParams, NodeConfig, ShutdownMode,
    SpindleNodeConfig,
};
pub use socket::SocketCanPort;

/// Function codes of the predefined connection set (CiA 301): COB-ID = code + node id.
pub mod cob {
    pub const NMT: u16 = 0x000;
    pub const SYNC: u16 = 0x080;
    pub const EMCY: u16 = 0x080;
    pub const TPDO1: u16 = 0x180;
    pub const RPDO1: u16 = 0x200;
    pub const SDO_TX: u16 = 0x580;
    pub const SDO_RX: u16 = 0x600;
    pub const HEARTBEAT: u16 = 0x700;

    /// Splits a COB-ID into function code and node id (node 0 for NMT and SYNC).
    pub fn split(id: u16) -> (u16, u8) {
        if id == NMT || id == SYNC {
            (id, 0)
        } else {
            (id & 0x780, (id & 0x7F) as u8)
        }
    }
}

/// A classic CAN data frame with an 11-bit identifier, independent of the socket library so
/// the protocol code and its tests need no CAN interface.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Frame {
    pub id: u16,
    pub len: u8,
    pub data: [u8; 8],
}

impl Frame {
    /// A frame with `data` (at most 8 bytes; more are cut off).
    pub fn new(id: u16, data: &[u8]) -> Frame {
        let len = data.len().min(8);
        let mut d = [0u8; 8];
        d[..len].copy_from_slice(&data[..len]);
        Frame {
            id: id & 0x7FF,
            len: len as u8,
            data: d,
        }
    }

    pub fn payload(&self) -> &[u8] {
        &self.data[..usize::from(self.len.min(8))]
    }
}

/// What the port delivers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RxEvent {
    Frame(Frame),
    /// A SocketCAN error frame: class bits of the id (`CAN_ERR_*`) and the data bytes.
    Error {
        class: u32,
        data: [u8; 8],
    },
}

/// SocketCAN error-class bits (linux/can/error.h) the master acts on.
pub mod err_class {
    pub const CONTROLLER: u32 = 0x0004;
    pub const PROTOCOL: u32 = 0x0008;
    pub const NO_ACK: u32 = 0x0020;
    pub const BUS_OFF: u32 = 0x0040;
    pub const BUS_ERROR: u32 = 0x0080;
    pub const RESTARTED: u32 = 0x0100;
}

/// Why a port operation failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PortError {
    /// Transmit queue full: the frame was not sent (the bus is jammed or nobody acknowledges).
    WouldBlock,
    /// The interface is down or gone.
    Down,
}

/// A CAN interface seen by the master: non-blocking send and receive. Implementations must
/// not allocate.
pub trait CanPort: Send {
    fn send(&mut self, frame: &Frame) -> Result<(), PortError>;
    /// The next received event, `Ok(None)` when nothing is waiting.
    fn try_recv(&mut self) -> Result<Option<RxEvent>, PortError>;
}
