//! Fault reaction (issue #15): a bus or KŘR fault ends the job, every healthy axis brakes on
//! its own, and once at rest the drives go to their safe state.

use hal::{BusFault, DriveBus};
use kernel::estop::AxisBrake;
use kernel::interp::InterpState;
use kernel::units::AxesMm;

use super::RtCore;
use super::state::{SETTLE_TICKS, SETTLED_MM};

/// The fault stop under way.
pub(super) struct FaultStop {
    /// Every healthy axis brakes on its own.
    pub(super) brake: AxisBrake,
    /// Setpoints sent the tick before the last one (the brake starts from their speed).
    pub(super) prev_setpoint: AxesMm,
    /// Ticks since the brake came to rest; the drives go to their safe state once settled.
    pub(super) rest_ticks: u32,
    pub(super) safe_state_sent: bool,
    /// Reset was asked for while the axes still braked: it is done once they are at rest.
    pub(super) reset_pending: bool,
}

impl RtCore {
    /// Ends the active job: brake on the path and drop what remains.
    pub(super) fn abort(&mut self) {
        self.job.spindle_off = true;
        self.changer.abort();
        if self.job.active != 0 {
            self.snap.progress.aborted_job = self.job.active;
            self.job.active = 0;
        }
        self.motion.interp.stop();
    }

    pub(super) fn fault(&mut self, fault: BusFault) {
        self.forget_reference(fault);
        if self.snap.alarm.fault.is_none() {
            self.snap.alarm.fault = Some(fault);
            self.start_fault_stop(fault);
            self.abort();
        }
    }

    /// Fault reaction (issue #15): a faulted axis no longer follows, so braking along the path
    /// would pull the tool off it. Every healthy axis brakes on its own at its stop
    /// deceleration from the speed of its last setpoints; a faulted axis keeps its setpoint
    /// where it stands.
    pub(super) fn start_fault_stop(&mut self, fault: BusFault) {
        // The brake takes over from the jog's last setpoints.
        self.motion.jog.cancel();
        let homing = self.motion.homing.take();
        if let Some(h) = homing {
            self.snap.axes.homing_failed |= 1 << h.axis;
        }
        let now = AxesMm(self.io.cmd.positions_mm);
        self.fault_stop.brake.start(
            &self.fault_stop.prev_setpoint,
            &now,
            self.motion.interp.current_path(),
        );
        // A drive homing on its own is not where its setpoint is: it stops where it stands.
        if let Some(h) = homing.filter(|h| h.by_drive) {
            self.fault_stop
                .brake
                .hold_axis(h.axis, self.io.fb.axes[h.axis].position_mm);
        }
        // (An input's fault names an axis that still follows: a limit switch's.)
        let faulted_axis = fault.axis.filter(|_| !fault.reason.is_input());
        if let Some(a) = faulted_axis.map(usize::from).filter(|&a| a < self.io.axes) {
            self.fault_stop
                .brake
                .hold_axis(a, self.io.fb.axes[a].position_mm);
        }
        self.fault_stop.rest_ticks = 0;
        self.fault_stop.safe_state_sent = false;
        self.snap.alarm.fault_path_deviation_mm = 0.0;
    }

    /// While the fault stop runs: measure the deviation from the path; once every axis is at
    /// rest (setpoints still, drives caught up, or a settle timeout), bring the drives to
    /// their safe state (CiA 402 quick stop / disable).
    pub(super) fn fault_reaction(&mut self, bus: &mut dyn DriveBus) {
        if self.fault_stop.reset_pending && self.motion.interp.state() == InterpState::Idle {
            // (As the command itself: not while the emergency-stop chain is open.)
            self.fault_stop.reset_pending = false;
            if self.io_reset() {
                self.reset_fault(bus);
            }
            return;
        }
        if !self.fault_stop.brake.active() {
            return;
        }
        self.fault_stop.brake.observe(&self.snap.axes.actual);
        self.snap.alarm.fault_path_deviation_mm = self.fault_stop.brake.deviation_mm();
        if self.fault_stop.safe_state_sent || !self.fault_stop.brake.at_rest() {
            return;
        }
        let settled = (0..self.io.axes)
            .all(|i| (self.io.cmd.positions_mm[i] - self.snap.axes.actual[i]).abs() < SETTLED_MM);
        self.fault_stop.rest_ticks += 1;
        if settled || self.fault_stop.rest_ticks >= SETTLE_TICKS {
            bus.safe_state();
            self.fault_stop.safe_state_sent = true;
        }
    }
}
