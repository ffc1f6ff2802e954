//! CANopen (CiA 301) for CiA 402 drives and CiA 401 I/O modules: frame encodings in small modules, the cyclic
//! [`master::CanOpenMaster`] (a state machine that talks to the bus only through [`CanPort`]),
//! and the SocketCAN port in [`socket`].

pub mod cia401;
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

/// A CANopen node id, 1..=127 (CiA 301: 0 addresses every node in NMT and is no node's id).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct NodeId(u8);

impl NodeId {
    /// The master's own id unless configured: the highest, out of the drives' usual range.
    pub const MASTER_DEFAULT: NodeId = NodeId(127);

    /// `id` if it is a node id.
    pub const fn new(id: u8) -> Result<NodeId, CanOpenError> {
        if id >= 1 && id <= 127 {
            Ok(NodeId(id))
        } else {
            Err(CanOpenError::NodeIdRange { id })
        }
    }

    /// The 7-bit value the frames carry.
    pub const fn get(self) -> u8 {
        self.0
    }
}

impl TryFrom<u8> for NodeId {
    type Error = CanOpenError;
    fn try_from(id: u8) -> Result<NodeId, CanOpenError> {
        NodeId::new(id)
    }
}

impl std::fmt::Display for NodeId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.0.fmt(f)
    }
}

/// Why a CANopen master cannot be set up.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CanOpenError {
    #[error("node id {id} is outside 1..127")]
    NodeIdRange { id: u8 },
    #[error("{count} drives configured, 1..={} are supported", crate::MAX_AXES)]
    DriveCount { count: usize },
    #[error("cycle time {cycle_us} µs: 1 to 10 ms in whole ms are supported")]
    CycleTime { cycle_us: u128 },
    #[error("node id {node} of axis {axis} equals the master's")]
    AxisNodeIsMaster { axis: usize, node: NodeId },
    #[error("node id {node} is used twice")]
    NodeUsedTwice { node: NodeId },
    #[error("increments per mm of axis {axis} must be positive")]
    AxisScale { axis: usize },
    #[error("maximum speed of axis {axis} must be positive")]
    AxisSpeed { axis: usize },
    #[error("node id {node} of the spindle equals the master's")]
    SpindleNodeIsMaster { node: NodeId },
    #[error("node id {node} of the spindle is used by an axis")]
    SpindleNodeUsed { node: NodeId },
    #[error("velocity units per rpm of the spindle must be positive")]
    SpindleScale,
    #[error("node id {node} of an I/O module is the master's or a drive's")]
    ModuleNodeUsed { node: u8 },
    #[error("I/O module node {node}: bit {bit} is beyond the 64 bits a PDO carries")]
    ModuleBitRange { node: u8, bit: u8 },
    #[error("I/O point on axis index {axis}: no drive of that axis on this bus")]
    IoDriveMissing { axis: u8 },
    #[error("I/O point on axis index {axis}: bit {bit} is beyond the 32 bits of 0x60FD/0x60FE")]
    IoDriveBitRange { axis: u8, bit: u8 },
    #[error("cannot open CAN interface {iface}: {reason} (does it exist and is it up?)")]
    Open { iface: String, reason: String },
    #[error("cannot configure CAN interface {iface}: {reason}")]
    Configure { iface: String, reason: String },
}

impl CanOpenError {
    /// Stable code (tests and HMIs match it; the message may improve).
    pub fn code(&self) -> &'static str {
        match self {
            CanOpenError::NodeIdRange { .. } => "can_node_id_range",
            CanOpenError::DriveCount { .. } => "can_drive_count",
            CanOpenError::CycleTime { .. } => "can_cycle_time",
            CanOpenError::AxisNodeIsMaster { .. } => "can_axis_node_is_master",
            CanOpenError::NodeUsedTwice { .. } => "can_node_used_twice",
            CanOpenError::AxisScale { .. } => "can_axis_scale",
            CanOpenError::AxisSpeed { .. } => "can_axis_speed",
            CanOpenError::SpindleNodeIsMaster { .. } => "can_spindle_node_is_master",
            CanOpenError::SpindleNodeUsed { .. } => "can_spindle_node_used",
            CanOpenError::SpindleScale => "can_spindle_scale",
            CanOpenError::ModuleNodeUsed { .. } => "can_module_node_used",
            CanOpenError::ModuleBitRange { .. } => "can_module_bit_range",
            CanOpenError::IoDriveMissing { .. } => "can_io_drive_missing",
            CanOpenError::IoDriveBitRange { .. } => "can_io_drive_bit_range",
            CanOpenError::Open { .. } => "can_open",
            CanOpenError::Configure { .. } => "can_configure",
        }
    }
}

/// Function codes of the predefined connection set (CiA 301): COB-ID = code + node id.
pub mod cob {
    pub const NMT: u16 = 0x000;
    pub const SYNC: u16 = 0x080;
    pub const EMCY: u16 = 0x080;
    pub const TPDO1: u16 = 0x180;
    pub const RPDO1: u16 = 0x200;
    pub const TPDO2: u16 = 0x280;
    pub const RPDO2: u16 = 0x300;
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
