//! `Offsets.TouchOff` (issue #47, docs/setup.md): an entry's length of one axis set so that
//! where the axis stands reads a given value in program coordinates; written through the
//! same path as every operator edit of TAB0.KOR (file and memory, a hand edit never lost).

use proto::v1 as pb;
use tonic::{Code, Status};

use kernel::DiagCode;
use kernel::offsets::touch_off::{self, TouchOff};
use kernel::offsets::{ENTRIES, WorkOffsets};

use super::diagnostics::refused;
use super::{ApiState, blocking, status_of};
use crate::runtime::homing;
use crate::runtime::rt::MachineState;

fn invalid(msg: String) -> Status {
    refused(Code::InvalidArgument, DiagCode::TouchOffInvalid, msg)
}

/// What the request asks for, checked against the machine (nothing is read from the axes).
pub(super) fn request(st: &ApiState, r: &pb::TouchOffRequest) -> Result<TouchOff, Status> {
    let entry = u8::try_from(r.entry)
        .ok()
        .filter(|n| (1..=ENTRIES).contains(n))
        .ok_or_else(|| {
            invalid(format!(
                "offset entry {} does not exist: entries are 01..99",
                r.entry
            ))
        })?;
    let config = st.ctl.config();
    let axis = homing::axis_index(config, &r.axis).map_err(|e| invalid(e.to_string()))?;
    let work_mm = if r.work_offset.trim().is_empty() {
        0.0
    } else {
        let k = WorkOffsets::index_of(&r.work_offset).ok_or_else(|| {
            invalid(format!(
                "work offset system {:?} does not exist: G54 .. G59, G59.1 .. G59.3",
                r.work_offset
            ))
        })?;
        st.ctl.work_offsets().get(k, axis)
    };
    Ok(TouchOff {
        entry,
        axis,
        value_mm: r.value_mm,
        work_mm,
        diameter: st.ctl.diameter_axis() == Some(axis),
    })
}

/// Refused unless the machine is idle and the axis homed.
fn ready(st: &ApiState, axis: usize) -> Result<f64, Status> {
    let snap = st.ctl.snapshot();
    if snap.state != MachineState::Idle {
        return Err(refused(
            Code::FailedPrecondition,
            DiagCode::TouchOffBusy,
            format!(
                "touch-off needs an idle machine; it is {:?}: stop the program or the motion first",
                snap.state
            ),
        ));
    }
    if !st.ctl.axis_homed(&snap, axis) {
        return Err(refused(
            Code::FailedPrecondition,
            DiagCode::TouchOffNotHomed,
            format!(
                "touch-off needs the axis homed: home {} first (cncctl home)",
                st.ctl.config().axes[axis].name
            ),
        ));
    }
    Ok(snap.axes.commanded[axis])
}

/// Checks, computes and writes the touch-off; replies with the entry as it is now.
pub(super) async fn touch_off(
    st: std::sync::Arc<ApiState>,
    r: pb::TouchOffRequest,
) -> Result<pb::TouchOffReply, Status> {
    let t = request(&st, &r)?;
    let machine_mm = ready(&st, t.axis)?;
    let length_mm = write(&st, &t, machine_mm, r.radius_mm).await?;
    Ok(pb::TouchOffReply {
        entry: Some(entry_now(&st, t.entry)),
        length_mm,
        machine_mm,
    })
}

/// Writes the length that makes `machine_mm` read `t.value_mm` (and a radius, if any) as
/// every table edit is written; the length written.
pub(super) async fn write(
    st: &std::sync::Arc<ApiState>,
    t: &TouchOff,
    machine_mm: f64,
    radius_mm: Option<f64>,
) -> Result<f64, Status> {
    let edit = touch_off::edit_for(t, machine_mm, radius_mm).map_err(|e| invalid(e.to_string()))?;
    let length_mm = edit.values[t.axis + 1].unwrap_or_default();
    let ctl = st.clone();
    blocking(move || ctl.ctl.edit_offset(&edit))
        .await?
        .map_err(status_of)?;
    Ok(length_mm)
}

/// Entry `entry` as it is in memory now.
pub(super) fn entry_now(st: &ApiState, entry: u8) -> pb::OffsetEntry {
    let memory = st.ctl.offsets_memory();
    let e = memory.entry(entry).copied().unwrap_or_default();
    pb::OffsetEntry {
        entry: entry.into(),
        radius_mm: e.radius_mm,
        length_mm: e.length_mm.to_vec(),
        changed_by_program: false,
    }
}
