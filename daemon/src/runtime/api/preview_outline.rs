//! `Preview.GetPreviewOutline`: the selected program's outline reduced to what a screen shows
//! (issue #30: the browser HMI draws a program of any size). The outline comes from the pass
//! that validated the selection (`programs::prepare`), made again beside the load with its
//! setup ([`SelectionOutline`]), so it is the program a start runs.
//! While a job runs it is the job's: the pass the job validated with when it made one (a
//! setup changed since the selection, a restart, single block). A machine setup changed since
//! the selection gets a pass of its own, kept for the next request with the same program and
//! setup; a zoom finer than the outline gets a pass clipped to the extent (never while a job
//! runs: that pass would start from wherever the tool is). Passes run on a blocking thread
//! like every validation pass, the selection's on a thread of its own (never the RT thread).

use std::sync::{Arc, Condvar, Mutex, Weak};

use proto::v1 as pb;
use tonic::Status;

use ::preview::collect::Bounds;
use ::preview::outline::{Clip, Outline, Plane, Runs, START_CELL_MM, View};
use kernel::block::Block;
use kernel::comp::CompBlock;
use kernel::machine::MachineSetup;
use kernel::pipeline::{Flow, Observer, Options};
use kernel::plan::Segment;
use kernel::program::Modal;

use super::{ApiState, invalid_with_diagnostics};
use crate::runtime::controller::{LoadedProgram, SetupStamp};
use crate::runtime::library::ProgramText;
use crate::runtime::rt::MachineState;

/// Picture size when the request gives none.
const DEFAULT_PX: (u32, u32) = (1200, 800);

/// The outlines kept besides the selection's (in [`ApiState`]'s job view).
#[derive(Default)]
pub(super) struct Outlines {
    /// The selected program's pass with a setup changed since its selection. Locked while
    /// that pass runs, so a second request waits for it instead of making the same pass.
    setup: Mutex<Option<SetupOutline>>,
    /// The running job's.
    job: Mutex<Option<JobOutline>>,
}

/// A pass of its own over a program with the setup of `stamp`.
struct SetupOutline {
    program: Weak<LoadedProgram>,
    stamp: SetupStamp,
    outline: Arc<Outline>,
}

/// What job `job` runs: its own validation pass (`None`: the selection's pass was the job's).
struct JobOutline {
    job: u32,
    outline: Option<Arc<Outline>>,
}

/// A job was started from the selected program; `pass` is the outline of its own validation
/// pass if it made one (`Controller::start_program_observed`).
pub(super) fn job_started(st: &ApiState, job: u32, pass: Option<Outline>) {
    let outline = pass.map(|mut o| {
        o.freeze();
        Arc::new(o)
    });
    *st.job.outlines.job.lock().unwrap() = Some(JobOutline { job, outline });
}

/// The selection's outline, if `program` is the selection it belongs to: waits for its pass
/// (`SelectionOutline`) when that has not ended yet.
fn selection_outline(
    st: &ApiState,
    program: &Arc<LoadedProgram>,
) -> Result<Option<Arc<Outline>>, Status> {
    let slot = {
        let info = st.job.plan_info.lock().unwrap();
        match info.as_ref() {
            Some(i) if i.program == Arc::as_ptr(program) as *const () as usize => i.outline.clone(),
            _ => return Ok(None),
        }
    };
    slot.wait().map(Some)
}

/// The outline of a selected program, from a pass of its own made beside the load with the
/// setup the load validated with: the same pass, so the outline is the selection's, and a
/// load does not wait for it (the outline of a million blocks takes about as long again as
/// their validation, issue #49). A request for it waits until it is there.
pub(super) struct SelectionOutline {
    outline: Mutex<Option<Result<Arc<Outline>, String>>>,
    done: Condvar,
}

impl SelectionOutline {
    /// Starts the pass over `text` with `setup` on a thread of its own (at a lower priority
    /// than the API's threads: a start right after the load comes first). The pass ends early
    /// when the outline is no longer wanted (another program selected).
    pub(super) fn start(text: ProgramText, setup: MachineSetup) -> Arc<SelectionOutline> {
        let slot = Arc::new(SelectionOutline {
            outline: Mutex::new(None),
            done: Condvar::new(),
        });
        let wanted = Arc::downgrade(&slot);
        let pass = move || {
            let mut o = Outline::new(&setup.program().axis_names);
            let mut pass = WhileWanted {
                outline: &mut o,
                wanted: &wanted,
            };
            let sum = text.run(&setup, Options::default(), &mut pass);
            o.freeze();
            if let Some(slot) = wanted.upgrade() {
                slot.fill(match sum.errors {
                    0 => Ok(Arc::new(o)),
                    n => Err(format!(
                        "the outline's pass found {n} errors the load did not"
                    )),
                });
            }
        };
        if super::fuzz_rig::inline_threads() {
            pass();
            return slot;
        }
        let spawned = std::thread::Builder::new()
            .name("cnc-outline".into())
            .stack_size(crate::runtime::rt::THREAD_STACK_BYTES)
            .spawn(move || {
                crate::runtime::rt::lower_own_priority();
                pass();
            });
        if let Err(e) = spawned {
            slot.fill(Err(format!("no thread for the outline's pass: {e}")));
        }
        slot
    }

    fn fill(&self, outline: Result<Arc<Outline>, String>) {
        *self.outline.lock().unwrap() = Some(outline);
        self.done.notify_all();
    }

    /// The outline, once its pass has ended. Blocking.
    fn wait(&self) -> Result<Arc<Outline>, Status> {
        let mut g = self.outline.lock().unwrap();
        loop {
            match &*g {
                Some(Ok(o)) => return Ok(o.clone()),
                Some(Err(e)) => return Err(Status::internal(e.clone())),
                None => g = self.done.wait(g).unwrap(),
            }
        }
    }
}

/// The selection outline's pass, stopped once nobody wants the outline.
struct WhileWanted<'a> {
    outline: &'a mut Outline,
    wanted: &'a Weak<SelectionOutline>,
}

impl Observer for WhileWanted<'_> {
    fn programmed(&mut self, b: &Block, modal: &Modal) {
        self.outline.programmed(b, modal);
    }
    fn compensated(&mut self, c: &CompBlock) {
        self.outline.compensated(c);
    }
    fn segment(&mut self, s: &Segment) -> Flow {
        self.outline.segment(s);
        if self.wanted.strong_count() == 0 {
            Flow::Stop
        } else {
            Flow::Go
        }
    }
}

/// The outline of what runs while the machine runs: the job's when the selected program was
/// started through the API, the selection's otherwise (an MDI job runs: the selection is the
/// next start's).
fn running_outline(
    st: &ApiState,
    program: &Arc<LoadedProgram>,
    job: u32,
) -> Result<Arc<Outline>, Status> {
    let own = match &*st.job.outlines.job.lock().unwrap() {
        Some(j) if j.job == job => j.outline.clone(),
        _ => None,
    };
    let own = match own {
        Some(o) => Some(o),
        None => selection_outline(st, program)?,
    };
    own.ok_or_else(|| {
        Status::failed_precondition(
            "the outline of the running job is not kept: ask again once it has ended",
        )
    })
}

/// The selected program with the setup in force: its selection's pass while that is the next
/// start's (same check as the recorded preview pass: constants, offsets and start position
/// unchanged), else a pass of its own, kept for the next request with the same setup.
fn idle_outline(
    st: &ApiState,
    program: &Arc<LoadedProgram>,
) -> Result<(Arc<Outline>, bool), Status> {
    if st.ctl.validated_as_now(program, &st.ctl.snapshot())
        && let Some(o) = selection_outline(st, program)?
    {
        return Ok((o, false));
    }
    let axes = st.ctl.config().axes.len();
    let mut kept = st.job.outlines.setup.lock().unwrap();
    let now = st.ctl.setup_stamp();
    if let Some(k) = kept.as_ref()
        && std::ptr::eq(k.program.as_ptr(), Arc::as_ptr(program))
        && k.stamp.matches(&now, axes)
    {
        return Ok((k.outline.clone(), true));
    }
    let (outline, stamp) = own_pass(st, program, None, START_CELL_MM)?;
    let outline = Arc::new(outline);
    *kept = Some(SetupOutline {
        program: Arc::downgrade(program),
        stamp,
        outline: outline.clone(),
    });
    Ok((outline, true))
}

/// A pass over `program` with the setup in force, into an outline (clipped to `clip` from
/// grid `cell_mm` when given), with the stamp of the setup it used.
fn own_pass(
    st: &ApiState,
    program: &LoadedProgram,
    clip: Option<Clip>,
    cell_mm: f64,
) -> Result<(Outline, SetupStamp), Status> {
    let mut o = Outline::clipped(&st.ctl.config().axis_names(), clip, cell_mm);
    let (v, setup, generation) = st
        .ctl
        .validate_program_with(&program.text, program.dialect, Options::default(), &mut o)
        .map_err(super::status_of)?;
    if v.has_errors() {
        return Err(invalid_with_diagnostics("program", &v.diagnostics));
    }
    o.freeze();
    Ok((o, SetupStamp::of(&setup, generation)))
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
    let snap = st.ctl.snapshot();
    let running = matches!(
        snap.state,
        MachineState::Running | MachineState::Hold | MachineState::Stopping
    );
    let (outline, mut own) = if running {
        (running_outline(st, &program, snap.progress.job)?, false)
    } else {
        idle_outline(st, &program)?
    };
    let mut view = outline.view(plane, extent, w, h);
    // Zoomed in finer than the outline's grid: a pass of its own over the extent (not while
    // a job runs: it would not be the job's).
    if let Some(e) = extent.filter(|_| !running) {
        let px_mm =
            ((e.max[0] - e.min[0]) / f64::from(w)).max((e.max[1] - e.min[1]) / f64::from(h));
        if px_mm < outline.cell_mm() / 2.0 {
            let (fine, _) = own_pass(st, &program, Some(Clip { plane, extent: e }), px_mm)?;
            let bounds = view.bounds;
            view = View {
                bounds,
                ..fine.view(plane, extent, w, h)
            };
            own = true;
        }
    }
    let mut reply = reply(&program.name, &outline, view, own);
    if let Some(n) = r.from_block {
        reply.approach = Some(approach(st, plane, n)?);
    }
    Ok(reply)
}

/// The approach of a restart of the selected program from block `n` on `plane`: one
/// polyline from where the axes are through the end of each leg.
fn approach(st: &ApiState, plane: Plane, n: u32) -> Result<pb::Polylines, Status> {
    let legs = super::preview::approach_legs(&st.ctl, "", "", n)?;
    let mut points: Vec<kernel::AxesMm> = Vec::new();
    for (start, end, _) in legs.iter().filter_map(|b| b.motion()) {
        if points.is_empty() {
            points.push(start);
        }
        points.push(end);
    }
    let names = st.ctl.config().axis_names();
    Ok(runs_pb(::preview::outline::polyline(
        &names, plane, &points,
    )))
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
        approach: None,
    }
}
