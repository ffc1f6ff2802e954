//! What the API keeps beside the controller about the selected program and the job it started:
//! the junction classes, recorded pass and outlines of the selection and of the running job
//! (status, previews), the job's own block list (modal codes in status), single block as the
//! operator set it, and the lock that serialises Start and MDI.

use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};

use kernel::block::Block;
use proto::v1 as pb;

/// How a job was started.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum RunMode {
    Auto,
    Mdi,
}

impl RunMode {
    pub(super) fn to_pb(self) -> pb::Mode {
        match self {
            RunMode::Auto => pb::Mode::Auto,
            RunMode::Mdi => pb::Mode::Mdi,
        }
    }
}

/// A job started through the API with its blocks (for the modal codes in status).
pub(super) struct RunInfo {
    pub(super) job: u32,
    pub(super) blocks: Arc<Vec<Block>>,
    pub(super) mode: RunMode,
}

/// Junction class per block index of the selected program.
pub(super) struct PlanInfo {
    /// `Arc::as_ptr` of the `LoadedProgram` it belongs to.
    pub(super) program: usize,
    pub(super) junctions: Vec<pb::JunctionClass>,
    /// The outputs of the same pass, read by the previews of the selected program (`None`:
    /// too large to keep).
    pub(super) pass: Option<Arc<::preview::pipeline::Recording>>,
    /// The outline of the same pass (`GetPreviewOutline`), made beside the load.
    pub(super) outline: Arc<super::preview_outline::SelectionOutline>,
}

/// The selection's pass and the started job, as the API saw them.
pub(super) struct JobView {
    pub(super) plan_info: Mutex<Option<PlanInfo>>,
    /// Outlines besides the selection's: of a changed setup, of the running job.
    pub(super) outlines: super::preview_outline::Outlines,
    pub(super) run: Mutex<Option<RunInfo>>,
    pub(super) single_block: AtomicBool,
    /// Serialises Start and MDI: the RT thread takes a start on its next tick, so a second
    /// start must wait until the first is seen in the snapshot.
    pub(super) start_lock: tokio::sync::Mutex<()>,
}

impl JobView {
    pub(super) fn new() -> JobView {
        JobView {
            plan_info: Mutex::new(None),
            outlines: super::preview_outline::Outlines::default(),
            run: Mutex::new(None),
            single_block: AtomicBool::new(false),
            start_lock: tokio::sync::Mutex::new(()),
        }
    }

    /// The junction class of block `seq` of the program at `program_ptr`, if it is the one
    /// the recorded pass belongs to.
    pub(super) fn junction_of(&self, program_ptr: usize, seq: u32) -> pb::JunctionClass {
        let g = self.plan_info.lock().unwrap();
        match &*g {
            Some(p) if p.program == program_ptr => p
                .junctions
                .get(seq as usize)
                .copied()
                .unwrap_or(pb::JunctionClass::Unspecified),
            _ => pb::JunctionClass::Unspecified,
        }
    }

    /// How job `job` was started, with its blocks when the API started it with its own list
    /// (MDI, a run from a block list); else automatic with the selected program's blocks.
    pub(super) fn run_of(&self, job: u32) -> (RunMode, Option<Arc<Vec<Block>>>) {
        match &*self.run.lock().unwrap() {
            Some(r) if r.job == job && job != 0 => (r.mode, Some(r.blocks.clone())),
            _ => (RunMode::Auto, None),
        }
    }
}
