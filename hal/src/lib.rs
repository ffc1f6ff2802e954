//! The drive-bus seam between the real-time loop and the drives.
//!
//! Once per tick the real-time thread calls [`DriveBus::cycle`]: it hands over one position
//! setpoint per axis and gets back the drives' feedback. Implementations must not allocate or
//! block beyond the bus transfer itself. Backends: the in-process simulated bus (`sim` crate),
//! CANopen CiA 402 over SocketCAN and a serial link (issue #6).

use std::fmt;

/// Most axes a bus serves.
pub const MAX_AXES: usize = 6;

/// Drive state as the controller sees it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DriveState {
    /// Not yet enabled (power stage off).
    #[default]
    Disabled,
    /// Going through the enable sequence.
    Enabling,
    /// Following setpoints.
    Operational,
    /// Faulted; needs a reset.
    Fault,
}

/// Feedback of one axis after a cycle.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AxisFeedback {
    /// Actual position, mm (degrees for rotary axes).
    pub position_mm: f64,
    pub state: DriveState,
}

/// Why the bus or a drive stopped the machine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FaultReason {
    /// The drive reported a fault (e.g. an EMCY code, CiA 402 statusword fault bit).
    DriveFault { code: u16 },
    /// Following error beyond the window.
    FollowingError,
    /// No feedback arrived in time.
    Timeout,
    /// The drive's heartbeat stopped.
    HeartbeatLost,
    /// The bus itself failed (bus-off, error frames, port gone).
    BusError,
}

impl fmt::Display for FaultReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FaultReason::DriveFault { code } => write!(f, "drive fault (code {code:04X}h)"),
            FaultReason::FollowingError => write!(f, "following error too large"),
            FaultReason::Timeout => write!(f, "no feedback from the drive in time"),
            FaultReason::HeartbeatLost => write!(f, "drive heartbeat lost"),
            FaultReason::BusError => write!(f, "bus error"),
        }
    }
}

/// A fault with the axis and node it concerns, where known. `Copy` so the real-time thread can
/// pass it on without allocating.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{reason} (axis {axis:?}, node {node:?})")]
pub struct BusFault {
    /// Axis index, if the fault concerns one axis.
    pub axis: Option<u8>,
    /// Bus node id (CANopen node, serial address), if known.
    pub node: Option<u8>,
    pub reason: FaultReason,
}

/// What the controller sends in one tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CycleCommand {
    /// Position setpoint per axis, mm (degrees for rotary axes); `[..axes()]` are used.
    pub positions_mm: [f64; MAX_AXES],
    /// Spindle speed setpoint, rpm (signed: negative is M4). Buses without a spindle drive
    /// ignore it.
    pub spindle_rpm: f64,
}

/// What the drives reported in one tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CycleFeedback {
    pub axes: [AxisFeedback; MAX_AXES],
    /// Actual spindle speed, rpm.
    pub spindle_rpm: f64,
}

/// A bus that serves a fixed set of axes.
pub trait DriveBus: Send {
    /// Short name for logs and status (`sim`, `can0`, `/dev/ttyUSB0`).
    fn name(&self) -> &str;

    /// Number of axes this bus serves.
    fn axes(&self) -> usize;

    /// One tick: send the setpoints, fill the feedback of `axes()` axes.
    /// An error means the machine must stop; the caller keeps calling `cycle` (holding the
    /// setpoints) so the bus can report recovery after [`DriveBus::reset`].
    fn cycle(&mut self, cmd: &CycleCommand, feedback: &mut CycleFeedback) -> Result<(), BusFault>;

    /// Asks for every drive to be enabled (state machine up to operational).
    fn enable(&mut self);

    /// Clears faults (CiA 402 fault reset), then enables again.
    fn reset(&mut self);
}
