//! The master's side of one CiA 402 drive, the same for every bus (CANopen, serial): its
//! power phase ([`DrivePhase`]), the controlword it is sent, and a target that never jumps.
//! Sans-IO: the bus stores what the drive reported ([`Drive::on_status`]) when a TPDO or a
//! reply arrives, calls [`Drive::tick`] once per tick, and sends [`Drive::controlword`] and
//! [`Drive::target_increments`]. What a bus does around it (NMT and SDO on CAN, the link on
//! serial, a drive's own reference run) stays with the bus.
//!
//! One tick, by phase:
//! - `Enabling`: a fresh statusword showing Operation Enabled enables the drive, even in the
//!   tick the timeout passes (the drive made it). Otherwise, once `enable_timeout_ticks` have
//!   passed the drive faults with [`FaultReason::EnableTimeout`], whether or not a statusword
//!   arrived (a drive that stops answering is also caught by the bus's own watch). A fresh
//!   statusword short of enabled sets the next controlword toward it; a stale one is never
//!   acted on (after a reset the last one known may be old). The target holds.
//! - `Enabled`: the statusword watch ([`super::operating_fault`]) and the master's
//!   following-error check, then the target. A position drive holds its own position until the
//!   commanded position comes within one tick's travel at the axis's highest speed (the
//!   controller takes its commanded position from the drives once all are enabled): from then
//!   on it follows. A velocity drive follows at once.
//! - `Stopped`: the fault reaction's controlword stays; the target holds.
//! - `PoweringDown`: the orderly switch-off, one step per fresh statusword (07h → 06h → 00h,
//!   or 02h → 00h), ending `Off` when the drive reports it is off or after the enable timeout.
//! - `Off`, `Faulted`: disable voltage (00h); the target holds.

use super::{
    EnableStep, PowerState, controlword_toward_disabled, controlword_toward_disabled_by_quick_stop,
    cw, enable_step, operating_fault,
};
use crate::FaultReason;

/// Where the master has a drive's power stage.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DrivePhase {
    /// Not asked to enable, or switched off: controlword 00h.
    Off,
    /// The enable sequence, begun at tick `since`.
    Enabling { since: u64 },
    /// Operation Enabled: the drive follows the setpoints (once taken over).
    Enabled,
    /// Brought to the safe state after a fault stop ([`FaultReaction`]); a reset enables it
    /// again.
    Stopped,
    /// The orderly switch-off, begun at tick `since`.
    PoweringDown { since: u64 },
    /// Stopped by a fault of this drive: power stage off until a reset.
    Faulted(FaultReason),
}

/// What the drive's setpoint is, which decides how it holds still.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Setpoint {
    /// Cyclic synchronous position: holding still is the actual position.
    Position,
    /// Cyclic synchronous velocity (a spindle): holding still is speed 0.
    Velocity,
}

/// How the orderly shutdown switches an enabled drive off.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ShutdownMode {
    /// Disable operation (07h), shutdown (06h), disable voltage (00h).
    #[default]
    Disable,
    /// Quick stop (02h), then disable voltage (00h): the drive stops by its quick stop
    /// option (0x605A) first.
    QuickStop,
}

/// What the drives do after a fault stop, once the healthy axes are at rest
/// ([`crate::DriveBus::safe_state`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FaultReaction {
    /// Quick stop (controlword 02h): the drives end in Quick Stop Active (or Switch On
    /// Disabled, by their quick stop option 0x605A).
    #[default]
    QuickStop,
    /// Disable voltage (00h): power stage off at once, Switch On Disabled (an axis with a
    /// holding brake needs it; a vertical axis without one may sag).
    DisableVoltage,
    /// The drives stay enabled and hold their last setpoint.
    Hold,
}

impl FaultReaction {
    /// The safe state's controlword, or `None` to stay enabled.
    pub fn controlword(self) -> Option<u16> {
        match self {
            FaultReaction::QuickStop => Some(cw::QUICK_STOP_CMD),
            FaultReaction::DisableVoltage => Some(cw::DISABLE_VOLTAGE),
            FaultReaction::Hold => None,
        }
    }
}

/// One drive's settings, fixed at start-up (drive units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveSettings {
    pub setpoint: Setpoint,
    /// One tick's travel at the axis's highest speed (at least 1): the largest target step
    /// accepted when an enabled position drive is handed over to the commanded positions.
    pub max_step_increments: i64,
    /// Master-side following-error check (target minus actual) of a position drive;
    /// `None`: only the drive's own check (statusword bit 13).
    pub following_error_increments: Option<f64>,
    /// Ticks allowed for the enable sequence, and for the switch-off walk.
    pub enable_timeout_ticks: u64,
    pub shutdown: ShutdownMode,
}

impl DriveSettings {
    /// A drive of `setpoint` whose fastest tick travels `max_step_increments`, with no
    /// master-side following-error check and the default switch-off.
    pub fn new(setpoint: Setpoint, max_step_increments: f64, enable_timeout_ticks: u64) -> Self {
        DriveSettings {
            setpoint,
            max_step_increments: (max_step_increments.floor() as i64).max(1),
            following_error_increments: None,
            enable_timeout_ticks,
            shutdown: ShutdownMode::Disable,
        }
    }
}

/// One CiA 402 drive as its master sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Drive {
    settings: DriveSettings,
    phase: DrivePhase,
    statusword: u16,
    /// The drive's actual position (or velocity), drive units.
    actual_increments: i32,
    /// The error code the drive reported with a fault (EMCY, reply), 0 for none.
    error_code: u16,
    controlword: u16,
    target_increments: i32,
    /// The commanded positions have been taken over: until then an enabled position drive
    /// holds its own position, so the target never jumps.
    taken_over: bool,
}

impl Drive {
    pub fn new(settings: DriveSettings) -> Drive {
        Drive {
            settings,
            phase: DrivePhase::Off,
            statusword: 0,
            actual_increments: 0,
            error_code: 0,
            controlword: cw::DISABLE_VOLTAGE,
            target_increments: 0,
            taken_over: false,
        }
    }

    pub fn phase(&self) -> DrivePhase {
        self.phase
    }

    pub fn statusword(&self) -> u16 {
        self.statusword
    }

    pub fn power_state(&self) -> PowerState {
        PowerState::from_statusword(self.statusword)
    }

    pub fn actual_increments(&self) -> i32 {
        self.actual_increments
    }

    pub fn error_code(&self) -> u16 {
        self.error_code
    }

    /// The controlword to send this tick.
    pub fn controlword(&self) -> u16 {
        self.controlword
    }

    /// The target to send this tick, drive units.
    pub fn target_increments(&self) -> i32 {
        self.target_increments
    }

    /// The fault that stopped this drive, if any.
    pub fn fault_reason(&self) -> Option<FaultReason> {
        match self.phase {
            DrivePhase::Faulted(r) => Some(r),
            _ => None,
        }
    }

    /// The drive reported its statusword and actual value (a TPDO, a reply).
    pub fn on_status(&mut self, statusword: u16, actual_increments: i32) {
        self.statusword = statusword;
        self.actual_increments = actual_increments;
    }

    /// The actual value read otherwise (an SDO upload at start-up).
    pub fn set_actual_increments(&mut self, actual_increments: i32) {
        self.actual_increments = actual_increments;
    }

    /// The drive reported an error code (with a fault).
    pub fn set_error_code(&mut self, code: u16) {
        self.error_code = code;
    }

    /// The target that holds the drive still: where it is, or speed 0.
    pub fn hold_target(&self) -> i32 {
        match self.settings.setpoint {
            Setpoint::Position => self.actual_increments,
            Setpoint::Velocity => 0,
        }
    }

    /// Starts the enable sequence at `tick` (at enable, or a reset). The error code of an
    /// earlier fault is forgotten: a new one comes with a new fault.
    pub fn begin_enable(&mut self, tick: u64) {
        self.phase = DrivePhase::Enabling { since: tick };
        self.error_code = 0;
        self.taken_over = false;
    }

    /// Stops the drive for `reason`: power stage off, target holding. The first fault stays
    /// (it is the cause; later ones follow from it).
    pub fn fault(&mut self, reason: FaultReason) {
        if self.fault_reason().is_none() {
            self.phase = DrivePhase::Faulted(reason);
        }
        self.hold(cw::DISABLE_VOLTAGE);
    }

    /// The safe state after a fault stop: `controlword` (a fault reaction's), target holding.
    pub fn stop(&mut self, controlword: u16) {
        self.phase = DrivePhase::Stopped;
        self.hold(controlword);
    }

    /// Starts the orderly switch-off at `tick`; the target stays where it is.
    pub fn begin_power_down(&mut self, tick: u64) {
        self.phase = DrivePhase::PoweringDown { since: tick };
    }

    /// Off at once (the drive can no longer be talked to, or starts afresh).
    pub fn switch_off(&mut self) {
        self.phase = DrivePhase::Off;
        self.hold(cw::DISABLE_VOLTAGE);
    }

    /// The drive holds where it is under `controlword`, its phase unchanged (a reference run
    /// by the drive, run by the bus): the commanded positions are taken over anew after it.
    pub fn hold(&mut self, controlword: u16) {
        self.controlword = controlword;
        self.target_increments = self.hold_target();
        self.taken_over = false;
    }

    /// One tick at `tick`: `fresh` when the statusword arrived in this tick, `target` this
    /// tick's setpoint in drive units.
    pub fn tick(&mut self, tick: u64, fresh: bool, target: i32) {
        match self.phase {
            DrivePhase::Off | DrivePhase::Faulted(_) => self.hold(cw::DISABLE_VOLTAGE),
            DrivePhase::Enabling { since } => self.enable(tick, since, fresh),
            DrivePhase::Enabled => self.operate(target),
            DrivePhase::Stopped => self.target_increments = self.hold_target(),
            DrivePhase::PoweringDown { since } => self.power_down(tick, since, fresh),
        }
    }

    fn enable(&mut self, tick: u64, since: u64, fresh: bool) {
        self.target_increments = self.hold_target();
        let step = fresh.then(|| enable_step(self.statusword, self.controlword));
        match step {
            Some(EnableStep::Enabled) => {
                self.phase = DrivePhase::Enabled;
                self.controlword = cw::ENABLE_OPERATION_CMD;
                self.taken_over = self.settings.setpoint == Setpoint::Velocity;
            }
            _ if tick - since > self.settings.enable_timeout_ticks => {
                let statusword = self.statusword;
                self.fault(FaultReason::EnableTimeout { statusword });
            }
            Some(EnableStep::Toward(c)) => self.controlword = c,
            // Keep the last controlword until the drive reports again.
            None => {}
        }
    }

    fn operate(&mut self, target: i32) {
        let lag = f64::from(self.target_increments) - f64::from(self.actual_increments);
        let fe_limit = self
            .settings
            .following_error_increments
            .filter(|_| self.settings.setpoint == Setpoint::Position);
        if let Some(reason) = operating_fault(self.statusword, self.error_code) {
            self.fault(reason);
        } else if fe_limit.is_some_and(|l| lag.abs() > l) {
            self.fault(FaultReason::FollowingError);
        } else if self.taken_over
            || (i64::from(target) - i64::from(self.target_increments)).abs()
                <= self.settings.max_step_increments
        {
            // The controller commands from where the drive is: from now on it leads.
            self.taken_over = true;
            self.target_increments = target;
        } else {
            // The controller has not yet taken its commanded position from this drive's
            // actual position: hold still.
            self.target_increments = self.hold_target();
        }
    }

    fn power_down(&mut self, tick: u64, since: u64, fresh: bool) {
        let state = self.power_state();
        let off = matches!(
            state,
            PowerState::SwitchOnDisabled
                | PowerState::NotReadyToSwitchOn
                | PowerState::Fault
                | PowerState::FaultReactionActive
        );
        if (fresh && off) || tick - since > self.settings.enable_timeout_ticks {
            self.phase = DrivePhase::Off;
            self.controlword = cw::DISABLE_VOLTAGE;
        } else if fresh {
            self.controlword = match self.settings.shutdown {
                ShutdownMode::Disable => controlword_toward_disabled(state),
                ShutdownMode::QuickStop => controlword_toward_disabled_by_quick_stop(state),
            };
        }
    }
}

#[cfg(test)]
#[path = "drive_tests.rs"]
mod tests;
