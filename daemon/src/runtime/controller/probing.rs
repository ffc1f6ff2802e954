//! Probing (docs/setup.md, "Probing"): single probing moves, and the workflows a machinist
//! sets a job up with — a tool's length on the tool setter, an edge, a bore's centre. Each
//! is a sequence of commands to the RT core (probing moves and positioning steps of one axis,
//! one after the other), checked here first; the positions they find are machine
//! coordinates, which the API turns into offset table writes (touch-off's path).
//!
//! A touch is two probing moves: fast at `[probe] search_feed_mm_min` to find the surface,
//! back off, slow at `latch_feed_mm_min` for the position taken, back off again.

use kernel::units::AxesMm;

use super::Controller;
use crate::runtime::rt::{MachineState, ProbeOutcome, ProbeRequest, RtCommand, Snapshot};

/// Why probing failed or was refused; each has its stable code ([`ProbeError::code`]).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ProbeError {
    #[error("probing needs an idle machine; it is {0:?}")]
    Busy(MachineState),
    #[error("probing needs the axes homed: home {0} first (cncctl home)")]
    NotHomed(char),
    #[error("this machine has no probe input (an input with function = \"probe\", docs/io.md)")]
    Unavailable,
    #[error("{0}")]
    Invalid(String),
    #[error("the probe did not {what} within {distance_mm} mm of {axis}")]
    NoContact {
        axis: char,
        distance_mm: f64,
        what: &'static str,
    },
    #[error("the probe already {0} where the move starts")]
    AlreadyTriggered(&'static str),
    #[error("probing stopped before it ended ({0})")]
    Aborted(String),
}

impl ProbeError {
    pub fn code(&self) -> kernel::DiagCode {
        use kernel::DiagCode as D;
        match self {
            ProbeError::Busy(_) => D::ProbeBusy,
            ProbeError::NotHomed(_) => D::ProbeNotHomed,
            ProbeError::Unavailable => D::ProbeUnavailable,
            ProbeError::Invalid(_) => D::ProbeInvalid,
            ProbeError::NoContact { .. } => D::ProbeNoContact,
            ProbeError::AlreadyTriggered(_) => D::ProbeAlreadyTriggered,
            ProbeError::Aborted(_) => D::ProbeAborted,
        }
    }
}

/// A probing move of one axis, relative to where it stands.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbeMove {
    pub axis: usize,
    /// Signed: the direction and how far at most, mm.
    pub distance_mm: f64,
    pub feed_mm_min: f64,
    /// Toward a contact (G38.2), or away until the probe releases (G38.4).
    pub toward: bool,
}

/// What the bore workflow found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoreCentre {
    pub x_mm: f64,
    pub y_mm: f64,
    /// Across Y once X stands on the centre (across X is a chord when the start was off
    /// the centre in Y), with the ball's diameter added.
    pub diameter_mm: f64,
}

impl Controller {
    fn probe_axis(&self, letter: char) -> Result<usize, ProbeError> {
        self.config
            .axes
            .iter()
            .position(|a| a.name == letter)
            .ok_or_else(|| ProbeError::Invalid(format!("this machine has no {letter} axis")))
    }

    /// Refused when `target_mm` of `axis` lies beyond its soft limits: neither a probing
    /// move nor a workflow's positioning goes where a jog may not.
    fn probe_within_travel(&self, axis: usize, target_mm: f64) -> Result<(), ProbeError> {
        let a = &self.config.axes[axis];
        let below = a.soft_min_mm.is_some_and(|lo| target_mm < lo - 1e-9);
        let above = a.soft_max_mm.is_some_and(|hi| target_mm > hi + 1e-9);
        if below || above {
            return Err(ProbeError::Invalid(format!(
                "{} would go to {target_mm:.3} mm, beyond its soft limits",
                a.name
            )));
        }
        Ok(())
    }

    /// Refused unless there is a probe, the machine is idle and every axis homed.
    pub fn probe_ready(&self) -> Result<(), ProbeError> {
        if !self
            .config
            .io()
            .inputs
            .iter()
            .any(|i| i.function == crate::runtime::config::InputFunction::Probe)
        {
            return Err(ProbeError::Unavailable);
        }
        let snap = self.snapshot();
        if snap.state != MachineState::Idle {
            return Err(ProbeError::Busy(snap.state));
        }
        match (0..self.config.axes.len()).find(|&i| !self.axis_homed(&snap, i)) {
            Some(i) => Err(ProbeError::NotHomed(self.config.axes[i].name)),
            None => Ok(()),
        }
    }

    /// One probing move; the axes' actual positions at the contact.
    pub async fn probe(&self, m: ProbeMove) -> Result<AxesMm, ProbeError> {
        let a = self
            .config
            .axes
            .get(m.axis)
            .ok_or_else(|| ProbeError::Invalid(format!("axis {} does not exist", m.axis)))?;
        let usable = |v: f64| v.is_finite() && v != 0.0;
        if !(usable(m.distance_mm) && usable(m.feed_mm_min) && m.feed_mm_min > 0.0) {
            return Err(ProbeError::Invalid(format!(
                "a probing move needs a distance and a positive feed (got {} mm at {} mm/min)",
                m.distance_mm, m.feed_mm_min
            )));
        }
        self.probe_ready()?;
        let here = self.snapshot().axes.commanded[m.axis];
        // As a jog step: the move looks no further than the soft limit.
        let target_mm = a.step_within_soft_limits(here, here + m.distance_mm);
        if (target_mm - here).abs() < 1e-6 {
            return Err(ProbeError::Invalid(format!(
                "{} stands at its soft limit in that direction",
                a.name
            )));
        }
        let r = ProbeRequest {
            axis: m.axis,
            target_mm,
            speed_mm_s: m.feed_mm_min.min(a.max_velocity_mm_min) / 60.0,
            accel_mm_s2: a.max_accel_mm_s2,
            toward: m.toward,
        };
        let s = self.until_at_rest(RtCommand::Probe(r)).await?;
        let what = if m.toward { "touch" } else { "release" };
        match s.probe.outcome {
            ProbeOutcome::Contact => Ok(s.probe.position),
            ProbeOutcome::NoContact => Err(ProbeError::NoContact {
                axis: a.name,
                distance_mm: m.distance_mm,
                what,
            }),
            ProbeOutcome::AlreadyTriggered => Err(ProbeError::AlreadyTriggered(if m.toward {
                "touches"
            } else {
                "is clear"
            })),
            ProbeOutcome::Refused => Err(ProbeError::Busy(s.state)),
            o => Err(ProbeError::Aborted(format!("{o:?}, machine {:?}", s.state))),
        }
    }

    /// Sends `cmd` and waits until the core has taken it and no jog or probing move runs.
    async fn until_at_rest(&self, cmd: RtCommand) -> Result<Snapshot, ProbeError> {
        let gone = || ProbeError::Aborted("the real-time thread is not running".into());
        let sent = self.rt.send_counted(cmd).map_err(|_| gone())?;
        let mut rx = self.rt.subscribe();
        loop {
            let s = *rx.borrow_and_update();
            if s.tick.commands_taken >= sent
                && s.probe.outcome != ProbeOutcome::Moving
                && s.state != MachineState::Jog
            {
                return Ok(s);
            }
            rx.changed().await.map_err(|_| gone())?;
        }
    }

    /// Moves one axis to `target_mm` (machine coordinates) at its highest speed, as G0 would
    /// (a machinist's probing cycle moves so between touches), as a jog step; fails when it
    /// did not arrive (Stop, a fault, a limit).
    async fn probe_position(&self, axis: usize, target_mm: f64) -> Result<(), ProbeError> {
        self.probe_within_travel(axis, target_mm)?;
        let a = &self.config.axes[axis];
        let r = kernel::jog::JogRequest {
            axis,
            target_mm,
            speed_mm_s: a.max_velocity_mm_min / 60.0,
            accel_mm_s2: a.max_accel_mm_s2,
            lease_ticks: u32::MAX,
        };
        let s = self.until_at_rest(RtCommand::Jog(r)).await?;
        if s.state != MachineState::Idle || (s.axes.commanded[axis] - target_mm).abs() > 1e-6 {
            return Err(ProbeError::Aborted(format!(
                "{} did not reach {target_mm:.3} mm (machine {:?})",
                a.name, s.state
            )));
        }
        Ok(())
    }

    /// A touch along `axis` in direction `dir` (sign): fast, back off, slow, back off. The
    /// positions of the slow touch.
    pub async fn probe_touch(
        &self,
        axis: usize,
        dir: f64,
        travel_mm: f64,
    ) -> Result<AxesMm, ProbeError> {
        let p = self.config.probe();
        let fast = ProbeMove {
            axis,
            distance_mm: dir * travel_mm,
            feed_mm_min: p.search_feed_mm_min,
            toward: true,
        };
        let first = self.probe(fast).await?;
        let clear = first[axis] - dir * p.backoff_mm;
        self.probe_position(axis, clear).await?;
        let slow = ProbeMove {
            distance_mm: dir * 2.0 * p.backoff_mm,
            feed_mm_min: p.latch_feed_mm_min,
            ..fast
        };
        let second = self.probe(slow).await?;
        self.probe_position(axis, second[axis] - dir * p.backoff_mm)
            .await?;
        Ok(second)
    }

    /// The tool setter: Z up to the clearance, X and Y over the setter, touch down, Z up
    /// again. The carriage's Z at the contact (the tool's length is this less the setter's
    /// `z_mm`).
    pub async fn probe_tool_setter(&self) -> Result<f64, ProbeError> {
        let p = self.config.probe();
        let s = p.setter.ok_or_else(|| {
            ProbeError::Invalid(
                "no tool setter is configured ([probe.setter], docs/setup.md)".into(),
            )
        })?;
        let (x, y, z) = (
            self.probe_axis('X')?,
            self.probe_axis('Y')?,
            self.probe_axis('Z')?,
        );
        self.probe_ready()?;
        self.probe_position(z, s.clearance_z_mm).await?;
        self.probe_position(x, s.x_mm).await?;
        self.probe_position(y, s.y_mm).await?;
        // A tool of length 0 touches at z_mm: never further down than a back-off below it.
        let travel = s.clearance_z_mm - s.z_mm + p.backoff_mm;
        let contact = self.probe_touch(z, -1.0, travel).await?;
        self.probe_position(z, s.clearance_z_mm).await?;
        Ok(contact[z])
    }

    /// An edge along `axis` in direction `dir`: where the ball's surface met it (the centre's
    /// position plus a ball radius toward the edge).
    pub async fn probe_edge(&self, axis: usize, dir: f64) -> Result<f64, ProbeError> {
        let p = self.config.probe();
        let contact = self.probe_touch(axis, dir, p.max_travel_mm).await?;
        Ok(contact[axis] + dir * p.ball_radius_mm)
    }

    /// A bore's centre from inside it: X both ways, to the centre, Y both ways, to the
    /// centre. The ball's radius cancels out of the centre.
    pub async fn probe_bore(&self) -> Result<BoreCentre, ProbeError> {
        let p = self.config.probe();
        let (x, y) = (self.probe_axis('X')?, self.probe_axis('Y')?);
        let mut across = [0.0; 2];
        let mut centre = [0.0; 2];
        for (k, axis) in [x, y].into_iter().enumerate() {
            let start = self.snapshot().axes.commanded[axis];
            let plus = self.probe_touch(axis, 1.0, p.max_travel_mm).await?[axis];
            self.probe_position(axis, start).await?;
            let minus = self.probe_touch(axis, -1.0, p.max_travel_mm).await?[axis];
            centre[k] = 0.5 * (plus + minus);
            across[k] = plus - minus + 2.0 * p.ball_radius_mm;
            self.probe_position(axis, centre[k]).await?;
        }
        Ok(BoreCentre {
            x_mm: centre[0],
            y_mm: centre[1],
            diameter_mm: across[1],
        })
    }
}
