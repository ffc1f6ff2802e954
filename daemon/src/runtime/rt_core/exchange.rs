//! Phase *bus exchange*: the resampled setpoint out, feedback in; and the drives' switch-off
//! walk when the loop has ended.

use hal::{CycleCommand, CycleFeedback, DriveBus};

use super::super::resample::Resampler;
use super::RtCore;

/// What goes to and comes from the bus.
pub(super) struct BusIo {
    /// Axes on the bus (machine order).
    pub(super) axes: usize,
    /// The interpolator's (4 ms) setpoints and spindle speed.
    pub(super) cmd: CycleCommand,
    /// What the bus gets this bus tick: `cmd` resampled at the bus tick's time.
    pub(super) bus_cmd: CycleCommand,
    pub(super) fb: CycleFeedback,
    /// The bus setpoint from the last interpolator setpoints.
    pub(super) resampler: Resampler,
    /// The bus has a spindle drive (asked once at start-up).
    pub(super) has_spindle: bool,
}

impl RtCore {
    /// After the loop has ended ([`RtCore::finished`]): the bus switches its drives off in
    /// order (CANopen: disable step by step, heartbeat watch cleared, NMT pre-operational),
    /// still on the tick grid, holding the last setpoints. `sleep_until_ns` waits for a
    /// deadline. Bounded by the bus's own step timeouts.
    pub fn shut_down_bus(&mut self, bus: &mut dyn DriveBus, mut sleep_until_ns: impl FnMut(u64)) {
        let mut deadline = self.timing.deadline_ns;
        let cycle_ns = self.timing.bus_clock.cycle_ns();
        hal::shut_down(bus, &self.io.bus_cmd, &mut self.io.fb, || {
            sleep_until_ns(deadline);
            deadline += cycle_ns;
        });
        self.timing.deadline_ns = deadline;
    }

    /// Setpoints out (resampled at the bus tick's time), feedback in; a bus fault stops the
    /// machine.
    pub(super) fn exchange(&mut self, bus: &mut dyn DriveBus) {
        let axes = self.io.axes;
        self.io.bus_cmd.spindle_rpm = self.io.cmd.spindle_rpm;
        self.io.resampler.sample(
            axes,
            self.timing.bus_clock.phase(),
            &mut self.io.bus_cmd.positions_mm,
        );
        let result = bus.cycle(&self.io.bus_cmd, &mut self.io.fb);
        for i in 0..axes {
            self.snap.axes.actual[i] = self.io.fb.axes[i].position_mm;
        }
        if let Err(fault) = result {
            self.fault(fault);
        }
    }
}
