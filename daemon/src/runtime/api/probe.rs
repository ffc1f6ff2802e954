//! `Machine.Probe` and `Offsets.ProbeWorkflow` (docs/setup.md, "Probing"): a probing move,
//! and the tool-setter, edge and bore workflows whose results are written into an entry of
//! TAB0.KOR the way touch-off writes (a value read at a machine position found by probing).

use std::sync::Arc;

use proto::v1 as pb;
use tonic::{Code, Status};

use super::ApiState;
use super::diagnostics::refused;
use super::touch_off;
use crate::runtime::controller::{ProbeError, ProbeMove};
use crate::runtime::homing;

/// The gRPC status of a probing error, with its code.
pub(super) fn status_of_probe(e: ProbeError) -> Status {
    let code = match e {
        ProbeError::Invalid(_) => Code::InvalidArgument,
        ProbeError::NoContact { .. } | ProbeError::Aborted(_) => Code::Aborted,
        _ => Code::FailedPrecondition,
    };
    refused(code, e.code(), e.to_string())
}

fn invalid(msg: String) -> Status {
    status_of_probe(ProbeError::Invalid(msg))
}

/// One probing move.
pub(super) async fn probe(st: &ApiState, r: pb::ProbeRequest) -> Result<pb::ProbeReply, Status> {
    let config = st.ctl.config();
    let axis = homing::axis_index(config, &r.axis).map_err(|e| invalid(e.to_string()))?;
    let feed_mm_min = if r.feed_mm_min == 0.0 {
        config.probe().search_feed_mm_min
    } else {
        r.feed_mm_min
    };
    let m = ProbeMove {
        axis,
        distance_mm: r.distance_mm,
        feed_mm_min,
        toward: !r.away,
    };
    let p = st.ctl.probe(m).await.map_err(status_of_probe)?;
    Ok(pb::ProbeReply {
        machine_mm: p.0[..config.axes.len()].to_vec(),
    })
}

/// What a workflow writes: axis letter, the machine position found, the value it reads.
struct Found {
    axis: char,
    machine_mm: f64,
    value_mm: f64,
}

/// Runs the workflow, then writes what it found into the entry.
pub(super) async fn workflow(
    st: Arc<ApiState>,
    r: pb::ProbeWorkflowRequest,
) -> Result<pb::ProbeWorkflowReply, Status> {
    // The entry and the work offset are checked before anything moves.
    let touch = |axis: char, value_mm: f64| pb::TouchOffRequest {
        entry: r.entry,
        axis: axis.to_string(),
        value_mm,
        radius_mm: None,
        work_offset: r.work_offset.clone(),
    };
    touch_off::request(&st, &touch('X', 0.0))?;
    st.ctl.probe_ready().map_err(status_of_probe)?;
    let mut reply = pb::ProbeWorkflowReply::default();
    let found = match pb::ProbeWorkflowKind::try_from(r.kind) {
        Ok(pb::ProbeWorkflowKind::ToolSetter) => tool_setter(&st, &r).await?,
        Ok(pb::ProbeWorkflowKind::Edge) => edge(&st, &r).await?,
        Ok(pb::ProbeWorkflowKind::Bore) => {
            let c = st.ctl.probe_bore().await.map_err(status_of_probe)?;
            reply.diameter_mm = c.diameter_mm;
            vec![
                Found {
                    axis: 'X',
                    machine_mm: c.x_mm,
                    value_mm: r.value_mm.unwrap_or(0.0),
                },
                Found {
                    axis: 'Y',
                    machine_mm: c.y_mm,
                    value_mm: r.value2_mm.unwrap_or(0.0),
                },
            ]
        }
        _ => return Err(invalid(format!("unknown probing workflow {}", r.kind))),
    };
    for f in found {
        let t = touch_off::request(&st, &touch(f.axis, f.value_mm))?;
        let length_mm = touch_off::write(&st, &t, f.machine_mm, None).await?;
        reply.written.push(pb::ProbeWritten {
            axis: f.axis.to_string(),
            machine_mm: f.machine_mm,
            length_mm,
        });
    }
    reply.entry = Some(touch_off::entry_now(&st, r.entry as u8));
    Ok(reply)
}

async fn tool_setter(st: &ApiState, r: &pb::ProbeWorkflowRequest) -> Result<Vec<Found>, Status> {
    let setter_z = st.ctl.config().probe().setter.map_or(0.0, |s| s.z_mm);
    let z = st.ctl.probe_tool_setter().await.map_err(status_of_probe)?;
    Ok(vec![Found {
        axis: 'Z',
        machine_mm: z,
        value_mm: r.value_mm.unwrap_or(setter_z),
    }])
}

async fn edge(st: &ApiState, r: &pb::ProbeWorkflowRequest) -> Result<Vec<Found>, Status> {
    let config = st.ctl.config();
    let axis = homing::axis_index(config, &r.axis).map_err(|e| invalid(e.to_string()))?;
    if r.direction != 1 && r.direction != -1 {
        return Err(invalid(format!(
            "an edge is touched in direction +1 or -1, not {}",
            r.direction
        )));
    }
    let edge_mm = st
        .ctl
        .probe_edge(axis, f64::from(r.direction))
        .await
        .map_err(status_of_probe)?;
    Ok(vec![Found {
        axis: config.axes[axis].name,
        machine_mm: edge_mm,
        value_mm: r.value_mm.unwrap_or(0.0),
    }])
}
