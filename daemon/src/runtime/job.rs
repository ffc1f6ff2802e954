//! The planner thread of one program run: the program streams through the kernel pipeline
//! (`kernel::pipeline`, the same pass that validated it) into the segment ring to the RT
//! thread. Runs outside the RT thread; waits (sleeps) while the ring is full, so memory stays
//! bounded by the look-ahead.

use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use kernel::Diagnostic;
use kernel::block::Block;
use kernel::machine::MachineSetup;
use kernel::offsets::TableEdit;
use kernel::pipeline::{Flow, Observer, Options};
use kernel::plan::Segment;
use kernel::program::Modal;

use kernel::probe::ProbeResult;

use super::library::ProgramText;
use super::pipeline::{Execution, PendingWrite};
use super::program_probe;
use super::rt::Snapshot;

/// What a run needs.
pub struct JobSpec {
    /// In memory, or the open file of a stored program (streamed line by line).
    pub text: ProgramText,
    /// The job's snapshot of the machine setup: every stage reads it.
    pub setup: MachineSetup,
    pub opts: Options,
    /// Where the streamed blocks and `G92` writes are recorded until they execute.
    pub execution: Arc<Mutex<Execution>>,
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

/// Where a run's segments go and how it sees the machine: the planner thread's ring and the
/// RT thread's snapshots, or the single-threaded harness stepping the core itself.
pub(crate) trait RunLink {
    /// Hands over one segment, waiting while the ring is full; false: the run was cancelled.
    fn segment(&mut self, s: Segment) -> bool;
    /// Lets the machine run a little (the planner thread sleeps, the harness ticks) and
    /// gives the latest snapshot; `None`: the run was cancelled.
    fn wait(&mut self) -> Option<Snapshot>;
}

/// A run's observer: segments to `link`, blocks and table writes to the execution record.
struct Runner<'a, L> {
    spec: &'a JobSpec,
    link: L,
    error: Option<Diagnostic>,
}

impl<L: RunLink> Observer for Runner<'_, L> {
    fn programmed(&mut self, b: &Block, modal: &Modal) {
        let job = self.spec.opts.job;
        lock(&self.spec.execution).record(job, b, modal);
    }

    fn segment(&mut self, s: &Segment) -> Flow {
        if self.link.segment(*s) {
            Flow::Go
        } else {
            Flow::Stop
        }
    }

    fn probe(&mut self, b: &Block) -> Option<ProbeResult> {
        let job = self.spec.opts.job;
        loop {
            let s = self.link.wait()?;
            if s.progress.aborted_job == job {
                return None;
            }
            let p = s.program_probe;
            if p.job == job && p.seq == b.seq && p.done {
                return program_probe::result(b, &p)
                    .map_err(|d| self.error = Some(d))
                    .ok();
            }
        }
    }

    fn diagnostic(&mut self, d: Diagnostic) -> Flow {
        if d.is_error() {
            self.error = Some(d);
            return Flow::Stop;
        }
        Flow::Go
    }

    fn table_write(&mut self, b: &Block, edit: &TableEdit) -> Flow {
        let w = PendingWrite {
            seq: b.seq,
            n: b.n,
            line: b.line,
            edit: *edit,
        };
        lock(&self.spec.execution).table_write(self.spec.opts.job, w);
        Flow::Go
    }

    fn dynam_set_cell(&mut self) -> Option<u8> {
        // DYNAM_SET as the PLC has it now (cell 0..3 = set 1..4; acts after the look-ahead).
        Some(self.spec.status.borrow().plc.dynam_set().saturating_sub(1))
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// Runs the planning of one job to its end. Always marks the job planned when it returns,
/// whether it finished, was cancelled or failed, so the RT thread never waits for it forever.
pub fn run(spec: JobSpec, link: &JobLink, cancel: &AtomicBool) -> Result<(), Diagnostic> {
    let mut ring = link.segments.lock().unwrap_or_else(|e| e.into_inner());
    let thread = ThreadLink {
        ring: &mut ring,
        cancel,
        status: spec.status.clone(),
    };
    let result = plan_into(&spec, thread);
    link.planned_job.store(spec.opts.job, Ordering::Release);
    result
}

/// The planner thread's side of the RT thread: the segment ring and the snapshots.
struct ThreadLink<'a> {
    ring: &'a mut rtrb::Producer<Segment>,
    cancel: &'a AtomicBool,
    status: tokio::sync::watch::Receiver<Snapshot>,
}

impl RunLink for ThreadLink<'_> {
    fn segment(&mut self, s: Segment) -> bool {
        push_waiting(self.ring, s, self.cancel)
    }

    fn wait(&mut self) -> Option<Snapshot> {
        std::thread::sleep(Duration::from_millis(1));
        (!self.cancel.load(Ordering::Relaxed)).then(|| *self.status.borrow())
    }
}

/// Plans `spec` through the pipeline, handing its segments in order to `link` (false: cancel)
/// and recording blocks and `G92` writes for execution. The first error ends it. Shared by the
/// planner thread and the single-threaded harness.
pub(crate) fn plan_into(spec: &JobSpec, link: impl RunLink) -> Result<(), Diagnostic> {
    let mut runner = Runner {
        spec,
        link,
        error: None,
    };
    spec.text.run(&spec.setup, spec.opts, &mut runner);
    runner.error.map_or(Ok(()), Err)
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
