//! The jog RPCs of `cnc.v1.Machine` (the service calls these after its role check): the
//! streamed continuous jog, the leased continuous jog of the browser (`JogLease`, `JogStop`)
//! and the step jog. One motion source at a time (issue #31): a jog is refused while another
//! jog, a program or a reference run moves the machine.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

use proto::v1 as pb;
use tonic::Status;

use super::{ApiState, refused, status_of};
use crate::runtime::homing;
use crate::runtime::rt::MachineState;

/// Jog lease of `JogLease` when the request gives none, and its bounds, ms (cnc.proto).
const DEFAULT_LEASE_MS: u32 = 500;
const MIN_LEASE_MS: u32 = 100;
const MAX_LEASE_MS: u32 = 1000;

/// The continuous jogs the API started, each holding the jog while it runs.
#[derive(Default)]
pub(super) struct JogSources {
    /// A continuous jog stream (`Machine.Jog`) holds the jog.
    stream: AtomicBool,
    /// The continuous jog `Machine.JogLease` runs, if any.
    leased: Mutex<Option<LeasedJog>>,
}

/// Releases the continuous jog when its stream ends, however it ends.
struct JogHeld<'a>(&'a AtomicBool);

impl Drop for JogHeld<'_> {
    fn drop(&mut self) {
        self.0.store(false, Ordering::Release);
    }
}

/// `Machine.Jog`: the streamed continuous jog; returns the last target, mm.
pub(super) async fn streamed(
    st: &ApiState,
    mut stream: tonic::Streaming<pb::JogRequest>,
) -> Result<f64, Status> {
    let ctl = &st.ctl;
    // One motion source at a time: this stream holds the jog until it ends; another
    // stream, a running step, a program or a reference run refuses it.
    let state = ctl.snapshot().state;
    if state != MachineState::Idle || st.jog.stream.swap(true, Ordering::AcqRel) {
        return Err(refused(
            tonic::Code::FailedPrecondition,
            kernel::DiagCode::JogBusy,
            format!("the machine is busy ({state:?}, or another jog): one motion at a time"),
        ));
    }
    let _held = JogHeld(&st.jog.stream);
    let mut target = 0.0;
    // Every message renews the jog; the end of the stream (or its failure: the client
    // went away) stops it. A silent client is stopped by the RT thread's lease.
    let result = loop {
        match stream.message().await {
            Ok(Some(m)) => match ctl.jog(&m.axis, m.direction, m.speed_mm_min) {
                Ok(t) => target = t,
                Err(e) => break Err(status_of(e)),
            },
            Ok(None) => break Ok(()),
            Err(e) => break Err(e),
        }
    };
    let _ = ctl.jog_stop();
    result.map(|()| target)
}

/// `Machine.JogStop`: ends the leased jog (and brakes any jog).
pub(super) fn stop(st: &ApiState) -> Result<(), Status> {
    let mut held = st.jog.leased.lock().unwrap();
    *held = None;
    // Only a jog is braked: the jog generator also moves a reference run (homing).
    if st.ctl.snapshot().state == MachineState::Jog {
        st.ctl.jog_stop().map_err(status_of)?;
    }
    Ok(())
}

/// `Machine.JogStep`: one step of `step_mm`; returns its target, mm.
pub(super) fn step(st: &ApiState, r: pb::JogStepRequest) -> Result<f64, Status> {
    let state = st.ctl.snapshot().state;
    if state != MachineState::Idle || st.jog.stream.load(Ordering::Acquire) {
        return Err(refused(
            tonic::Code::FailedPrecondition,
            kernel::DiagCode::JogBusy,
            format!("the machine is busy ({state:?}, or a jog): one motion at a time"),
        ));
    }
    st.ctl.jog_step_check(&r.axis, r.step_mm).map_err(|m| {
        refused(
            tonic::Code::InvalidArgument,
            kernel::DiagCode::JogBeyondTravel,
            m.to_string(),
        )
    })?;
    st.ctl
        .jog_step(&r.axis, r.step_mm, r.speed_mm_min)
        .map_err(status_of)
}

/// The continuous jog `JogLease` started: which axis (index) in which direction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct LeasedJog {
    axis: usize,
    dir: i32,
}

/// A lease of `lease_ms` (0: [`DEFAULT_LEASE_MS`]) within 100..1000 ms.
fn lease_of(lease_ms: u32) -> Result<u32, Status> {
    match lease_ms {
        0 => Ok(DEFAULT_LEASE_MS),
        ms if (MIN_LEASE_MS..=MAX_LEASE_MS).contains(&ms) => Ok(ms),
        ms => Err(Status::invalid_argument(format!(
            "jog lease {ms} ms is outside {MIN_LEASE_MS}..{MAX_LEASE_MS} ms (0 means \
             {DEFAULT_LEASE_MS})"
        ))),
    }
}

/// `Machine.JogLease`: starts or renews the leased continuous jog (the browser's dead-man):
/// the same checks as the streamed `Jog`; another axis or direction while a jog runs is
/// refused, not merged. Returns the target, mm.
pub(super) fn lease(st: &ApiState, r: pb::JogLeaseRequest) -> Result<f64, Status> {
    let lease_ms = lease_of(r.lease_ms)?;
    if r.direction != 1 && r.direction != -1 {
        return Err(Status::invalid_argument(format!(
            "jog direction {} must be +1 or -1",
            r.direction
        )));
    }
    let axis = homing::axis_index(st.ctl.config(), &r.axis).map_err(status_of)?;
    let want = LeasedJog {
        axis,
        dir: r.direction,
    };
    let names = st.ctl.config().axis_names();
    let mut held = st.jog.leased.lock().unwrap();
    if st.ctl.snapshot().state == MachineState::Jog && *held != Some(want) {
        let running = match *held {
            Some(h) => format!(
                "a jog of {}{} runs",
                names[h.axis],
                if h.dir > 0 { '+' } else { '-' }
            ),
            None => "another jog runs (a step or a streamed jog)".into(),
        };
        return Err(Status::failed_precondition(format!(
            "{running}: stop it (JogStop, or let it end) before jogging {}{}",
            names[axis],
            if r.direction > 0 { '+' } else { '-' }
        )));
    }
    let target = st
        .ctl
        .jog_leased(&r.axis, r.direction, r.speed_mm_min, lease_ms)
        .map_err(status_of)?;
    *held = Some(want);
    Ok(target)
}
