//! Motion outside programs and the operator's switches: reference runs (homing), jogging
//! (continuous with its dead-man lease, and by steps), the overrides, single block, optional
//! stop, and the fault reset. Each is a command to the RT core, checked here first.

use std::sync::Arc;

use kernel::jog::{Jog, JogRequest};

use super::ControlError;
use super::rt_link::RtLink;
use crate::runtime::config::Config;
use crate::runtime::homing;
use crate::runtime::rt::{MachineState, RtCommand, Snapshot};

/// A continuous jog stops by itself unless renewed within this many ticks (0.5 s): the
/// dead-man of a client that goes away without a word (the API renews it every 100 ms).
pub const JOG_LEASE_TICKS: u32 = 125;

/// The longest jog step on an axis without soft limits, mm (degrees on a rotary axis): no
/// machine of this family travels further (issue #31).
pub const MAX_JOG_STEP_MM: f64 = 10_000.0;

pub(super) struct Motion {
    config: Arc<Config>,
    /// The bus can run reference runs (homing).
    can_home: bool,
}

impl Motion {
    pub(super) fn new(config: Arc<Config>, can_home: bool) -> Motion {
        Motion { config, can_home }
    }

    /// Whether axis `i` is referenced: homed since power-on, or needing no reference run.
    pub(super) fn axis_homed(&self, snap: &Snapshot, i: usize) -> bool {
        homing::axis_homed(&self.config, snap, i)
    }

    /// Reference run of `axes` (all when empty), one axis after the other in the configured
    /// order. Returns the letters homed.
    pub(super) async fn home(&self, rt: &RtLink, axes: &str) -> Result<String, ControlError> {
        if !self.can_home {
            return Err(ControlError::WrongState(
                "this bus cannot run a reference run (serial: it needs an axis with \
                 homing = \"required\", which switches the link to protocol version 3)"
                    .into(),
            ));
        }
        let order = homing::homing_order(&self.config, axes)?;
        let mut done = String::new();
        for i in order {
            self.home_axis(rt, i).await?;
            done.push(self.config.axes[i].name);
        }
        Ok(done)
    }

    async fn home_axis(&self, rt: &RtLink, i: usize) -> Result<(), ControlError> {
        let snap = rt.snapshot();
        if snap.state != MachineState::Idle {
            return Err(ControlError::WrongState(format!(
                "homing needs an idle machine; it is {:?}",
                snap.state
            )));
        }
        let sent = rt.send_counted(RtCommand::Home(homing::home_request(&self.config, i)))?;
        let mut rx = rt.subscribe();
        let bit = 1u8 << i;
        loop {
            let s = *rx.borrow_and_update();
            if s.tick.commands_taken >= sent && s.state != MachineState::Homing {
                if s.axes.homed & bit != 0 {
                    return Ok(());
                }
                return Err(homing::failure(&self.config, &s, i));
            }
            rx.changed().await.map_err(|_| ControlError::RtGone)?;
        }
    }

    /// Axis index of letter `axis`, or INVALID_ARGUMENT.
    fn axis_index(&self, axis: &str) -> Result<usize, ControlError> {
        homing::axis_index(&self.config, axis)
    }

    /// Jog speed in mm/s: the asked speed within the axis's maximum; 0 asks for 10 % of it.
    fn jog_speed(&self, axis: usize, speed_mm_min: f64) -> Result<f64, ControlError> {
        let max = self.config.axes[axis].max_velocity_mm_min;
        if !speed_mm_min.is_finite() || speed_mm_min < 0.0 {
            return Err(ControlError::Invalid(format!(
                "jog speed {speed_mm_min} mm/min must be positive"
            )));
        }
        let v = if speed_mm_min == 0.0 {
            0.1 * max
        } else {
            speed_mm_min.min(max)
        };
        Ok(v / 60.0)
    }

    /// Starts or renews a continuous jog of `axis` in direction `dir` (sign) at `speed_mm_min`.
    /// The real-time thread stops it by itself unless renewed within [`JOG_LEASE_TICKS`]
    /// (the dead-man). Returns the target: the soft limit in that direction.
    pub(super) fn jog(
        &self,
        rt: &RtLink,
        axis: &str,
        dir: i32,
        speed_mm_min: f64,
    ) -> Result<f64, ControlError> {
        self.jog_with_lease(rt, axis, dir, speed_mm_min, JOG_LEASE_TICKS)
    }

    /// A continuous jog as [`Motion::jog`] whose lease is `lease_ms` (the browser's
    /// dead-man, `Machine.JogLease`): the axis brakes to rest unless renewed within it.
    pub(super) fn jog_leased(
        &self,
        rt: &RtLink,
        axis: &str,
        dir: i32,
        speed_mm_min: f64,
        lease_ms: u32,
    ) -> Result<f64, ControlError> {
        // The jog generator ticks on the interpolator's grid (TS_S), whatever the bus cycle.
        let ticks = (f64::from(lease_ms) / 1000.0 / kernel::units::TS_S).ceil() as u32;
        self.jog_with_lease(rt, axis, dir, speed_mm_min, ticks.max(1))
    }

    fn jog_with_lease(
        &self,
        rt: &RtLink,
        axis: &str,
        dir: i32,
        speed_mm_min: f64,
        lease_ticks: u32,
    ) -> Result<f64, ControlError> {
        let i = self.axis_index(axis)?;
        if dir == 0 {
            return Err(ControlError::Invalid(
                "jog direction must be +1 or -1".into(),
            ));
        }
        let speed = self.jog_speed(i, speed_mm_min)?;
        let snap = rt.snapshot();
        if !self.axis_homed(&snap, i) {
            return Err(ControlError::WrongState(format!(
                "axis {} is not homed: its soft limits mean nothing yet, so it jogs only by \
                 steps until homed (cncctl home {})",
                self.config.axes[i].name, self.config.axes[i].name
            )));
        }
        if !matches!(snap.state, MachineState::Idle | MachineState::Jog) {
            return Err(ControlError::WrongState(format!(
                "jogging needs an idle machine; it is {:?}",
                snap.state
            )));
        }
        if let Some(why) = self.jog_toward_reached_limit(&snap, i, f64::from(dir)) {
            return Err(ControlError::WrongState(why.to_string()));
        }
        let a = &self.config.axes[i];
        let (lo, hi) = (
            a.soft_min_mm.unwrap_or(f64::NEG_INFINITY),
            a.soft_max_mm.unwrap_or(f64::INFINITY),
        );
        let target =
            Jog::continuous_target(snap.axes.commanded[i], f64::from(dir.signum()), lo, hi);
        rt.send(RtCommand::Jog(JogRequest {
            axis: i,
            target_mm: target,
            speed_mm_s: speed,
            accel_mm_s2: a.max_accel_mm_s2,
            lease_ticks,
        }))?;
        Ok(if dir > 0 { hi } else { lo })
    }

    /// Why a jog of axis `i` in direction `dir` would move into a hardware limit switch that
    /// is still reached (docs/io.md: only a jog away from it moves).
    fn jog_toward_reached_limit(&self, snap: &Snapshot, i: usize, dir: f64) -> Option<JogRefusal> {
        let f = crate::runtime::io_setup::functions(&self.config);
        let reached = snap.io.limits.0;
        let axis = self.config.axes[i].name;
        if dir > 0.0 && reached & f.limit_pos[i] != 0 {
            Some(JogRefusal::OnLimitSwitch {
                axis,
                positive: true,
            })
        } else if dir < 0.0 && reached & f.limit_neg[i] != 0 {
            Some(JogRefusal::OnLimitSwitch {
                axis,
                positive: false,
            })
        } else {
            None
        }
    }

    /// Whether a jog step of `step_mm` on `axis` may run (issue #31): refused before motion
    /// when it would end beyond a soft limit (an axis standing beyond one may step back
    /// inside), or, on an axis without limits, when it is longer than [`MAX_JOG_STEP_MM`].
    pub(super) fn jog_step_check(
        &self,
        rt: &RtLink,
        axis: &str,
        step_mm: f64,
    ) -> Result<(), JogRefusal> {
        let Ok(i) = self.axis_index(axis) else {
            return Ok(()); // jog_step names the axis error
        };
        if let Some(why) = self.jog_toward_reached_limit(&rt.snapshot(), i, step_mm) {
            return Err(why);
        }
        let a = &self.config.axes[i];
        let target = rt.snapshot().axes.commanded[i] + step_mm;
        let beyond = |limit: Option<f64>, upper: bool| match limit {
            Some(l) if upper => target > l + 1e-9 && step_mm > 0.0,
            Some(l) => target < l - 1e-9 && step_mm < 0.0,
            None => false,
        };
        if beyond(a.soft_max_mm, true) || beyond(a.soft_min_mm, false) {
            return Err(JogRefusal::BeyondSoftLimits {
                axis: a.name,
                step_mm,
                target_mm: target,
                soft_mm: (a.soft_min_mm, a.soft_max_mm),
            });
        }
        if step_mm.abs() > MAX_JOG_STEP_MM {
            return Err(JogRefusal::LongerThanTravel {
                axis: a.name,
                step_mm,
            });
        }
        Ok(())
    }

    /// Incremental jog: `step_mm` on `axis`, clamped to the soft limits. Returns the target.
    pub(super) fn jog_step(
        &self,
        rt: &RtLink,
        axis: &str,
        step_mm: f64,
        speed_mm_min: f64,
    ) -> Result<f64, ControlError> {
        let i = self.axis_index(axis)?;
        if !step_mm.is_finite() || step_mm == 0.0 {
            return Err(ControlError::Invalid(format!("jog step {step_mm} mm")));
        }
        let speed = self.jog_speed(i, speed_mm_min)?;
        let snap = rt.snapshot();
        if snap.state != MachineState::Idle {
            return Err(ControlError::WrongState(format!(
                "a jog step needs an idle machine; it is {:?}",
                snap.state
            )));
        }
        let a = &self.config.axes[i];
        let here = snap.axes.commanded[i];
        let target = a.step_within_soft_limits(here, here + step_mm);
        rt.send(RtCommand::Jog(JogRequest {
            axis: i,
            target_mm: target,
            speed_mm_s: speed,
            accel_mm_s2: a.max_accel_mm_s2,
            lease_ticks: u32::MAX,
        }))?;
        Ok(target)
    }

    /// Brakes a jog to rest (the client let go, or went away).
    pub(super) fn jog_stop(&self, rt: &RtLink) -> Result<(), ControlError> {
        rt.send(RtCommand::JogStop)
    }

    /// Optional stop switch: M1 stops the program only while it is on.
    pub(super) fn set_optional_stop(&self, rt: &RtLink, on: bool) -> Result<(), ControlError> {
        rt.send(RtCommand::OptionalStop(on))
    }

    pub(super) fn set_override(&self, rt: &RtLink, percent: f64) -> Result<(), ControlError> {
        if !(0.0..=150.0).contains(&percent) {
            return Err(ControlError::WrongState(format!(
                "feed override {percent} % is outside 0..150 %"
            )));
        }
        rt.send(RtCommand::Override(percent))
    }

    /// Spindle override, 50..120 % (issue #19): the RT core scales the commanded spindle
    /// speed within the gear range from the next tick.
    pub(super) fn set_spindle_override(
        &self,
        rt: &RtLink,
        percent: f64,
    ) -> Result<(), ControlError> {
        let range = kernel::kr::SPINDLE_OVERRIDE_PCT;
        if !range.contains(&percent) {
            return Err(ControlError::Invalid(format!(
                "spindle override {percent} % is outside {}..{} %",
                range.start(),
                range.end()
            )));
        }
        rt.send(RtCommand::SpindleOverride(percent))
    }

    /// Rapid override, 0..100 % (issue #19): G0 moves run at this share of their speed.
    pub(super) fn set_rapid_override(&self, rt: &RtLink, percent: f64) -> Result<(), ControlError> {
        if !(0.0..=100.0).contains(&percent) {
            return Err(ControlError::Invalid(format!(
                "rapid override {percent} % is outside 0..100 %"
            )));
        }
        rt.send(RtCommand::RapidOverride(percent))
    }

    /// Clears a fault and re-enables the drives.
    pub(super) fn reset(&self, rt: &RtLink) -> Result<(), ControlError> {
        let snap = rt.snapshot();
        if snap.io.estop_open && !crate::runtime::rt_core::bus_fault(&snap) {
            return Err(ControlError::WrongState(
                "the emergency-stop chain is open: close it (release the button), then Reset"
                    .into(),
            ));
        }
        // Reset also ends the forcing of outputs (docs/io.md).
        if snap.state != MachineState::Fault && snap.io.forced.0 != 0 {
            return rt.send(RtCommand::Reset);
        }
        if snap.state != MachineState::Fault {
            return Err(ControlError::WrongState(
                "there is no fault to reset".into(),
            ));
        }
        rt.send(RtCommand::Reset)
    }

    /// Single-block mode on the RT thread: hold when the path enters a new block.
    pub(super) fn set_single_block(&self, rt: &RtLink, on: bool) -> Result<(), ControlError> {
        rt.send(RtCommand::SingleBlock(on))
    }
}

/// Why a jog may not run (`Motion::jog_step_check`, and a continuous jog onto a reached
/// limit switch).
#[derive(Clone, Debug, PartialEq)]
pub enum JogRefusal {
    /// The axis stands on its limit switch of that side: only a jog away from it moves.
    OnLimitSwitch { axis: char, positive: bool },
    /// The step would end beyond the soft limits (min, max).
    BeyondSoftLimits {
        axis: char,
        step_mm: f64,
        target_mm: f64,
        soft_mm: (Option<f64>, Option<f64>),
    },
    /// A step on an axis without soft limits longer than any travel (`MAX_JOG_STEP_MM`).
    LongerThanTravel { axis: char, step_mm: f64 },
}

impl std::fmt::Display for JogRefusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            JogRefusal::OnLimitSwitch { axis, positive } => {
                let (side, away) = if positive {
                    ("positive", '-')
                } else {
                    ("negative", '+')
                };
                write!(
                    f,
                    "axis {axis} stands on its {side} limit switch: only a jog away from it \
                     ({axis}{away}) moves"
                )
            }
            JogRefusal::BeyondSoftLimits {
                axis,
                step_mm,
                target_mm,
                soft_mm: (lo, hi),
            } => write!(
                f,
                "a step of {step_mm} mm on {axis} would end at {target_mm:.3}, beyond its soft \
                 limits {lo:?}..{hi:?}"
            ),
            JogRefusal::LongerThanTravel { axis, step_mm } => write!(
                f,
                "a step of {step_mm} mm on {axis} is longer than any travel ({MAX_JOG_STEP_MM} mm)"
            ),
        }
    }
}
