//! The drive-bus seam between the real-time loop and the drives.
//!
//! Once per tick the real-time thread calls [`DriveBus::cycle`]: it hands over one position
//! setpoint per axis and gets back the drives' feedback. Implementations must not allocate or
//! block beyond the bus transfer itself. Backends: the in-process simulated bus (`sim` crate),
//! CANopen CiA 402 over SocketCAN ([`canopen`]) and a serial link ([`serial`]).

use std::fmt;

pub mod candump;
pub mod canopen;
pub mod cia402;
pub mod io;
pub mod serial;
pub mod units;

/// Most axes a bus serves: the kernel's axis count ([`kernel::MAX_AXES`]), defined once there
/// because the setpoints a bus carries are the kernel's [`kernel::AxesMm`].
pub use kernel::MAX_AXES;

/// [`BusFault::axis`] of a fault of the spindle drive: faults name the spindle the way they
/// name an axis (alarm texts say "spindle" where they say "axis X").
pub const SPINDLE_AXIS: u8 = u8::MAX;

/// How alarms name the axis of a fault: the axis letter, "spindle", or `None` for the bus.
pub fn fault_axis_label(axis: Option<u8>, axis_names: &[char]) -> Option<String> {
    match axis {
        Some(SPINDLE_AXIS) => Some("spindle".into()),
        Some(a) => axis_names.get(usize::from(a)).map(char::to_string),
        None => None,
    }
}

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
    /// The bus itself failed (send or receive error on the interface).
    BusError,
    /// The CAN controller went bus-off.
    BusOff,
    /// Too many CAN error frames in a short time.
    ErrorFrames,
    /// The drive refused an SDO request of its configuration: the object and the CiA 301
    /// abort code.
    SdoAbort {
        index: u16,
        subindex: u8,
        abort_code: u32,
    },
    /// The drive did not answer an SDO request of its configuration (one retry included).
    SdoTimeout { index: u16, subindex: u8 },
    /// A process data object arrived with a length that does not match the mapping the
    /// master configured (the drive's PDO mapping differs, or another device uses the COB-ID).
    PdoLength { cob_id: u16, len: u8, expected: u8 },
    /// The drive did not report boot-up after an NMT reset.
    NoBootUp,
    /// The drive did not reach Operation Enabled in time.
    EnableTimeout { statusword: u16 },
    /// The drive switched its power stage off by itself (no fault bit): safe torque off,
    /// quick stop or a local operator.
    DriveDisabled { statusword: u16 },
    /// The drive left the NMT operational state (restarted or stopped by someone else).
    NmtStateChanged { state: u8 },
    /// The serial port is closed or unplugged.
    LinkDown,
    /// Replies arrived but were corrupt (CRC or framing errors).
    CorruptFrames,
    /// The drive's own reference run (CiA 402 homing mode) ended with its homing error bit
    /// (statusword bit 13): switch not found, limit switch hit, or the method is unsupported.
    HomingError { statusword: u16 },
    /// The reference run did not end in time: a CANopen drive's run took longer than
    /// `homing_timeout_ms`, or a serial drive did not acknowledge the reference position.
    HomingTimeout,
    /// The drive refused to take the reference position at the end of a reference run
    /// (serial protocol version 3).
    HomingRefused,
    /// The drive unit answers an older protocol version than the configuration needs
    /// (serial: homing needs version 3).
    ProtocolVersion { drive: u8, needed: u8 },
    /// The emergency-stop chain opened (an input of function `estop` reads open); `input` is
    /// its index in the configuration's `[[io.inputs]]`.
    EmergencyStop { input: u8 },
    /// A hardware limit switch of the axis (`BusFault::axis`) was reached: `positive` side
    /// or negative; `input` as above.
    LimitSwitch { positive: bool, input: u8 },
    /// An alarm input of severity `fault` became active (its message is the configuration's).
    InputAlarm { input: u8 },
}

impl FaultReason {
    /// Stable code of the fault (alarm consumers such as the MTConnect agent's `nativeCode`
    /// match it; the message may improve).
    pub fn code(&self) -> &'static str {
        match self {
            FaultReason::DriveFault { .. } => "drive_fault",
            FaultReason::FollowingError => "following_error",
            FaultReason::Timeout => "feedback_timeout",
            FaultReason::HeartbeatLost => "heartbeat_lost",
            FaultReason::BusError => "bus_error",
            FaultReason::BusOff => "bus_off",
            FaultReason::ErrorFrames => "error_frames",
            FaultReason::SdoAbort { .. } => "sdo_abort",
            FaultReason::SdoTimeout { .. } => "sdo_timeout",
            FaultReason::PdoLength { .. } => "pdo_length",
            FaultReason::NoBootUp => "no_boot_up",
            FaultReason::EnableTimeout { .. } => "enable_timeout",
            FaultReason::DriveDisabled { .. } => "drive_disabled",
            FaultReason::NmtStateChanged { .. } => "nmt_state_changed",
            FaultReason::LinkDown => "link_down",
            FaultReason::CorruptFrames => "corrupt_frames",
            FaultReason::HomingError { .. } => "homing_error",
            FaultReason::HomingTimeout => "homing_timeout",
            FaultReason::HomingRefused => "homing_refused",
            FaultReason::ProtocolVersion { .. } => "protocol_version",
            FaultReason::EmergencyStop { .. } => "emergency_stop",
            FaultReason::LimitSwitch { .. } => "limit_switch",
            FaultReason::InputAlarm { .. } => "input_alarm",
        }
    }

    /// The fault concerns the link to the drives rather than one drive.
    /// The fault is the machine's own input (e-stop chain, limit switch, alarm input), not a
    /// drive's: every axis, the named one too, still follows and brakes on its own.
    pub fn is_input(&self) -> bool {
        matches!(
            self,
            FaultReason::EmergencyStop { .. }
                | FaultReason::LimitSwitch { .. }
                | FaultReason::InputAlarm { .. }
        )
    }

    pub fn is_communication(&self) -> bool {
        matches!(
            self,
            FaultReason::Timeout
                | FaultReason::HeartbeatLost
                | FaultReason::BusError
                | FaultReason::BusOff
                | FaultReason::ErrorFrames
                | FaultReason::LinkDown
                | FaultReason::CorruptFrames
        )
    }
}

impl FaultReason {
    /// The machinist's message of a fault that carries no value (a table, issue #22's
    /// exception); `None` for the faults whose message shows their value.
    fn fixed_text(&self) -> Option<&'static str> {
        Some(match self {
            FaultReason::FollowingError => {
                "following error too large (axis blocked, too fast, or drive too weak)"
            }
            FaultReason::Timeout => {
                "no feedback from the drive in time (drive off, cable, or drive not answering)"
            }
            FaultReason::HeartbeatLost => {
                "drive heartbeat lost (drive switched off, reset, or cable disconnected)"
            }
            FaultReason::BusError => "bus error (interface down or not writable)",
            FaultReason::BusOff => "CAN bus-off (check the wiring, termination and baud rate)",
            FaultReason::ErrorFrames => {
                "too many CAN error frames (check the wiring, termination and baud rate)"
            }
            FaultReason::NoBootUp => {
                "drive did not start after reset (powered? node id set right?)"
            }
            FaultReason::LinkDown => "serial link lost (port closed or unplugged)",
            FaultReason::CorruptFrames => {
                "serial replies corrupt (check the cable, shielding and baud rate)"
            }
            FaultReason::HomingTimeout => {
                "reference run did not end in time (home switch not reached, or the drive did not confirm the reference position; see homing_timeout_ms)"
            }
            FaultReason::HomingRefused => {
                "drive refused the reference position of the reference run (home again)"
            }
            FaultReason::EmergencyStop { .. } => {
                "emergency stop: the e-stop chain is open (release the button, then Reset)"
            }
            _ => return None,
        })
    }
}

impl fmt::Display for FaultReason {
    // The faults with a value: one arm each, the machinist's message.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(text) = self.fixed_text() {
            return f.write_str(text);
        }
        match *self {
            FaultReason::DriveFault { code } => match canopen::emcy::describe(code) {
                Some(text) => write!(f, "drive fault: {text} (code {code:04X}h)"),
                None => write!(f, "drive fault (code {code:04X}h, see the drive manual)"),
            },
            FaultReason::SdoTimeout { index, subindex } => write!(
                f,
                "drive did not answer its configuration (object {index:04X}h:{subindex})"
            ),
            FaultReason::SdoAbort {
                index,
                subindex,
                abort_code,
            } => write!(
                f,
                "drive refused its configuration (object {index:04X}h:{subindex}: {}, abort code {abort_code:08X}h)",
                canopen::sdo::abort_text(abort_code)
            ),
            FaultReason::PdoLength {
                cob_id,
                len,
                expected,
            } => write!(
                f,
                "process data of wrong length (COB-ID {cob_id:03X}h: {len} bytes, the mapping gives {expected}; check the drive's PDO mapping)"
            ),
            FaultReason::EnableTimeout { statusword } => write!(
                f,
                "drive did not switch on (statusword {statusword:04X}h; safe torque off or no power?)"
            ),
            FaultReason::DriveDisabled { statusword } => write!(
                f,
                "drive switched itself off (statusword {statusword:04X}h; safe torque off or quick stop?)"
            ),
            FaultReason::NmtStateChanged { state } => write!(
                f,
                "drive left operation ({}; it was restarted or stopped)",
                canopen::nmt::state_name(state)
            ),
            FaultReason::HomingError { statusword } => write!(
                f,
                "reference run failed in the drive (statusword {statusword:04X}h: home switch not found, limit switch, or homing method not supported)"
            ),
            FaultReason::ProtocolVersion { drive, needed } => fmt_protocol(f, drive, needed),
            FaultReason::LimitSwitch { positive, .. } => write!(
                f,
                "hardware limit switch reached on the {} side (after Reset jog away from it)",
                if positive { "positive" } else { "negative" }
            ),
            FaultReason::InputAlarm { input } => {
                write!(f, "alarm input {input} active (see the machine's I/O list)")
            }
            // Every fault without a value has its fixed text.
            _ => Ok(()),
        }
    }
}

/// The serial drive unit's protocol is older than a feature needs: version 3 for homing, 4
/// for digital I/O on the link.
fn fmt_protocol(f: &mut fmt::Formatter<'_>, drive: u8, needed: u8) -> fmt::Result {
    if needed >= 4 {
        write!(
            f,
            "drive unit speaks serial protocol version {drive}, digital I/O on the link \
             needs version {needed} (update the unit, or wire the I/O elsewhere)"
        )
    } else {
        write!(
            f,
            "drive unit speaks serial protocol version {drive}, homing needs version \
             {needed} (update the unit, or set homing = \"none\")"
        )
    }
}

/// A fault with the axis and node it concerns, where known. `Copy` so the real-time thread can
/// pass it on without allocating.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{reason}{}{}", axis.map(|a| if a == SPINDLE_AXIS { ", spindle".to_string() } else { format!(", axis index {a}") }).unwrap_or_default(), node.map(|n| format!(", node {n}")).unwrap_or_default())]
pub struct BusFault {
    /// Axis index, if the fault concerns one axis; [`SPINDLE_AXIS`] for the spindle drive.
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
    /// Spindle speed setpoint, rpm (signed: negative is M4). It goes to the spindle drive as
    /// a velocity setpoint; buses without a spindle drive ([`DriveBus::has_spindle`]) ignore it.
    pub spindle_rpm: f64,
    /// Digital outputs, bit k for output k of the bus's [`io::IoMap`], written in this cycle.
    pub outputs: io::IoBits,
}

/// What the drives reported in one tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CycleFeedback {
    pub axes: [AxisFeedback; MAX_AXES],
    /// Actual spindle speed, rpm (signed like the setpoint); 0 without a spindle drive.
    pub spindle_rpm: f64,
    /// State of the spindle drive; stays `Disabled` on a bus without one.
    pub spindle_state: DriveState,
    /// Digital inputs as the wire reads them, bit k for input k of the bus's [`io::IoMap`]
    /// (the newest values received; 0 for points the bus does not serve).
    pub inputs: io::IoBits,
}

/// Where a reference run done by the drive itself stands ([`DriveBus::drive_homes`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum HomingState {
    /// No reference run since power-on (or since the last one was reported).
    #[default]
    Idle,
    /// Under way; the drive moves on its own, the setpoints of the axis are not used.
    Running,
    /// Done: the drive's position is referenced and it follows setpoints again, starting
    /// from where it stands (no jump).
    Done,
    /// Stopped before its end ([`DriveBus::stop_homing`], or a fault elsewhere on the bus):
    /// the drive stands and follows setpoints again; the axis is not referenced.
    Aborted,
}

/// A bus that serves a fixed set of axes.
pub trait DriveBus: Send {
    /// Short name for logs and status (`sim`, `can0`, `/dev/ttyUSB0`).
    fn name(&self) -> &str;

    /// Number of axes this bus serves.
    fn axes(&self) -> usize;

    /// Whether a spindle drive takes [`CycleCommand::spindle_rpm`] and reports
    /// [`CycleFeedback::spindle_rpm`]. Without one the spindle setpoint has nowhere to go.
    fn has_spindle(&self) -> bool {
        false
    }

    /// One tick: send the setpoints, fill the feedback of `axes()` axes.
    /// An error means the machine must stop; the caller keeps calling `cycle` (holding the
    /// setpoints) so the bus can report recovery after [`DriveBus::reset`].
    fn cycle(&mut self, cmd: &CycleCommand, feedback: &mut CycleFeedback) -> Result<(), BusFault>;

    /// Asks for every drive to be enabled (state machine up to operational).
    fn enable(&mut self);

    /// Clears faults (CiA 402 fault reset), then enables again.
    fn reset(&mut self);

    /// Ticks from [`DriveBus::enable`] or [`DriveBus::reset`] within which the bus either
    /// reports every drive operational or a fault naming the drive (its own per-drive
    /// timeouts). The caller's enabling window must not be shorter.
    fn enable_timeout_ticks(&self) -> u32 {
        2_500
    }

    /// Orderly switch-off, called once the axes are at rest before the daemon exits: the
    /// drives go to a safe state (CiA 402 drives, on CAN and serial: power stage disabled step
    /// by step; CANopen then: heartbeat watch cleared, NMT pre-operational). The caller keeps calling [`DriveBus::cycle`]
    /// (holding the setpoints) until [`DriveBus::is_shut_down`]; the bus bounds that time.
    fn shutdown(&mut self) {}

    /// Whether the switch-off begun by [`DriveBus::shutdown`] is complete.
    fn is_shut_down(&self) -> bool {
        true
    }

    /// After a fault stop, once the healthy axes are at rest: brings every drive to its safe
    /// state (CiA 402: quick stop, then power stage off), so nothing moves until a reset.
    /// Default: nothing (the bus has no such command; its drives hold their last setpoint).
    fn safe_state(&mut self) {}

    /// Whether this bus can run a reference run (homing) of its axes: either the controller
    /// searches the switch ([`DriveBus::home_switch`] reports it and [`DriveBus::set_home`]
    /// redefines a drive's position), or the drive homes itself ([`DriveBus::drive_homes`]).
    fn supports_homing(&self) -> bool {
        false
    }

    /// The drives run the reference run themselves (CiA 402 homing mode 6): the controller
    /// starts it with [`DriveBus::start_homing`], watches [`DriveBus::homing_state`], and
    /// takes the axis's position from the feedback once it is done.
    fn drive_homes(&self) -> bool {
        false
    }

    /// Starts the drive's reference run of `axis` (the drive must be operational). Its
    /// failures are faults of [`DriveBus::cycle`] naming the axis.
    fn start_homing(&mut self, _axis: usize) {}

    /// Interrupts the drive's reference run of `axis`: the drive stops, and the state ends
    /// as [`HomingState::Aborted`].
    fn stop_homing(&mut self, _axis: usize) {}

    /// The drive's reference run of `axis`.
    fn homing_state(&self, _axis: usize) -> HomingState {
        HomingState::Idle
    }

    /// The home switch of `axis` is pressed (last cycle).
    fn home_switch(&self, _axis: usize) -> bool {
        false
    }

    /// Ends a reference run of `axis`: the drive's position where the switch was found
    /// (`trigger_mm`) becomes `reference_mm`; its reported positions shift by the difference.
    fn set_home(&mut self, _axis: usize, _trigger_mm: f64, _reference_mm: f64) {}
}

/// Runs the orderly switch-off of `bus` to its end: `wait_tick` sleeps until the next tick.
/// Bounded by the bus (every step of its switch-off has a timeout).
pub fn shut_down(
    bus: &mut dyn DriveBus,
    cmd: &CycleCommand,
    feedback: &mut CycleFeedback,
    mut wait_tick: impl FnMut(),
) {
    bus.shutdown();
    while !bus.is_shut_down() {
        wait_tick();
        // Faults no longer matter here: the drives are being switched off.
        let _ = bus.cycle(cmd, feedback);
    }
}
