//! Reference runs (homing) inside the tick: by switch search (a jog toward the switch, braked
//! when it is pressed) or by the drive itself (CiA 402 homing mode); both end in the state
//! machine's phase, after the bus exchange.

use hal::{BusFault, DriveBus, HomingState};
use kernel::jog::JogRequest;

use super::{HomeRequest, MachineState, RtCore};

/// A reference run under way.
#[derive(Clone, Copy, Debug)]
pub(super) struct HomingRun {
    pub(super) axis: usize,
    pub(super) reference_mm: f64,
    /// Drive position where the switch was found.
    pub(super) trigger_mm: Option<f64>,
    /// The drive runs it itself (CiA 402 homing mode): no switch search here.
    pub(super) by_drive: bool,
}

impl RtCore {
    /// Starts a reference run: the axis moves toward its switch like a jog (no lease: the
    /// operator started it and Stop ends it), at most `max_travel_mm`.
    pub(super) fn home_request(&mut self, r: HomeRequest, bus: &mut dyn DriveBus) {
        let free = self.snap.state == MachineState::Idle
            && self.job.active == 0
            && !self.lifecycle.shutting_down
            && r.axis < self.io.axes;
        if !free {
            return;
        }
        let bit = 1u8 << r.axis;
        self.snap.axes.homed &= !bit;
        self.snap.axes.homing_failed &= !bit;
        if bus.drive_homes() {
            // The drive moves on its own (its settings are the bus's); the axis's setpoint
            // is not used until the run ends.
            bus.start_homing(r.axis);
            self.motion.homing = Some(HomingRun {
                axis: r.axis,
                reference_mm: r.reference_mm,
                trigger_mm: None,
                by_drive: true,
            });
            self.snap.state = MachineState::Homing;
            return;
        }
        let here = self.io.cmd.positions_mm[r.axis];
        let jog = JogRequest {
            axis: r.axis,
            target_mm: here + r.direction.signum() * r.max_travel_mm,
            speed_mm_s: r.speed_mm_s,
            accel_mm_s2: r.accel_mm_s2,
            lease_ticks: u32::MAX,
        };
        if self.motion.jog.request(jog, here) {
            self.motion.homing = Some(HomingRun {
                axis: r.axis,
                reference_mm: r.reference_mm,
                trigger_mm: None,
                by_drive: false,
            });
            self.snap.state = MachineState::Homing;
        }
    }

    /// The reference run after this tick's feedback: brake at the switch; once at rest the
    /// switch position becomes the reference (drive and setpoint shift together: no jump).
    pub(super) fn homing_step(&mut self, bus: &mut dyn DriveBus) {
        let Some(mut h) = self.motion.homing else {
            return;
        };
        if h.by_drive {
            return self.drive_homing_step(h.axis, bus);
        }
        let pressed = self
            .home_input(h.axis)
            .unwrap_or_else(|| bus.home_switch(h.axis));
        if h.trigger_mm.is_none() && pressed {
            h.trigger_mm = Some(self.io.fb.axes[h.axis].position_mm);
            self.motion.jog.stop();
        }
        if self.motion.jog.active() {
            self.motion.homing = Some(h);
            return;
        }
        let bit = 1u8 << h.axis;
        match h.trigger_mm {
            Some(t) => {
                bus.set_home(h.axis, t, h.reference_mm);
                // Setpoint and this tick's feedback shift with the drive's position.
                let shift = h.reference_mm - t;
                self.io.cmd.positions_mm[h.axis] += shift;
                self.io.bus_cmd.positions_mm[h.axis] += shift;
                self.io.resampler.shift(h.axis, shift);
                self.io.fb.axes[h.axis].position_mm += shift;
                self.snap.axes.actual[h.axis] += shift;
                self.snap.axes.homed |= bit;
            }
            None => self.snap.axes.homing_failed |= bit,
        }
        self.motion.homing = None;
    }

    /// A reference run by the drive: once it ends the drive follows setpoints again from where
    /// it stands, so the axis's commanded position is re-based on the drive's (homed)
    /// position: the first setpoint equals it, no jump.
    pub(super) fn drive_homing_step(&mut self, axis: usize, bus: &mut dyn DriveBus) {
        let bit = 1u8 << axis;
        match bus.homing_state(axis) {
            HomingState::Idle | HomingState::Running => return,
            HomingState::Done => self.snap.axes.homed |= bit,
            HomingState::Aborted => self.snap.axes.homing_failed |= bit,
        }
        let here = self.io.fb.axes[axis].position_mm;
        self.io.cmd.positions_mm[axis] = here;
        self.fault_stop.prev_setpoint[axis] = here;
        self.motion.homing = None;
    }

    /// Stop or shutdown during a reference run by the drive: the drive stops it; the run
    /// ends (aborted) when the drive stands.
    pub(super) fn stop_drive_homing(&mut self, bus: &mut dyn DriveBus) {
        if let Some(h) = self.motion.homing.filter(|h| h.by_drive) {
            bus.stop_homing(h.axis);
        }
    }

    /// A drive that refused or did not confirm the reference of a reference run: the axis
    /// was marked homed when the run ended, but it is not.
    pub(super) fn forget_reference(&mut self, fault: BusFault) {
        use hal::FaultReason::{HomingRefused, HomingTimeout};
        if let (Some(a), HomingRefused | HomingTimeout) = (fault.axis, fault.reason)
            && usize::from(a) < self.io.axes
        {
            self.snap.axes.homed &= !(1 << a);
            self.snap.axes.homing_failed |= 1 << a;
        }
    }
}
