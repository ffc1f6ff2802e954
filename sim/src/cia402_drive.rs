//! A CiA 402 servo drive as the bus simulators expose it: power state machine, error code
//! (0x603F), and either cyclic synchronous position mode (position loop with lag,
//! [`crate::drive::follow`], following-error window 0x6065; positions on the wire are
//! increments) or cyclic synchronous velocity mode (a spindle: the speed ramps toward the
//! target velocity 0x60FF at a set acceleration; velocities on the wire are drive units).

use hal::cia402::{self, PowerState, sw};

use crate::drive::{SimDriveParams, follow};
use crate::homing::{Axis, Homer};

/// What a cycle changed that the bus must announce (CANopen: an EMCY message).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Event {
    Fault { code: u16 },
    FaultCleared,
}

/// Error code of a following error (CiA 402).
pub const FOLLOWING_ERROR: u16 = 0x8611;
/// Error code when the controller's heartbeat or setpoints stop (CiA 301 "life guard").
pub const COMMUNICATION_LOST: u16 = 0x8130;

#[derive(Clone, Debug)]
pub struct Cia402Drive {
    pub params: SimDriveParams,
    pub increments_per_mm: f64,
    state: PowerState,
    last_controlword: u16,
    position_mm: f64,
    following_error: bool,
    error_code: u16,
    /// Actual velocity in CSV, drive units.
    velocity_units: f64,
    /// Acceleration of the velocity ramp in CSV, drive units per second (0: the speed follows
    /// the target at once).
    pub velocity_ramp_units_s2: f64,
    /// Safe torque off: the power stage cannot be switched on (stays Switch On Disabled).
    pub sto: bool,
    /// Edge of the home switch in the drive's coordinates, mm (`None`: no switch); which
    /// side is active depends on the homing method ([`crate::homing`]).
    pub home_switch_mm: Option<f64>,
    /// Homing mode (6): objects and the reference run.
    pub homer: Homer,
    homing_mode: bool,
}

impl Cia402Drive {
    pub fn new(params: SimDriveParams, increments_per_mm: f64, start_mm: f64) -> Self {
        Cia402Drive {
            params,
            increments_per_mm,
            state: PowerState::SwitchOnDisabled,
            last_controlword: 0,
            position_mm: start_mm,
            following_error: false,
            error_code: 0,
            velocity_units: 0.0,
            velocity_ramp_units_s2: 0.0,
            sto: false,
            home_switch_mm: None,
            homer: Homer::default(),
            homing_mode: false,
        }
    }

    /// The mode of operation is homing (6) or not: entering it starts with no run.
    pub fn set_homing_mode(&mut self, on: bool) {
        if on != self.homing_mode {
            self.homer.reset();
        }
        self.homing_mode = on;
    }

    /// One cycle in homing mode: apply the controlword; enabled, bit 4 runs the reference
    /// run (the target position is not used).
    pub fn cycle_homing(&mut self, controlword: u16, dt_s: f64) -> Option<Event> {
        let event = self.apply(controlword);
        if self.state != PowerState::OperationEnabled {
            self.homer.reset();
            return event;
        }
        let mut axis = Axis {
            position_mm: &mut self.position_mm,
            switch_mm: &mut self.home_switch_mm,
            increments_per_mm: self.increments_per_mm,
        };
        let start = controlword & hal::cia402::cw::HOMING_START != 0;
        self.homer.cycle(start, &mut axis, dt_s);
        event
    }

    /// Actual velocity (0x606C), drive units.
    pub fn velocity_units(&self) -> i32 {
        self.velocity_units
            .round()
            .clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
    }

    pub fn state(&self) -> PowerState {
        self.state
    }

    pub fn error_code(&self) -> u16 {
        self.error_code
    }

    pub fn position_mm(&self) -> f64 {
        self.position_mm
    }

    pub fn position_increments(&self) -> i32 {
        (self.position_mm * self.increments_per_mm).round() as i32
    }

    /// Following-error window, increments (0x6065).
    pub fn window_increments(&self) -> u32 {
        (self.params.following_window_mm * self.increments_per_mm).round() as u32
    }

    pub fn set_window_increments(&mut self, inc: u32) {
        self.params.following_window_mm = f64::from(inc) / self.increments_per_mm;
    }

    pub fn statusword(&self) -> u16 {
        let mut s = self.state.statusword_bits() | sw::REMOTE;
        if self.homing_mode {
            // Bits 10, 12, 13 are the homing handshake in mode 6.
            return s | self.homer.status_bits();
        }
        if self.state == PowerState::OperationEnabled {
            s |= sw::TARGET_FOLLOWED;
        }
        if self.following_error {
            s |= sw::FOLLOWING_ERROR;
        }
        s
    }

    /// A software reset (NMT reset node): power stage off, faults cleared, position kept.
    pub fn restart(&mut self) {
        self.state = PowerState::SwitchOnDisabled;
        self.last_controlword = 0;
        self.following_error = false;
        self.error_code = 0;
    }

    /// The drive's own fault (over-current, lost communication...).
    pub fn fault(&mut self, code: u16) -> Option<Event> {
        if self.state == PowerState::Fault {
            return None;
        }
        self.state = PowerState::Fault;
        self.error_code = code;
        Some(Event::Fault { code })
    }

    /// One cycle: apply the controlword, then follow `target_increments` for `dt_s` when
    /// enabled (the target is ignored otherwise: the drive holds where it is).
    pub fn cycle(&mut self, controlword: u16, target_increments: i32, dt_s: f64) -> Option<Event> {
        let mut event = self.apply(controlword);
        if self.state == PowerState::OperationEnabled {
            let target_mm = f64::from(target_increments) / self.increments_per_mm;
            self.position_mm = follow(&self.params, self.position_mm, target_mm, dt_s);
            if (target_mm - self.position_mm).abs() > self.params.following_window_mm {
                self.following_error = true;
                event = self.fault(FOLLOWING_ERROR);
            }
        }
        event
    }

    /// One cycle in velocity mode: apply the controlword, then ramp the speed toward
    /// `target_units` when enabled; a drive without power stage coasts down on the same ramp.
    pub fn cycle_velocity(
        &mut self,
        controlword: u16,
        target_units: i32,
        dt_s: f64,
    ) -> Option<Event> {
        let event = self.apply(controlword);
        let target = if self.state == PowerState::OperationEnabled {
            f64::from(target_units)
        } else {
            0.0
        };
        let step = self.velocity_ramp_units_s2 * dt_s;
        self.velocity_units = if step <= 0.0 {
            target
        } else {
            self.velocity_units + (target - self.velocity_units).clamp(-step, step)
        };
        event
    }

    /// The controlword's effect on the power state machine; a fault reset clears the fault.
    fn apply(&mut self, controlword: u16) -> Option<Event> {
        let before = self.state;
        self.state = cia402::apply_controlword(self.state, self.last_controlword, controlword);
        // Strict handshake: Ready to Switch On goes to Operation Enabled only through
        // Switched On (07h, then 0Fh), as some drives insist; no 3+4 in one step.
        if before == PowerState::ReadyToSwitchOn && self.state == PowerState::OperationEnabled {
            self.state = PowerState::ReadyToSwitchOn;
        }
        if self.sto && self.state != PowerState::Fault {
            self.state = PowerState::SwitchOnDisabled;
        }
        self.last_controlword = controlword;
        if before == PowerState::Fault && self.state != PowerState::Fault {
            self.following_error = false;
            self.error_code = 0;
            return Some(Event::FaultCleared);
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hal::cia402::cw;

    fn enabled() -> Cia402Drive {
        let mut d = Cia402Drive::new(SimDriveParams::default(), 1000.0, 1.0);
        for c in [cw::SHUTDOWN, cw::SWITCH_ON_CMD, cw::ENABLE_OPERATION_CMD] {
            assert_eq!(d.cycle(c, 1000, 0.004), None);
        }
        assert_eq!(d.state(), PowerState::OperationEnabled);
        d
    }

    #[test]
    fn velocity_mode_ramps_to_the_target_and_coasts_when_disabled() {
        let mut d = enabled();
        d.velocity_ramp_units_s2 = 10_000.0; // 40 units per 4 ms cycle
        d.cycle_velocity(cw::ENABLE_OPERATION_CMD, 100, 0.004);
        assert_eq!(d.velocity_units(), 40);
        for _ in 0..5 {
            d.cycle_velocity(cw::ENABLE_OPERATION_CMD, 100, 0.004);
        }
        assert_eq!(d.velocity_units(), 100);
        d.cycle_velocity(cw::ENABLE_OPERATION_CMD, -20, 0.004);
        assert_eq!(d.velocity_units(), 60);
        // Power stage off: the target no longer counts, the spindle runs down.
        d.cycle_velocity(cw::DISABLE_VOLTAGE, 100, 0.004);
        assert_eq!(d.velocity_units(), 20);
        d.cycle_velocity(cw::DISABLE_VOLTAGE, 100, 0.004);
        assert_eq!(d.velocity_units(), 0);
    }

    #[test]
    fn follows_with_lag_and_faults_beyond_the_window() {
        let mut d = enabled();
        assert_eq!(
            d.position_increments(),
            1000,
            "disabled drive holds its position"
        );
        for _ in 0..500 {
            d.cycle(cw::ENABLE_OPERATION_CMD, 5000, 0.004);
        }
        assert_eq!(d.position_increments(), 5000);
        let e = d.cycle(cw::ENABLE_OPERATION_CMD, 5000 + 60_000, 0.004);
        assert_eq!(
            e,
            Some(Event::Fault {
                code: FOLLOWING_ERROR
            })
        );
        assert_ne!(d.statusword() & sw::FOLLOWING_ERROR, 0);
        assert_eq!(
            PowerState::from_statusword(d.statusword()),
            PowerState::Fault
        );
        // Fault reset edge clears it.
        d.cycle(0, 0, 0.004);
        assert_eq!(
            d.cycle(cw::FAULT_RESET, 0, 0.004),
            Some(Event::FaultCleared)
        );
        assert_eq!(d.statusword() & sw::FOLLOWING_ERROR, 0);
    }
}
