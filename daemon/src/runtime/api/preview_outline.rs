//! `Preview.GetPreviewOutline`: the selected program's outline reduced to what a screen shows
//! (issue #30: the browser HMI draws a program of any size). The outline comes from the pass
//! that validated the selection (`programs::prepare`), so it is the program a start runs; a
//! zoom finer than it, or a machine setup changed since, gets a pass of its own (clipped to
//! the extent), made on a blocking thread like every validation pass (never the RT thread).

use std::sync::Arc;

use proto::v1 as pb;
use tonic::Status;

use ::preview::collect::Bounds;
use ::preview::outline::{Clip, Outline, Plane, Runs, View};
use kernel::pipeline::Options;

use super::{ApiState, invalid_with_diagnostics};
use crate::runtime::rt::MachineState;

/// Picture size when the request gives none.
const DEFAULT_PX: (u32, u32) = (1200, 800);

/// The outline recorded by the selection's pass, while it is the next start's (same check
/// as the recorded preview pass: constants, offsets and start position unchanged). While a
/// program runs it is the one shown: a pass now would start from wherever the tool is.
fn recorded_outline(st: &ApiState) -> Option<Arc<Outline>> {
    let program = st.ctl.program()?;
    let snap = st.ctl.snapshot();
    let running = matches!(
        snap.state,
        MachineState::Running | MachineState::Hold | MachineState::Stopping
    );
    if !running && !st.ctl.validated_as_now(&program, &snap) {
        return None;
    }
    let info = st.job.plan_info.lock().unwrap();
    let info = info.as_ref()?;
    (info.program == Arc::as_ptr(&program) as *const () as usize).then(|| info.outline.clone())
}

/// A pass over the selected program with the setup in force, into an outline (clipped to
/// `clip` from grid `cell_mm` when given).
fn own_pass(st: &ApiState, clip: Option<Clip>, cell_mm: f64) -> Result<Outline, Status> {
    let text = super::selected_text(&st.ctl)?;
    let mut o = Outline::clipped(&st.ctl.config().axis_names(), clip, cell_mm);
    let (v, _, _) = st
        .ctl
        .validate_program_with(&text, Options::default(), &mut o)
        .map_err(super::status_of)?;
    if v.has_errors() {
        return Err(invalid_with_diagnostics("program", &v.diagnostics));
    }
    o.freeze();
    Ok(o)
}

fn runs_pb(r: Runs) -> pb::Polylines {
    pb::Polylines {
        xy_mm: r.xy,
        starts: r.starts,
    }
}

/// The reply of `GetPreviewOutline`. Blocking (may make a pass).
pub fn outline_reply(
    st: &ApiState,
    r: &pb::PreviewOutlineRequest,
) -> Result<pb::PreviewOutline, Status> {
    let plane_name = if r.plane.is_empty() { "xy" } else { &r.plane };
    let plane = Plane::parse(plane_name).ok_or_else(|| {
        Status::invalid_argument(format!(
            "plane {:?}: use two of x, y, z, horizontal first (xy, xz, yz, zx ...)",
            r.plane
        ))
    })?;
    let extent = (r.max_h_mm > r.min_h_mm && r.max_v_mm > r.min_v_mm).then_some(Bounds {
        min: [r.min_h_mm, r.min_v_mm],
        max: [r.max_h_mm, r.max_v_mm],
    });
    let w = if r.width_px == 0 {
        DEFAULT_PX.0
    } else {
        r.width_px.clamp(50, 8000)
    };
    let h = if r.height_px == 0 {
        DEFAULT_PX.1
    } else {
        r.height_px.clamp(50, 8000)
    };
    let program = st
        .ctl
        .program()
        .ok_or_else(|| Status::failed_precondition("no program is selected"))?;
    let (outline, mut own) = match recorded_outline(st) {
        Some(o) => (o, false),
        None => (
            Arc::new(own_pass(st, None, ::preview::outline::START_CELL_MM)?),
            true,
        ),
    };
    let mut view = outline.view(plane, extent, w, h);
    // Zoomed in finer than the outline's grid: a pass of its own over the extent.
    if let Some(e) = extent {
        let px_mm =
            ((e.max[0] - e.min[0]) / f64::from(w)).max((e.max[1] - e.min[1]) / f64::from(h));
        if px_mm < outline.cell_mm() / 2.0 {
            let fine = own_pass(st, Some(Clip { plane, extent: e }), px_mm)?;
            let bounds = view.bounds;
            view = View {
                bounds,
                ..fine.view(plane, extent, w, h)
            };
            own = true;
        }
    }
    Ok(reply(&program.name, &outline, view, own))
}

fn reply(name: &str, o: &Outline, v: View, own_pass: bool) -> pb::PreviewOutline {
    let b = v.bounds.unwrap_or(Bounds {
        min: [0.0; 2],
        max: [0.0; 2],
    });
    pb::PreviewOutline {
        program: name.to_owned(),
        blocks: o.blocks,
        feed: Some(runs_pb(v.feed)),
        rapid: Some(runs_pb(v.rapid)),
        compensated: Some(runs_pb(v.comp)),
        smooth_xy_mm: v.smooth,
        red_xy_mm: v.red,
        smooth_junctions: o.smooth,
        red_junctions: o.red,
        min_h_mm: b.min[0],
        min_v_mm: b.min[1],
        max_h_mm: b.max[0],
        max_v_mm: b.max[1],
        cell_mm: v.cell_mm,
        own_pass,
    }
}
