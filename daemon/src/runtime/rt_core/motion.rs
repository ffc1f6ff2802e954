//! Phase *segments and interpolation*: one 4 ms step of the kernel: segments from the ring into
//! the interpolator, the path's motion (in-position, spindle ready; single block stops there at
//! the block ends), KŘR and the spindle, and the axes' setpoint (path, jog or fault brake)
//! handed to the resampler.

use kernel::block::SpindleDir;
use kernel::interp::{InterpState, Interpolator, TickOut};
use kernel::jog::Jog;
use kernel::kr::{ControllingAxis, Kr, KrInput, Motion, ProgramSpindle};
use kernel::plan::Segment;
use kernel::plc::PlcArea;
use kernel::units::AxesMm;

use super::RtCore;
use super::homing::HomingRun;

/// What commands the axes: the path's interpolator, a jog or a reference run.
pub(super) struct MotionSources {
    pub(super) interp: Interpolator,
    /// The interpolator's output of its last step.
    pub(super) out: TickOut,
    /// Jogging one axis by hand.
    pub(super) jog: Jog,
    /// Reference run under way.
    pub(super) homing: Option<HomingRun>,
    /// Probing move under way (it moves the axis with `jog`).
    pub(super) probe: super::probe::ProbeRun,
    /// A program's probing move braking at its change.
    pub(super) program_probe: super::program_probe::ProgramProbeRun,
}

/// The job the core runs and what it took with its start.
pub(super) struct JobRun {
    /// Job whose segments are accepted (0: none).
    pub(super) active: u32,
    /// G24 in-position window per axis (R6, R7), mm.
    pub(super) in_position_mm: AxesMm,
    /// A stop ended the job: the spindle stops once the axes are at rest (until the next
    /// start).
    pub(super) spindle_off: bool,
}

/// Constant cutting speed and the PLC cells it reads and writes (SPEC §6).
pub(super) struct MachineLogic {
    pub(super) kr: Kr,
    pub(super) plc: PlcArea,
}

/// The spindle counts as at speed within this share of its setpoint (or `SPINDLE_AT_SPEED_RPM`).
const SPINDLE_AT_SPEED_SHARE: f64 = 0.05;
const SPINDLE_AT_SPEED_RPM: f64 = 2.0;

/// Whether the actual spindle speed is close enough to the setpoint (same sign) for a cut.
pub(super) fn spindle_at_speed(set_rpm: f64, actual_rpm: f64) -> bool {
    (set_rpm - actual_rpm).abs()
        <= (SPINDLE_AT_SPEED_SHARE * set_rpm.abs()).max(SPINDLE_AT_SPEED_RPM)
}

/// Below this actual spindle speed feed per revolution holds (SPEC §5: V = n·β; a spindle
/// stalled by load must not be fed into), rpm. Above it the feed follows the speed in proportion.
const SPINDLE_HOLD_RPM: f64 = 1.0;

/// The spindle speed feed per revolution follows: the drive's actual speed, or 0 (hold) when
/// it is below [`SPINDLE_HOLD_RPM`] or turns against its setpoint.
pub(super) fn spindle_feed_rpm(set_rpm: f64, actual_rpm: f64) -> f64 {
    if actual_rpm.abs() < SPINDLE_HOLD_RPM || set_rpm * actual_rpm < 0.0 {
        0.0
    } else {
        actual_rpm.abs()
    }
}

impl RtCore {
    /// One 4 ms step of the kernel: segments, interpolator (single block stops it at the
    /// block ends), KŘR, and the axes' setpoint (path, jog or fault brake) handed to the
    /// resampler.
    pub(super) fn interpolator_step(&mut self, segments: &mut rtrb::Consumer<Segment>) {
        self.feed_segments(segments);
        self.program_probe_step();
        self.input_waits();
        let out = self.interpolate();
        self.tool_changer_step();
        self.spindle(&out);
        self.setpoint(&out);
        self.motion.out = out;
    }

    pub(super) fn feed_segments(&mut self, segments: &mut rtrb::Consumer<Segment>) {
        while self.motion.interp.has_room() {
            match segments.pop() {
                Ok(seg) if seg.job == self.job.active && self.job.active != 0 => {
                    // Cannot fail: room was checked and we are not stopping this job.
                    let _ = self.motion.interp.push(seg);
                }
                Ok(_) => {} // a stopped job's leftovers
                Err(_) => break,
            }
        }
    }

    /// The interpolator's setpoint of this tick. G24 waits at a stop until every axis has caught
    /// up with its setpoint (SPEC §7.1); a cut starts from rest only with the spindle at the
    /// speed commanded last tick.
    pub(super) fn interpolate(&mut self) -> TickOut {
        let in_position = (0..self.io.axes).all(|i| {
            (self.snap.axes.commanded[i] - self.snap.axes.actual[i]).abs()
                <= self.job.in_position_mm[i]
        });
        self.motion.interp.set_in_position(in_position);
        self.motion.interp.set_spindle_ready(
            !self.io.has_spindle
                || spindle_at_speed(self.io.cmd.spindle_rpm, self.io.fb.spindle_rpm),
        );
        // Feed per revolution follows the speed the drive reported last tick; without a
        // spindle drive there is no feedback and the planned (nominal) feed runs.
        self.motion
            .interp
            .set_spindle_feed_rpm(if self.io.has_spindle {
                spindle_feed_rpm(self.io.cmd.spindle_rpm, self.io.fb.spindle_rpm)
            } else {
                f64::INFINITY
            });
        self.motion.interp.tick()
    }

    /// Constant cutting speed and the spindle setpoint (SPEC §6): computed from the spindle
    /// state of the block being executed and the commanded position of the controlling axis.
    pub(super) fn spindle(&mut self, out: &TickOut) {
        let motion = if out.path_v_mm_s <= 0.0 {
            Motion::Stationary
        } else if out.rapid {
            Motion::Rapid
        } else {
            Motion::Feed
        };
        let axis = self.logic.kr.config().controlling_axis;
        // After a stop the spindle stops once the axes are at rest; on a fault at once.
        // An open door stops it too (docs/io.md).
        let off = self.snap.alarm.fault.is_some()
            || self.snap.io.door_open
            || (self.job.spindle_off && self.motion.interp.state() == InterpState::Idle);
        let input = KrInput {
            program: ProgramSpindle {
                dir: if off {
                    SpindleDir::Stopped
                } else {
                    out.spindle.dir
                },
                css: out.spindle.css,
                s_word: out.spindle.s,
                limit_rpm: out.spindle.limit_rpm,
                gear: out.spindle.gear,
            },
            motion,
            // The carriage and the offsets in force: KŘR computes at the tool tip, or at the
            // carriage with EXT_AKRR_SUPORT (SPEC §6).
            axis: ControllingAxis::of(out.position[axis], &out.spindle),
        };
        let k = self.logic.kr.tick(&input, &mut self.logic.plc);
        self.io.cmd.spindle_rpm = k.spindle_rpm;
        self.snap.spindle.kr = k;
        if let Some(f) = k.fault
            && self.snap.alarm.kr_fault.is_none()
        {
            self.snap.alarm.kr_fault = Some(f);
            self.abort();
        }
    }

    /// The axes' 4 ms setpoint of this step: the path, a jog, or the fault brake.
    pub(super) fn setpoint(&mut self, out: &TickOut) {
        let axes = self.io.axes;
        self.fault_stop.prev_setpoint = AxesMm(self.io.cmd.positions_mm);
        // After a fault the brake, not the path, commands the axes.
        let setpoint = if self.fault_stop.brake.active() {
            self.fault_stop.brake.tick()
        } else if self.motion.jog.active() {
            let mut p = out.position;
            p[self.motion.jog.axis()] = self.motion.jog.tick();
            p
        } else {
            out.position
        };
        self.io.cmd.positions_mm[..axes].copy_from_slice(&setpoint.0[..axes]);
        self.io.resampler.push(AxesMm(self.io.cmd.positions_mm));
    }
}
