//! In-process simulated bus: one [`SimDrive`] per axis, stepped once per cycle.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use hal::{AxisFeedback, BusFault, CycleCommand, CycleFeedback, DriveBus, DriveState, FaultReason};

use crate::drive::{SimDrive, SimDriveParams};
use crate::io::{SimInput, SimInputs, SimIo};

pub struct SimBus {
    drives: Vec<SimDrive>,
    /// Home switch per axis: (where it is in the drive's power-on coordinates, the side it
    /// is pressed on: -1 at and below, +1 at and above).
    switches: Vec<Option<(f64, f64)>>,
    /// Shift of each drive's reported position since power-on (homing).
    shifts: Vec<f64>,
    /// Spindle acceleration, rpm/s (0: the setpoint is reached at once).
    spindle_ramp_rpm_s: f64,
    spindle_rpm: f64,
    spindle_load: SpindleLoad,
    /// Time the drives advance per cycle, s (the bus period).
    cycle_s: f64,
    /// The simulated machine's inputs and outputs.
    io: SimIo,
    /// Work space: the drives' positions (no allocation per cycle).
    raw_mm: Vec<f64>,
}

/// Test knob of the simulated spindle: the share (0..1) of its speed lost to cutting load.
/// With load L the spindle settles at (1 − L) × setpoint, ramping there as it would.
#[derive(Clone, Debug, Default)]
pub struct SpindleLoad(Arc<AtomicU64>);

impl SpindleLoad {
    /// Sets the share of speed lost, clamped to 0..1 (1: stalled).
    pub fn set(&self, share: f64) {
        let share = if share.is_nan() {
            0.0
        } else {
            share.clamp(0.0, 1.0)
        };
        self.0.store(share.to_bits(), Ordering::Relaxed);
    }

    pub fn get(&self) -> f64 {
        f64::from_bits(self.0.load(Ordering::Relaxed))
    }
}

impl SimBus {
    /// `start_mm` gives the number of axes and where each starts.
    pub fn new(params: SimDriveParams, start_mm: &[f64]) -> Self {
        SimBus {
            drives: start_mm.iter().map(|&p| SimDrive::new(params, p)).collect(),
            switches: vec![None; start_mm.len()],
            shifts: vec![0.0; start_mm.len()],
            spindle_ramp_rpm_s: 0.0,
            spindle_rpm: 0.0,
            spindle_load: SpindleLoad::default(),
            // The interpolation period, which is also the daemon's default bus period.
            cycle_s: kernel::units::TS_S,
            io: SimIo {
                inputs: SimIo::machine_default(start_mm.len()),
                ..SimIo::default()
            },
            raw_mm: vec![0.0; start_mm.len()],
        }
    }

    /// The machine's simulated inputs, in the configuration's order (docs/io.md); without
    /// this call the daemon's default set ([`SimIo::machine_default`]).
    pub fn with_inputs(mut self, inputs: Vec<SimInput>) -> Self {
        self.io.inputs = inputs;
        self
    }

    /// What the probe inputs touch (docs/setup.md, "Probing").
    pub fn with_probe(mut self, probe: Option<crate::probe::SimProbe>) -> Self {
        self.io.probe = probe;
        self
    }

    /// Uses `handle` to set simulated inputs from outside (the daemon keeps one for
    /// `cncctl io sim-set`).
    pub fn with_input_handle(mut self, handle: SimInputs) -> Self {
        self.io.set = handle;
        self
    }

    /// The handle that sets simulated inputs from outside (shared: use it while the bus runs).
    pub fn input_handle(&self) -> SimInputs {
        self.io.set.clone()
    }

    /// The outputs as last written.
    pub fn outputs(&self) -> hal::io::IoBits {
        self.io.outputs
    }

    /// The drives advance `cycle_s` per cycle (the daemon's `[bus] cycle_ms`).
    pub fn with_cycle_s(mut self, cycle_s: f64) -> Self {
        self.cycle_s = cycle_s;
        self
    }

    /// Home switch model (issue #15): axis `axis` has a switch at `at_mm` (power-on
    /// coordinates), pressed at and beyond it on side `side` (-1 or +1).
    pub fn with_home_switch(mut self, axis: usize, at_mm: f64, side: f64) -> Self {
        self.switches[axis] = Some((at_mm, side.signum()));
        self
    }

    /// The spindle accelerates at `rpm_per_s` instead of reaching its setpoint at once.
    pub fn with_spindle_ramp(mut self, rpm_per_s: f64) -> Self {
        self.spindle_ramp_rpm_s = rpm_per_s.max(0.0);
        self
    }

    /// The load knob of the spindle (shared: set it while the bus runs).
    pub fn spindle_load(&self) -> SpindleLoad {
        self.spindle_load.clone()
    }

    /// One cycle of the spindle: toward setpoint × (1 − load), within the ramp.
    fn step_spindle(&mut self, set_rpm: f64) -> f64 {
        let target = set_rpm * (1.0 - self.spindle_load.get());
        self.spindle_rpm = if self.spindle_ramp_rpm_s > 0.0 {
            let dv = self.spindle_ramp_rpm_s * self.cycle_s;
            self.spindle_rpm + (target - self.spindle_rpm).clamp(-dv, dv)
        } else {
            target
        };
        self.spindle_rpm
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
        feedback.spindle_rpm = self.step_spindle(cmd.spindle_rpm);
        feedback.spindle_state = DriveState::Operational;
        for (i, (d, (sp, fb))) in self
            .drives
            .iter_mut()
            .zip(cmd.positions_mm.iter().zip(feedback.axes.iter_mut()))
            .enumerate()
        {
            d.step(*sp, self.cycle_s);
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
        for (i, d) in self.drives.iter().enumerate() {
            self.raw_mm[i] = d.position_mm();
        }
        feedback.inputs = self.io.read(&self.raw_mm);
        self.io.outputs = cmd.outputs;
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
