//! Fault injection for the deployment tests (`tests/systemd-vm/`), never for a machine: each
//! knob is an environment variable that the unit does not set, so it needs a deliberate
//! drop-in (`systemctl edit cncd`). Documented in deploy/README.md ("Fault injection").
//!
//! - `CNCD_FAULT_STALL_RT_AFTER_TICKS=N`: after `N` bus cycles the real-time thread blocks
//!   inside the bus cycle for good, as a wedged bus driver would. The watchdog pings stop and
//!   systemd aborts and restarts cncd (`WatchdogSec=`).

use std::time::Duration;

use hal::{BusFault, CycleCommand, CycleFeedback, DriveBus};

/// The environment variable of the stall knob.
pub const STALL_RT_AFTER_TICKS: &str = "CNCD_FAULT_STALL_RT_AFTER_TICKS";

/// A fault-injection knob with a value that cannot be used.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FaultKnobError {
    #[error("{STALL_RT_AFTER_TICKS}: {value:?} is not a number of ticks (fault injection)")]
    StallTicks { value: String },
}

impl FaultKnobError {
    /// Stable code (tests and logs match it; the message may improve).
    pub fn code(&self) -> &'static str {
        match self {
            FaultKnobError::StallTicks { .. } => "fault_stall_ticks",
        }
    }
}

/// The stall knob's value: `None` when unset, an error naming the variable when it is not a
/// number of ticks.
pub fn stall_after_ticks(value: Option<&str>) -> Result<Option<u64>, FaultKnobError> {
    value
        .map(|v| {
            v.trim()
                .parse()
                .map_err(|_| FaultKnobError::StallTicks { value: v.into() })
        })
        .transpose()
}

/// `bus`, wrapped so that the real-time thread stalls after `ticks` cycles.
pub struct StallAfter {
    inner: Box<dyn DriveBus>,
    left: u64,
}

impl StallAfter {
    pub fn new(inner: Box<dyn DriveBus>, ticks: u64) -> StallAfter {
        StallAfter { inner, left: ticks }
    }
}

impl DriveBus for StallAfter {
    crate::delegate_drive_bus!(inner: name, axes, has_spindle, enable, reset);
    fn cycle(&mut self, cmd: &CycleCommand, feedback: &mut CycleFeedback) -> Result<(), BusFault> {
        if self.left == 0 {
            tracing::error!(
                "fault injection: the real-time thread stalls now ({STALL_RT_AFTER_TICKS})"
            );
            loop {
                std::thread::sleep(Duration::from_secs(3600));
            }
        }
        self.left -= 1;
        self.inner.cycle(cmd, feedback)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stall_knob_is_off_unless_set_to_a_number() {
        assert_eq!(stall_after_ticks(None), Ok(None));
        assert_eq!(stall_after_ticks(Some("250")), Ok(Some(250)));
        let e = stall_after_ticks(Some("soon")).unwrap_err();
        assert_eq!(e.code(), "fault_stall_ticks", "{e}");
    }

    #[test]
    fn cycles_pass_through_until_the_stall() {
        let bus = sim::SimBus::new(Default::default(), &[0.0, 0.0, 0.0]);
        let mut b = StallAfter::new(Box::new(bus), 3);
        let cmd = CycleCommand::default();
        let mut fb = CycleFeedback::default();
        for _ in 0..3 {
            b.cycle(&cmd, &mut fb).unwrap();
        }
        assert_eq!(b.left, 0);
        assert_eq!(b.axes(), 3);
    }
}
