//! The planner thread of one program run: interpreted blocks → compensation → look-ahead
//! planner → segment ring to the RT thread. Runs outside the RT thread; waits (sleeps) while
//! the ring is full, so memory stays bounded by the look-ahead.

use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use kernel::Diagnostic;
use kernel::block::{Block, BlockKind};
use kernel::offsets::TableEdit;

use super::storage::OffsetStore;
use kernel::comp::{CompConfig, Compensator};
use kernel::plan::{Planner, PlannerConfig, Segment};

/// What a run needs.
pub struct JobSpec {
    pub job: u32,
    pub blocks: Arc<Vec<Block>>,
    pub planner: PlannerConfig,
    pub comp: CompConfig,
    /// The offset table: `G92 D..` blocks write its memory copy (SPEC §3 c).
    pub offsets: Arc<Mutex<OffsetStore>>,
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
    let result = plan_all(&spec, &mut ring, cancel);
    link.planned_job.store(spec.job, Ordering::Release);
    result
}

fn plan_all(
    spec: &JobSpec,
    ring: &mut rtrb::Producer<Segment>,
    cancel: &AtomicBool,
) -> Result<(), Diagnostic> {
    let mut comp = Compensator::new(spec.comp);
    let mut planner = Planner::new(spec.planner.clone(), spec.job);
    for block in spec.blocks.iter() {
        if cancel.load(Ordering::Relaxed) {
            return Ok(());
        }
        if let BlockKind::TableWrite { entry, values } = block.kind {
            // Applied when the block is planned (at most the look-ahead before it executes);
            // the interpreter already applied it to the program's own copy.
            let edit = TableEdit { entry, values };
            if let Err(m) = spec.offsets.lock().unwrap().program_write(&edit) {
                return Err(Diagnostic::error(block.n, block.line, 0, m));
            }
        }
        comp.push(block)?;
        while let Some(b) = comp.poll() {
            planner.push(&b)?;
            drain(&mut planner, ring, cancel);
        }
    }
    comp.finish();
    while let Some(b) = comp.poll() {
        planner.push(&b)?;
        drain(&mut planner, ring, cancel);
    }
    planner.finish();
    drain(&mut planner, ring, cancel);
    Ok(())
}

/// Moves committed segments to the ring, waiting while it is full.
fn drain(planner: &mut Planner, ring: &mut rtrb::Producer<Segment>, cancel: &AtomicBool) {
    while let Some(mut seg) = planner.poll() {
        loop {
            if cancel.load(Ordering::Relaxed) {
                return;
            }
            match ring.push(seg) {
                Ok(()) => break,
                Err(rtrb::PushError::Full(s)) => {
                    seg = s;
                    std::thread::sleep(Duration::from_millis(1));
                }
            }
        }
    }
}
