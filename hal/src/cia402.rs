//! CiA 402 drive profile: the power state machine driven by the controlword (0x6040) and
//! reported by the statusword (0x6041). Both sides live here, so the master and the simulated
//! drive share one reading of the standard; [`drive`] is the master's phase machine of one
//! drive, shared by every bus.

pub mod drive;
pub use drive::{Drive, DrivePhase, DriveSettings, FaultReaction, Setpoint, ShutdownMode};

/// Controlword bits (0x6040).
pub mod cw {
    pub const SWITCH_ON: u16 = 1 << 0;
    pub const ENABLE_VOLTAGE: u16 = 1 << 1;
    /// Active low: 0 requests a quick stop.
    pub const QUICK_STOP: u16 = 1 << 2;
    pub const ENABLE_OPERATION: u16 = 1 << 3;
    /// Homing mode (6): a rising edge starts the reference run, 0 interrupts it.
    pub const HOMING_START: u16 = 1 << 4;
    /// Rising edge resets a fault.
    pub const FAULT_RESET: u16 = 1 << 7;

    pub const DISABLE_VOLTAGE: u16 = 0x0000;
    pub const SHUTDOWN: u16 = ENABLE_VOLTAGE | QUICK_STOP;
    pub const SWITCH_ON_CMD: u16 = SHUTDOWN | SWITCH_ON;
    pub const ENABLE_OPERATION_CMD: u16 = SWITCH_ON_CMD | ENABLE_OPERATION;
    /// "Quick stop": voltage enabled, quick-stop bit low.
    pub const QUICK_STOP_CMD: u16 = ENABLE_VOLTAGE;
}

/// Statusword bits (0x6041).
pub mod sw {
    pub const READY_TO_SWITCH_ON: u16 = 1 << 0;
    pub const SWITCHED_ON: u16 = 1 << 1;
    pub const OPERATION_ENABLED: u16 = 1 << 2;
    pub const FAULT: u16 = 1 << 3;
    pub const VOLTAGE_ENABLED: u16 = 1 << 4;
    /// Active low: 0 means a quick stop is active.
    pub const QUICK_STOP: u16 = 1 << 5;
    pub const SWITCH_ON_DISABLED: u16 = 1 << 6;
    pub const WARNING: u16 = 1 << 7;
    pub const REMOTE: u16 = 1 << 9;
    /// Target reached; in homing mode (6): the drive stands (reference run ended or
    /// interrupted).
    pub const TARGET_REACHED: u16 = 1 << 10;
    /// In homing mode (6): homing attained (the reference run found its home position).
    pub const HOMING_ATTAINED: u16 = 1 << 12;
    /// In homing mode (6): homing error.
    pub const HOMING_ERROR: u16 = 1 << 13;
    /// In CSP mode: the drive follows the target position.
    pub const TARGET_FOLLOWED: u16 = 1 << 12;
    /// In CSP mode: following error beyond 0x6065.
    pub const FOLLOWING_ERROR: u16 = 1 << 13;
}

/// The CiA 402 power states.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PowerState {
    NotReadyToSwitchOn,
    SwitchOnDisabled,
    ReadyToSwitchOn,
    SwitchedOn,
    OperationEnabled,
    QuickStopActive,
    FaultReactionActive,
    Fault,
}

impl PowerState {
    /// Decodes the state bits of a statusword (masks from CiA 402 table 30).
    pub fn from_statusword(s: u16) -> PowerState {
        match (s & 0x004F, s & 0x006F) {
            (0x0000, _) => PowerState::NotReadyToSwitchOn,
            (0x0040, _) => PowerState::SwitchOnDisabled,
            (_, 0x0021) => PowerState::ReadyToSwitchOn,
            (_, 0x0023) => PowerState::SwitchedOn,
            (_, 0x0027) => PowerState::OperationEnabled,
            (_, 0x0007) => PowerState::QuickStopActive,
            (0x000F, _) => PowerState::FaultReactionActive,
            (0x0008, _) => PowerState::Fault,
            // Undefined bit patterns: treat as not ready, the master then waits.
            _ => PowerState::NotReadyToSwitchOn,
        }
    }

    /// The state bits a drive reports in this state (bits 0..6, voltage bit set when powered).
    pub fn statusword_bits(self) -> u16 {
        match self {
            PowerState::NotReadyToSwitchOn => 0x0000,
            PowerState::SwitchOnDisabled => 0x0040,
            PowerState::ReadyToSwitchOn => 0x0031,
            PowerState::SwitchedOn => 0x0033,
            PowerState::OperationEnabled => 0x0037,
            PowerState::QuickStopActive => 0x0017,
            PowerState::FaultReactionActive => 0x001F,
            PowerState::Fault => 0x0018,
        }
    }
}

/// Master side: the controlword that moves a drive in `state` one step toward Operation
/// Enabled. `previous` is the controlword sent last tick: a fault reset needs a rising edge of
/// bit 7, so in Fault the reset bit alternates.
pub fn controlword_toward_enabled(state: PowerState, previous: u16) -> u16 {
    match state {
        PowerState::Fault => {
            if previous & cw::FAULT_RESET != 0 {
                cw::DISABLE_VOLTAGE
            } else {
                cw::FAULT_RESET
            }
        }
        // From Quick Stop Active only disable voltage leads back (transition 12); 06h there
        // is not a transition of CiA 402 and a drive would stay.
        PowerState::FaultReactionActive
        | PowerState::NotReadyToSwitchOn
        | PowerState::QuickStopActive => cw::DISABLE_VOLTAGE,
        PowerState::SwitchOnDisabled => cw::SHUTDOWN,
        PowerState::ReadyToSwitchOn => cw::SWITCH_ON_CMD,
        PowerState::SwitchedOn | PowerState::OperationEnabled => cw::ENABLE_OPERATION_CMD,
    }
}

/// Master side: the controlword that moves a drive in `state` one step toward Switch On
/// Disabled in the orderly order of a shutdown: disable operation (07h) while enabled, then
/// shutdown (06h), then disable voltage (00h). Sent until the statusword shows each step.
pub fn controlword_toward_disabled(state: PowerState) -> u16 {
    match state {
        PowerState::OperationEnabled => cw::SWITCH_ON_CMD, // "disable operation"
        PowerState::SwitchedOn => cw::SHUTDOWN,
        _ => cw::DISABLE_VOLTAGE,
    }
}

/// Master side: as [`controlword_toward_disabled`], but through a quick stop (02h) while
/// enabled, then disable voltage (00h) from Quick Stop Active: the drive stops by its quick
/// stop option (0x605A) first.
pub fn controlword_toward_disabled_by_quick_stop(state: PowerState) -> u16 {
    match state {
        PowerState::OperationEnabled => cw::QUICK_STOP_CMD,
        _ => cw::DISABLE_VOLTAGE,
    }
}

/// Drive side: the state after receiving controlword `c` in `state` (CiA 402 transitions 2..16;
/// `previous` is the last controlword, for the fault-reset edge). Fault entry is the drive's
/// own decision and not handled here.
pub fn apply_controlword(state: PowerState, previous: u16, c: u16) -> PowerState {
    use PowerState::*;
    let disable_voltage = c & cw::ENABLE_VOLTAGE == 0;
    let quick_stop = c & (cw::ENABLE_VOLTAGE | cw::QUICK_STOP) == cw::ENABLE_VOLTAGE;
    let shutdown = c & 0x0007 == cw::SHUTDOWN;
    let switch_on = c & 0x000F == cw::SWITCH_ON_CMD;
    let enable = c & 0x000F == cw::ENABLE_OPERATION_CMD;
    match state {
        NotReadyToSwitchOn => SwitchOnDisabled,
        Fault => {
            if c & cw::FAULT_RESET != 0 && previous & cw::FAULT_RESET == 0 {
                SwitchOnDisabled
            } else {
                Fault
            }
        }
        FaultReactionActive => Fault,
        _ if disable_voltage => SwitchOnDisabled,
        SwitchOnDisabled => {
            if shutdown {
                ReadyToSwitchOn
            } else {
                SwitchOnDisabled
            }
        }
        ReadyToSwitchOn => {
            if quick_stop {
                SwitchOnDisabled
            } else if switch_on || enable {
                // Transition 3 (and 3+4 at once, which many drives accept).
                if enable { OperationEnabled } else { SwitchedOn }
            } else {
                ReadyToSwitchOn
            }
        }
        SwitchedOn => {
            if quick_stop {
                SwitchOnDisabled
            } else if shutdown {
                ReadyToSwitchOn
            } else if enable {
                OperationEnabled
            } else {
                SwitchedOn
            }
        }
        OperationEnabled => {
            if quick_stop {
                QuickStopActive
            } else if shutdown {
                ReadyToSwitchOn
            } else if switch_on {
                SwitchedOn
            } else {
                OperationEnabled
            }
        }
        QuickStopActive => {
            if enable && c & cw::QUICK_STOP != 0 {
                OperationEnabled
            } else {
                QuickStopActive
            }
        }
    }
}

/// One step of the master's enable sequence on a fresh statusword (the same for every bus).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EnableStep {
    /// Operation Enabled: the drive follows setpoints from now on (controlword
    /// [`cw::ENABLE_OPERATION_CMD`]).
    Enabled,
    /// Not there yet: send this controlword.
    Toward(u16),
}

/// The enable step for a drive reporting `statusword`, `previous` the controlword sent last.
pub fn enable_step(statusword: u16, previous: u16) -> EnableStep {
    match PowerState::from_statusword(statusword) {
        PowerState::OperationEnabled => EnableStep::Enabled,
        state => EnableStep::Toward(controlword_toward_enabled(state, previous)),
    }
}

/// Why an operating drive must stop, by its statusword (`error_code`: the drive's error code,
/// reported with a fault), or `None` while it follows. The same watch for every bus.
pub fn operating_fault(statusword: u16, error_code: u16) -> Option<crate::FaultReason> {
    use crate::FaultReason;
    let state = PowerState::from_statusword(statusword);
    if statusword & sw::FOLLOWING_ERROR != 0 {
        Some(FaultReason::FollowingError)
    } else if matches!(state, PowerState::Fault | PowerState::FaultReactionActive) {
        Some(FaultReason::DriveFault { code: error_code })
    } else if state != PowerState::OperationEnabled {
        Some(FaultReason::DriveDisabled { statusword })
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The states an enabled drive passes through under the controlwords of `toward`.
    fn walk_down(toward: fn(PowerState) -> u16) -> Vec<PowerState> {
        let mut state = PowerState::OperationEnabled;
        let mut last_cw = cw::ENABLE_OPERATION_CMD;
        let mut seen = vec![state];
        while state != PowerState::SwitchOnDisabled && seen.len() < 10 {
            let c = toward(state);
            state = apply_controlword(state, last_cw, c);
            last_cw = c;
            seen.push(state);
        }
        seen
    }

    #[test]
    fn operating_fault_names_following_error_fault_and_switch_off() {
        use crate::FaultReason;
        let enabled = PowerState::OperationEnabled.statusword_bits();
        assert_eq!(operating_fault(enabled, 0), None);
        assert_eq!(
            operating_fault(enabled | sw::FOLLOWING_ERROR, 0),
            Some(FaultReason::FollowingError)
        );
        let fault = PowerState::Fault.statusword_bits();
        assert_eq!(
            operating_fault(fault, 0x2310),
            Some(FaultReason::DriveFault { code: 0x2310 })
        );
        let off = PowerState::SwitchOnDisabled.statusword_bits();
        assert_eq!(
            operating_fault(off, 0),
            Some(FaultReason::DriveDisabled { statusword: off })
        );
        assert_eq!(enable_step(enabled, cw::SWITCH_ON_CMD), EnableStep::Enabled);
        assert_eq!(enable_step(off, 0), EnableStep::Toward(cw::SHUTDOWN));
    }

    /// The shutdown walk goes through Switched On and Ready to Switch On, never a jump.
    #[test]
    fn orderly_disable_walks_down_step_by_step() {
        assert_eq!(
            walk_down(controlword_toward_disabled),
            [
                PowerState::OperationEnabled,
                PowerState::SwitchedOn,
                PowerState::ReadyToSwitchOn,
                PowerState::SwitchOnDisabled
            ]
        );
        // Through a quick stop: Quick Stop Active, then Switch On Disabled.
        assert_eq!(
            walk_down(controlword_toward_disabled_by_quick_stop),
            [
                PowerState::OperationEnabled,
                PowerState::QuickStopActive,
                PowerState::SwitchOnDisabled
            ]
        );
    }

    /// The master's controlwords bring a drive from power-on to Operation Enabled, and from
    /// Fault back to it, through the drive-side transitions.
    #[test]
    fn master_and_drive_agree() {
        for start in [PowerState::NotReadyToSwitchOn, PowerState::Fault] {
            let mut state = start;
            let mut last_cw = 0u16;
            let mut seen = vec![state];
            for _ in 0..10 {
                let c = controlword_toward_enabled(state, last_cw);
                state = apply_controlword(state, last_cw, c);
                last_cw = c;
                seen.push(state);
                // Every state round-trips through its statusword bits.
                assert_eq!(PowerState::from_statusword(state.statusword_bits()), state);
                if state == PowerState::OperationEnabled {
                    break;
                }
            }
            assert_eq!(state, PowerState::OperationEnabled, "{seen:?}");
            assert!(seen.contains(&PowerState::ReadyToSwitchOn), "{seen:?}");
        }
    }

    #[test]
    fn fault_reset_needs_a_rising_edge() {
        assert_eq!(
            apply_controlword(PowerState::Fault, cw::FAULT_RESET, cw::FAULT_RESET),
            PowerState::Fault
        );
        assert_eq!(
            apply_controlword(PowerState::Fault, 0, cw::FAULT_RESET),
            PowerState::SwitchOnDisabled
        );
    }

    #[test]
    fn statusword_decoding_ignores_other_bits() {
        let s = PowerState::OperationEnabled.statusword_bits() | sw::REMOTE | sw::TARGET_FOLLOWED;
        assert_eq!(PowerState::from_statusword(s), PowerState::OperationEnabled);
        assert_eq!(
            PowerState::from_statusword(0x0008 | sw::FOLLOWING_ERROR),
            PowerState::Fault
        );
        assert_eq!(
            PowerState::from_statusword(0x0040),
            PowerState::SwitchOnDisabled
        );
    }
}
