//! Probing moves of a program (G38.2..G38.5, CNC836 G31; docs/language.md, "Probing") in the
//! tick. The planner hands the probing segment over last and waits; while the interpolator
//! runs it, every step watches the probe input of the last exchange. At the change the axes'
//! actual positions of that exchange are taken and the path brakes at its stop deceleration
//! and is dropped; without a change the segment runs to its end. Once the axes rest the
//! result is published (`Snapshot::program_probe`) and the planner goes on from where they
//! stand. A probe that already reads what the move looks for, or a machine without a probe
//! input, stops it before it moves.

use kernel::interp::InterpState;
use kernel::units::AxesMm;

use super::{ProbeOutcome, RtCore};

/// The probing move of a program as the snapshot shows it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ProgramProbe {
    /// The job and the block (`seq`) of the probing move.
    pub job: u32,
    pub seq: u32,
    /// `Moving` while it runs; then `Contact`, `NoContact`, `AlreadyTriggered` or `Refused`
    /// (the machine has no probe input: nothing moved).
    pub outcome: ProbeOutcome,
    /// The axes' actual positions in the tick the probe changed (the move's end without a
    /// change), mm.
    pub trip_mm: AxesMm,
    /// The move has ended and the axes rest at `stop_mm` (commanded), where the path goes on.
    pub done: bool,
    pub stop_mm: AxesMm,
}

/// Whether the watched probing move has started braking at a change.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct ProgramProbeRun {
    pub(super) braking: bool,
}

impl RtCore {
    /// One interpolator step's watch of a program's probing move, before the step: arms at
    /// the probing segment, brakes at the change, publishes the result once at rest.
    pub(super) fn program_probe_step(&mut self) {
        let job = self.job.active;
        if job == 0 {
            self.motion.program_probe.braking = false;
            return;
        }
        let touching = self.probe_touching();
        let seg = self.motion.interp.probing_segment().copied();
        let mut p = self.snap.program_probe;
        if let Some(seg) = seg
            && let Some(mv) = seg.probe
        {
            if p.job != job || p.seq != seg.seq {
                p = ProgramProbe {
                    job,
                    seq: seg.seq,
                    outcome: ProbeOutcome::Moving,
                    trip_mm: seg.path.end(),
                    ..ProgramProbe::default()
                };
                if self.io_logic.f.probe == 0 {
                    p.outcome = ProbeOutcome::Refused;
                    self.program_probe_brake();
                } else if touching == mv.toward {
                    p.outcome = ProbeOutcome::AlreadyTriggered;
                    self.program_probe_brake();
                }
            } else if p.outcome == ProbeOutcome::Moving && touching == mv.toward {
                p.outcome = ProbeOutcome::Contact;
                for (i, a) in self.io.fb.axes[..self.io.axes].iter().enumerate() {
                    p.trip_mm[i] = a.position_mm;
                }
                self.program_probe_brake();
            }
        }
        let at_rest = self.motion.interp.state() == InterpState::Idle;
        if p.job == job && !p.done && at_rest && p.outcome != ProbeOutcome::None {
            if p.outcome == ProbeOutcome::Moving {
                p.outcome = ProbeOutcome::NoContact;
            }
            p.done = true;
            p.stop_mm = self.motion.out.position;
            self.motion.program_probe.braking = false;
        }
        self.snap.program_probe = p;
    }

    fn program_probe_brake(&mut self) {
        self.motion.interp.stop();
        self.motion.program_probe.braking = true;
    }
}
