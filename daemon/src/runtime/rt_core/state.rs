//! Phase *state machine*: the machine state after each step, once its feedback is in
//! (enabling, running, jog and homing ending at rest, fault, shutdown).

use hal::{BusFault, DriveState};
use kernel::interp::InterpState;
use kernel::units::{AxesMm, TS_NS};

use super::RtCore;

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MachineState {
    /// Drives are being enabled.
    #[default]
    Enabling,
    Idle,
    Running,
    Stopping,
    Hold,
    Fault,
    /// Shutting down: braking, then the thread ends.
    Shutdown,
    /// An axis is jogged (or brakes at the end of a jog).
    Jog,
    /// An axis runs its reference run (homing).
    Homing,
}

/// Where the drives are in their life: enabling after power-on or a reset, shutting down.
pub(super) struct Lifecycle {
    /// Interpolator steps (4 ms) spent enabling.
    pub(super) enable_ticks: u32,
    /// Enabling window in interpolator steps: the bus's deadline plus a margin.
    pub(super) enable_window_ticks: u32,
    /// A `Shutdown` command came: brake, let the drives settle, end the loop.
    pub(super) shutting_down: bool,
    /// Interpolator steps the axes have been at rest while shutting down.
    pub(super) settle_ticks: u32,
}

/// 4 ms interpolator steps in `ms` (the counters below count steps, whatever the bus period).
const fn steps_in_ms(ms: u64) -> u32 {
    (ms * 1_000_000 / TS_NS) as u32
}

/// Time the drives get to become operational beyond the bus's own enable deadline
/// ([`hal::DriveBus::enable_timeout_ticks`]), in interpolator steps (1 s): the bus names the
/// drive that is late, so its alarm must come first.
pub(super) const ENABLE_MARGIN_TICKS: u32 = steps_in_ms(1000);
/// After shutdown braking: interpolator steps to let the drives settle before the thread ends
/// (1 s); also the settle timeout of the fault reaction.
pub(super) const SETTLE_TICKS: u32 = steps_in_ms(1000);
/// Following error under which an axis counts as settled, mm.
pub(super) const SETTLED_MM: f64 = 0.001;

impl RtCore {
    /// The machine state after this tick. `planned_job`: the last job whose planning is
    /// complete; `ring_empty`: no segment waits on the ring.
    pub(super) fn update_state(&mut self, planned_job: u32, ring_empty: bool) {
        let is = self.motion.interp.state();
        if self.lifecycle.shutting_down {
            self.update_shutdown(is);
            return;
        }
        let s = &mut self.snap;
        if s.alarm.fault.is_some() || s.alarm.kr_fault.is_some() {
            s.state = MachineState::Fault;
            return;
        }
        match s.state {
            MachineState::Enabling => self.update_enabling(),
            MachineState::Running | MachineState::Hold | MachineState::Stopping => {
                self.update_running(is, planned_job, ring_empty)
            }
            MachineState::Jog if !self.motion.jog.active() => {
                // The jog ended at rest: the path continues from where the axis is now.
                let here = AxesMm(self.io.cmd.positions_mm);
                if self.motion.interp.set_position(here) {
                    s.state = MachineState::Idle;
                }
            }
            MachineState::Homing if self.motion.homing.is_none() => {
                let here = AxesMm(self.io.cmd.positions_mm);
                if self.motion.interp.set_position(here) {
                    s.state = MachineState::Idle;
                }
            }
            MachineState::Jog
            | MachineState::Homing
            | MachineState::Idle
            | MachineState::Fault
            | MachineState::Shutdown => {}
        }
    }

    /// Shutting down: count the ticks the axes have been at rest (the drives are disabled
    /// once they settled).
    pub(super) fn update_shutdown(&mut self, is: InterpState) {
        let s = &mut self.snap;
        s.state = MachineState::Shutdown;
        if is == InterpState::Idle {
            let settled = (0..self.io.axes)
                .all(|i| (s.axes.commanded[i] - s.axes.actual[i]).abs() < SETTLED_MM);
            self.lifecycle.settle_ticks = if settled {
                SETTLE_TICKS
            } else {
                self.lifecycle.settle_ticks + 1
            };
        }
    }

    /// Enabling: idle once every drive is operational (commanding from where the drives
    /// are), a bus fault when the enable window passes first.
    pub(super) fn update_enabling(&mut self) {
        let s = &mut self.snap;
        // The spindle drive, where there is one, must be ready too: a program's M3
        // would otherwise go to a drive that cannot turn yet.
        let ready = self.io.fb.axes[..self.io.axes]
            .iter()
            .all(|a| a.state == DriveState::Operational)
            && (!self.io.has_spindle || self.io.fb.spindle_state == DriveState::Operational);
        self.lifecycle.enable_ticks += 1;
        if ready {
            // Drives report where they are: command from there (after a fault or at
            // power-on they may be elsewhere than the last setpoint).
            let mut here = s.axes.commanded;
            for i in 0..self.io.axes {
                here[i] = self.io.fb.axes[i].position_mm;
            }
            if self.motion.interp.set_position(here) {
                s.axes.commanded = here;
                self.io.cmd.positions_mm[..self.io.axes].copy_from_slice(&here.0[..self.io.axes]);
                self.io.bus_cmd.positions_mm[..self.io.axes]
                    .copy_from_slice(&here.0[..self.io.axes]);
                // Taken over from the drives: a step on purpose, not smoothed.
                self.io.resampler.reset(here);
            }
            s.state = MachineState::Idle;
        } else if self.lifecycle.enable_ticks > self.lifecycle.enable_window_ticks {
            s.alarm.fault = Some(BusFault {
                axis: None,
                node: None,
                reason: hal::FaultReason::Timeout,
            });
            s.state = MachineState::Fault;
        }
    }

    /// Running, holding or stopping: the job finishes when it is planned, drained and at
    /// rest; otherwise the state follows the interpolator's.
    pub(super) fn update_running(&mut self, is: InterpState, planned_job: u32, ring_empty: bool) {
        let s = &mut self.snap;
        // The bus setpoint must have arrived at the end too (the smoothing of a bus
        // period other than 4 ms lags: `resample`).
        let job_done = self.job.active != 0
            && planned_job == self.job.active
            && ring_empty
            && is == InterpState::Idle
            && self.io.resampler.settled();
        if job_done {
            s.progress.finished_job = self.job.active;
            self.job.active = 0;
        }
        s.state = match is {
            _ if self.job.active == 0 && is == InterpState::Idle => MachineState::Idle,
            // A program's probing move brakes at the contact as a stop does, and goes on.
            InterpState::Stopping if self.motion.program_probe.braking => MachineState::Running,
            InterpState::Stopping => MachineState::Stopping,
            // An automatic tool change runs unless its wait timed out.
            InterpState::Holding | InterpState::Held
                if self.changer.running() && !self.changer.timed_out() =>
            {
                MachineState::Running
            }
            InterpState::Holding | InterpState::Held => MachineState::Hold,
            _ => MachineState::Running,
        };
    }
}
