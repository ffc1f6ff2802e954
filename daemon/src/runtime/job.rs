//! The planner thread of one program run: the program streams through the kernel pipeline
//! into the segment ring to the RT thread. Runs outside the RT thread; waits (sleeps) while the
//! ring is full, so memory stays bounded by the look-ahead.

use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use kernel::Diagnostic;
use kernel::comp::CompConfig;
use kernel::plan::{PlannerConfig, Segment};
use kernel::program::Setup;

use super::pipeline::{self, RecentBlocks};
use super::storage::OffsetStore;

/// What a run needs.
pub struct JobSpec {
    pub job: u32,
    pub text: Arc<str>,
    pub setup: Setup,
    pub planner: PlannerConfig,
    pub comp: CompConfig,
    /// The offset table: `G92 D..` blocks write its memory copy (SPEC §3 c).
    pub offsets: Arc<Mutex<OffsetStore>>,
    /// Every block ends at rest (single-block runs).
    pub stop_at_blocks: bool,
    /// Where the streamed blocks are recorded for status.
    pub recent: Arc<Mutex<RecentBlocks>>,
    /// The RT thread's snapshots: the PLC cell DYNAM_SET selects the dynamic set (SPEC §7.4).
    pub status: tokio::sync::watch::Receiver<super::rt::Snapshot>,
}

/// Shared between the controller and the planner threads.
pub struct JobLink {
    /// The producer end of the segment ring; a run holds it for its whole life, so a new run
    /// starts only after the previous planner thread has let go.
    pub segments: Mutex<rtrb::Producer<Segment>>,
    /// Id of the last job whose segments are all on the ring (or that gave up).
    pub planned_job: Arc<AtomicU32>,
}

/// Runs the planning of one job to its end. Always marks the job planned when it returns,
/// whether it finished, was cancelled or failed, so the RT thread never waits for it forever.
pub fn run(spec: JobSpec, link: &JobLink, cancel: &AtomicBool) -> Result<(), Diagnostic> {
    let mut ring = link.segments.lock().unwrap_or_else(|e| e.into_inner());
    let result = pipeline::run(&spec, |seg| push_waiting(&mut ring, seg, cancel));
    link.planned_job.store(spec.job, Ordering::Release);
    result
}

/// Pushes one segment, waiting while the ring is full. False when the run was cancelled.
fn push_waiting(ring: &mut rtrb::Producer<Segment>, mut seg: Segment, cancel: &AtomicBool) -> bool {
    loop {
        if cancel.load(Ordering::Relaxed) {
            return false;
        }
        match ring.push(seg) {
            Ok(()) => return true,
            Err(rtrb::PushError::Full(s)) => {
                seg = s;
                std::thread::sleep(Duration::from_millis(1));
            }
        }
    }
}
