//! In-process simulated bus: one [`SimDrive`] per axis, stepped once per cycle.

use hal::{AxisFeedback, BusFault, CycleCommand, CycleFeedback, DriveBus, DriveState, FaultReason};

use crate::drive::{SimDrive, SimDriveParams};

/// Cycle time of the simulated drives, s (the controller's Ts).
const CYCLE_S: f64 = 0.004;

pub struct SimBus {
    drives: Vec<SimDrive>,
    /// Home switch per axis: (where it is in the drive's power-on coordinates, the side it
    /// is pressed on: -1 at and below, +1 at and above).
    switches: Vec<Option<(f64, f64)>>,
    /// Shift of each drive's reported position since power-on (homing).
    shifts: Vec<f64>,
}

impl SimBus {
    /// `start_mm` gives the number of axes and where each starts.
    pub fn new(params: SimDriveParams, start_mm: &[f64]) -> Self {
        SimBus {
            drives: start_mm.iter().map(|&p| SimDrive::new(params, p)).collect(),
            switches: vec![None; start_mm.len()],
            shifts: vec![0.0; start_mm.len()],
        }
    }

    /// Home switch model (issue #15): axis `axis` has a switch at `at_mm` (power-on
    /// coordinates), pressed at and beyond it on side `side` (-1 or +1).
    pub fn with_home_switch(mut self, axis: usize, at_mm: f64, side: f64) -> Self {
        self.switches[axis] = Some((at_mm, side.signum()));
        self
    }

    /// Access for fault injection in tests.
    pub fn drive_mut(&mut self, axis: usize) -> &mut SimDrive {
        &mut self.drives[axis]
    }
}

impl DriveBus for SimBus {
    fn name(&self) -> &str {
        "sim"
    }

    fn axes(&self) -> usize {
        self.drives.len()
    }

    fn has_spindle(&self) -> bool {
        true
    }

    fn cycle(&mut self, cmd: &CycleCommand, feedback: &mut CycleFeedback) -> Result<(), BusFault> {
        let mut fault = None;
        // The simulated spindle reaches its setpoint at once.
        feedback.spindle_rpm = cmd.spindle_rpm;
        feedback.spindle_state = DriveState::Operational;
        for (i, (d, (sp, fb))) in self
            .drives
            .iter_mut()
            .zip(cmd.positions_mm.iter().zip(feedback.axes.iter_mut()))
            .enumerate()
        {
            d.step(*sp, CYCLE_S);
            *fb = AxisFeedback {
                position_mm: d.position_mm(),
                state: d.state(),
            };
            if d.state() == DriveState::Fault && fault.is_none() {
                fault = Some(BusFault {
                    axis: Some(i as u8),
                    node: Some(i as u8 + 1),
                    reason: FaultReason::FollowingError,
                });
            }
        }
        fault.map_or(Ok(()), Err)
    }

    fn enable(&mut self) {
        self.drives.iter_mut().for_each(SimDrive::enable);
    }

    fn supports_homing(&self) -> bool {
        true
    }

    fn home_switch(&self, axis: usize) -> bool {
        let Some((at, side)) = self.switches.get(axis).copied().flatten() else {
            return false;
        };
        let p = self.drives[axis].position_mm() - self.shifts[axis];
        (p - at) * side >= 0.0
    }

    fn set_home(&mut self, axis: usize, trigger_mm: f64, reference_mm: f64) {
        self.drives[axis].shift_reference(trigger_mm, reference_mm);
        self.shifts[axis] += reference_mm - trigger_mm;
    }

    fn safe_state(&mut self) {
        self.drives.iter_mut().for_each(SimDrive::disable);
    }

    fn reset(&mut self) {
        for d in &mut self.drives {
            d.reset();
            d.enable();
        }
    }
}
