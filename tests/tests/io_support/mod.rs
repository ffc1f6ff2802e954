//! The simulated machine recording what each bus cycle sent (outputs and X), for the tests of
//! the machine's I/O in the single-threaded harness.
#![allow(dead_code)]

use std::sync::{Arc, Mutex};

use hal::{BusFault, CycleCommand, CycleFeedback, DriveBus};

/// Outputs word and X setpoint of each cycle, in order.
pub type Sent = Arc<Mutex<Vec<(u64, f64)>>>;

/// The simulated machine, recording what each cycle sent: outputs and X.
pub struct OutputsBus {
    pub inner: sim::SimBus,
    pub sent: Sent,
}

impl DriveBus for OutputsBus {
    fn name(&self) -> &str {
        "sim"
    }
    fn axes(&self) -> usize {
        self.inner.axes()
    }
    fn has_spindle(&self) -> bool {
        true
    }
    fn cycle(&mut self, cmd: &CycleCommand, fb: &mut CycleFeedback) -> Result<(), BusFault> {
        self.sent
            .lock()
            .unwrap()
            .push((cmd.outputs.0, cmd.positions_mm[0]));
        self.inner.cycle(cmd, fb)
    }
    fn enable(&mut self) {
        self.inner.enable()
    }
    fn reset(&mut self) {
        self.inner.reset()
    }
    fn safe_state(&mut self) {
        self.inner.safe_state()
    }
}
