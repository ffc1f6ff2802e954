//! Phase *commands*: what the non-RT side asks for (from the command ring), taken at the start
//! of each tick, and the requests that start motion by hand (jog).

use hal::DriveBus;
use kernel::interp::InterpState;
use kernel::jog::JogRequest;
use kernel::plc::PlcWrite;
use kernel::units::AxesMm;

use super::{MachineState, RtCore};

/// Commands from the non-RT side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RtCommand {
    /// Run the segments of `job` (arriving on the segment ring).
    Start { job: u32, machine: JobMachine },
    /// Brake to rest on the path, drop the rest of the job.
    Stop,
    /// Feed hold.
    Hold,
    /// Continue after a feed hold.
    Resume,
    /// Feed override in percent (0..150).
    Override(f64),
    /// Spindle override in percent (50..120, issue #19).
    SpindleOverride(f64),
    /// Rapid override in percent (0..100, issue #19).
    RapidOverride(f64),
    /// Clear a fault and re-enable the drives.
    Reset,
    /// Bring the axes to rest and end the thread.
    Shutdown,
    /// A validated write of the PLC side, in force from the next tick (SPEC §6).
    Plc(PlcWrite),
    /// Single-block mode: hold when the path enters a new block (API, issue #8).
    SingleBlock(bool),
    /// Optional stop switch: M1 stops the program while on (issue #15).
    OptionalStop(bool),
    /// Start or renew a jog (idle machine only; issue #15).
    Jog(JogRequest),
    /// Brake a jog to rest.
    JogStop,
    /// Reference run of one axis (idle machine only; issue #15).
    Home(HomeRequest),
    /// A probing move of one axis (idle machine only; docs/setup.md).
    Probe(super::ProbeRequest),
    /// Forces output `output` to a value (`None`: releases it), for commissioning; every
    /// forcing ends with Reset (docs/io.md).
    ForceOutput { output: u8, value: Option<bool> },
}

/// A reference run of one axis: search the home switch, then make its position the reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HomeRequest {
    pub axis: usize,
    /// -1 or +1.
    pub direction: f64,
    pub speed_mm_s: f64,
    pub accel_mm_s2: f64,
    /// The axis's position at the switch once homed.
    pub reference_mm: f64,
    /// Give up (homing failed) after this much travel without the switch.
    pub max_travel_mm: f64,
}

/// What the RT side reads of a job's machine setup (issue #14): taken with the job's start, so
/// KŘR, the spindle and the G24 window use the same constants as the job's planning. `Copy`:
/// no allocation on the RT thread.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JobMachine {
    /// R67, R329 d3, R580 (the gear table is the configuration's).
    pub kr: kernel::kr::KrConstants,
    /// G24 in-position window per axis (R6, R7), mm.
    pub in_position_mm: AxesMm,
}

impl RtCore {
    pub(super) fn commands(
        &mut self,
        commands: &mut rtrb::Consumer<RtCommand>,
        bus: &mut dyn DriveBus,
    ) {
        while let Ok(c) = commands.pop() {
            self.snap.tick.commands_taken += 1;
            match c {
                RtCommand::Start { job, machine } => self.start_job(job, machine),
                RtCommand::Stop => {
                    self.probe_stop();
                    self.motion.jog.stop();
                    self.stop_drive_homing(bus);
                    self.abort();
                }
                RtCommand::Jog(r) => self.jog_request(r),
                RtCommand::JogStop => {
                    self.probe_stop();
                    self.motion.jog.stop();
                }
                RtCommand::Probe(r) => self.probe_request(r),
                RtCommand::Home(r) => self.home_request(r, bus),
                // Only a job is held (the controller's check may have read an older
                // snapshot: the job may have ended since).
                RtCommand::Hold if self.job.active != 0 => self.motion.interp.hold(),
                RtCommand::Hold => {}
                RtCommand::Resume if !self.snap.io.door_open => self.resume_job(),
                RtCommand::Resume => {}
                RtCommand::ForceOutput { output, value } => self.force_output(output, value),
                RtCommand::Override(pct) => {
                    self.motion.interp.set_override(pct);
                    self.snap.operator.feed_override_pct = pct.clamp(0.0, 150.0);
                }
                RtCommand::SpindleOverride(pct) => self.spindle_override(pct),
                RtCommand::RapidOverride(pct) => {
                    self.motion.interp.set_rapid_override(pct);
                    self.snap.operator.rapid_override_pct = pct.clamp(0.0, 100.0);
                }
                // Forcing ends and reached limits are acknowledged; nothing while the e-stop
                // chain is open (docs/io.md).
                RtCommand::Reset if !self.io_reset() => {}
                RtCommand::Reset => self.reset_fault(bus),
                RtCommand::Plc(w) => self.logic.plc.stage(w),
                RtCommand::SingleBlock(on) => {
                    self.snap.operator.single_block = on;
                    self.motion.interp.set_single_block(on);
                }
                RtCommand::OptionalStop(on) => {
                    self.motion.interp.set_optional_stop(on);
                    self.snap.operator.optional_stop = on;
                }
                RtCommand::Shutdown => {
                    self.probe_stop();
                    self.motion.jog.stop();
                    self.stop_drive_homing(bus);
                    self.lifecycle.shutting_down = true;
                    self.abort();
                }
            }
        }
    }

    /// Starts `job` on an idle machine (never with the e-stop chain or the door open, or a
    /// limit switch reached).
    fn start_job(&mut self, job: u32, machine: JobMachine) {
        let io = &self.snap.io;
        let blocked = io.estop_open || io.door_open || self.any_limit();
        if self.snap.state != MachineState::Idle || self.lifecycle.shutting_down || blocked {
            return;
        }
        self.logic.kr.set_constants(machine.kr);
        self.job.in_position_mm = machine.in_position_mm;
        self.job.active = job;
        self.snap.progress.job = job;
        // Until its first segment arrives the job is in no block (not in the last job's).
        self.motion.interp.forget_block();
        self.job.spindle_off = false;
        self.snap.state = MachineState::Running;
    }

    /// Reset of a fault: the drives are enabled again once the path stands (asked for while
    /// the axes still brake, it waits for them: `FaultStop::reset_pending`).
    pub(super) fn reset_fault(&mut self, bus: &mut dyn DriveBus) {
        if self.snap.state != MachineState::Fault {
            return;
        }
        if self.motion.interp.state() != InterpState::Idle {
            // Pressed while the axes still brake from the fault: it takes effect once they
            // are at rest (`fault_reaction`), not lost.
            self.fault_stop.reset_pending = true;
            return;
        }
        self.fault_stop.reset_pending = false;
        self.snap.alarm.fault = None;
        self.snap.alarm.kr_fault = None;
        self.fault_stop.brake.clear();
        self.fault_stop.safe_state_sent = false;
        self.logic.kr.reset();
        bus.reset();
        self.lifecycle.enable_ticks = 0;
        self.snap.state = MachineState::Enabling;
    }

    /// Spindle override: KŘR scales the commanded speed from the next tick, within the gear
    /// range (the per-rev feed follows the actual spindle speed already).
    pub(super) fn spindle_override(&mut self, pct: f64) {
        self.logic.kr.set_override(pct);
        let (lo, hi) = (
            *kernel::kr::SPINDLE_OVERRIDE_PCT.start(),
            *kernel::kr::SPINDLE_OVERRIDE_PCT.end(),
        );
        self.snap.operator.spindle_override_pct = pct.clamp(lo, hi);
    }

    /// A jog starts only on an idle machine (or renews the running jog); its speed is scaled
    /// by the feed override in force.
    pub(super) fn jog_request(&mut self, mut r: JogRequest) {
        let free = matches!(self.snap.state, MachineState::Idle | MachineState::Jog)
            && self.job.active == 0
            && !self.lifecycle.shutting_down
            && r.axis < self.io.axes;
        if !free || self.jog_into_limit(r.axis, self.io.cmd.positions_mm[r.axis], r.target_mm) {
            return;
        }
        r.speed_mm_s *= self.snap.operator.feed_override_pct / 100.0;
        let here = self.io.cmd.positions_mm[r.axis];
        if self.motion.jog.request(r, here) {
            self.snap.state = MachineState::Jog;
        }
    }
}
