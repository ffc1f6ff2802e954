//! Probing moves inside the tick (docs/setup.md, "Probing"): one axis moves like a jog step
//! toward a target while the tick watches the probe input; the tick that sees the probe change
//! takes the axes' actual positions (the drives' feedback of the same exchange) and brakes
//! the move to rest at the axis's acceleration. The move ends with the contact, or without
//! one at its target, or aborted by Stop or a fault.

use kernel::jog::JogRequest;
use kernel::units::AxesMm;

use super::{MachineState, RtCore};

/// A probing move of one axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbeRequest {
    pub axis: usize,
    /// Where the move ends at the latest, machine coordinates, mm.
    pub target_mm: f64,
    pub speed_mm_s: f64,
    pub accel_mm_s2: f64,
    /// Probing toward a contact (the probe reads 1 on it: G38.2) or away from one (0 on
    /// release: G38.4).
    pub toward: bool,
}

/// How the last probing move ended.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum ProbeOutcome {
    /// None asked since start-up.
    #[default]
    None,
    /// Under way.
    Moving,
    /// The probe changed at `ProbeStatus::position`.
    Contact,
    /// The move reached its target with no change.
    NoContact,
    /// The probe already read what the move looks for: nothing moved.
    AlreadyTriggered,
    /// Refused: the machine was not idle, no probe input, an unknown axis.
    Refused,
    /// Stopped (Stop, a fault, the e-stop) before it ended.
    Aborted,
}

/// The probing move as the snapshot shows it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ProbeStatus {
    pub outcome: ProbeOutcome,
    /// The axes' actual positions in the tick the probe changed, mm.
    pub position: AxesMm,
    /// The probe touches now (its input, in its function's sense).
    pub touching: bool,
}

/// A probing move under way.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct ProbeRun {
    pub(super) active: bool,
    toward: bool,
    contact: bool,
    stopped: bool,
}

impl RtCore {
    pub(super) fn probe_touching(&self) -> bool {
        let mask = self.io_logic.f.probe;
        mask != 0 && self.io_logic.last & mask != 0
    }

    /// Starts a probing move: only on an idle machine with a probe input, and only when the
    /// probe does not already read what the move looks for.
    pub(super) fn probe_request(&mut self, r: ProbeRequest) {
        self.snap.probe.outcome = self.probe_start(r);
    }

    fn probe_start(&mut self, r: ProbeRequest) -> ProbeOutcome {
        let free = self.snap.state == MachineState::Idle
            && self.job.active == 0
            && !self.lifecycle.shutting_down
            && self.io_logic.f.probe != 0
            && r.axis < self.io.axes;
        if !free {
            return ProbeOutcome::Refused;
        }
        if self.probe_touching() == r.toward {
            return ProbeOutcome::AlreadyTriggered;
        }
        let here = self.io.cmd.positions_mm[r.axis];
        let jog = JogRequest {
            axis: r.axis,
            target_mm: r.target_mm,
            speed_mm_s: r.speed_mm_s,
            accel_mm_s2: r.accel_mm_s2,
            lease_ticks: u32::MAX,
        };
        if self.jog_into_limit(r.axis, here, r.target_mm) || !self.motion.jog.request(jog, here) {
            return ProbeOutcome::Refused;
        }
        self.snap.state = MachineState::Jog;
        self.motion.probe = ProbeRun {
            active: true,
            toward: r.toward,
            contact: false,
            stopped: false,
        };
        ProbeOutcome::Moving
    }

    /// Stop during a probing move: it ends aborted once at rest.
    pub(super) fn probe_stop(&mut self) {
        if self.motion.probe.active {
            self.motion.probe.stopped = true;
        }
    }

    /// The probing move after this step's feedback: at the probe's change the actual
    /// positions are taken and the axis brakes; at rest the move ends.
    pub(super) fn probe_step(&mut self) {
        let touching = self.probe_touching();
        self.snap.probe.touching = touching;
        let mut run = self.motion.probe;
        if !run.active {
            return;
        }
        if !run.contact && !run.stopped && touching == run.toward {
            run.contact = true;
            let mut p = self.snap.probe.position;
            for (i, a) in self.io.fb.axes[..self.io.axes].iter().enumerate() {
                p[i] = a.position_mm;
            }
            self.snap.probe.position = p;
            self.motion.jog.stop();
        }
        let faulted = self.snap.alarm.fault.is_some() || self.fault_stop.brake.active();
        if faulted {
            run.stopped = true;
        }
        if !self.motion.jog.active() || faulted {
            self.snap.probe.outcome = match (run.contact, run.stopped) {
                (true, _) => ProbeOutcome::Contact,
                (false, true) => ProbeOutcome::Aborted,
                (false, false) => ProbeOutcome::NoContact,
            };
            run.active = false;
        }
        self.motion.probe = run;
    }
}
