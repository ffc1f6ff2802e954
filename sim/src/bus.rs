//! In-process simulated bus: one [`SimDrive`] per axis, stepped once per cycle.

use hal::{AxisFeedback, BusFault, CycleCommand, CycleFeedback, DriveBus, DriveState, FaultReason};

use crate::drive::{SimDrive, SimDriveParams};

/// Cycle time of the simulated drives, s (the controller's Ts).
const CYCLE_S: f64 = 0.004;

pub struct SimBus {
    drives: Vec<SimDrive>,
}

impl SimBus {
    /// `start_mm` gives the number of axes and where each starts.
    pub fn new(params: SimDriveParams, start_mm: &[f64]) -> Self {
        SimBus {
            drives: start_mm.iter().map(|&p| SimDrive::new(params, p)).collect(),
        }
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
