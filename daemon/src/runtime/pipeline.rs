//! What the daemon keeps of a job's pipeline pass (`kernel::pipeline`) until the RT thread has
//! executed it: the blocks around the executing one (modal state for status and for the next
//! MDI) and the `G92 D..` table writes, applied to the memory offset table when their block
//! executes (SPEC §3 c). The status pump calls [`Execution::observe`] with every snapshot.
//!
//! The planner thread records ahead of execution (by at most the look-ahead and the rings), so
//! memory stays bounded by [`RECENT_BLOCKS`] whatever the program's length.

use std::collections::VecDeque;

use kernel::block::Block;
use kernel::offsets::TableEdit;
use kernel::program::Modal;

use super::rt::Snapshot;

/// Blocks kept: more than compensation window + planner look-ahead + segment ring +
/// interpolator buffer together.
pub const RECENT_BLOCKS: usize = 16_384;

/// A `G92 D..` write waiting for its block to execute.
#[derive(Clone, Debug)]
pub struct PendingWrite {
    pub seq: u32,
    pub n: Option<u32>,
    pub line: u32,
    pub edit: TableEdit,
}

/// The pass of the running job as the planner thread saw it, and what execution has reached.
#[derive(Default)]
pub struct Execution {
    job: u32,
    blocks: VecDeque<(Block, Modal)>,
    pending: VecDeque<PendingWrite>,
    /// The job's path has moved: from then on the snapshot's block index is this job's.
    moved: bool,
    /// The modal state the last finished or stopped job (or MDI) left (what MDI inherits).
    modal_left: Option<Modal>,
    /// Jobs already settled (finished or stopped) by [`Execution::observe`].
    settled: u32,
}

impl Execution {
    /// A new job's pass begins (the planner thread, before its first block).
    pub fn begin(&mut self, job: u32) {
        self.job = job;
        self.blocks.clear();
        self.pending.clear();
        self.moved = false;
    }

    /// The planner thread streamed block `b` of `job`; `modal` is the state after it.
    pub fn record(&mut self, job: u32, b: &Block, modal: &Modal) {
        if job != self.job {
            return;
        }
        if self.blocks.len() == RECENT_BLOCKS {
            self.blocks.pop_front();
        }
        self.blocks.push_back((*b, *modal));
    }

    /// A `G92` block of `job` was planned: its write waits for the block to execute.
    pub fn table_write(&mut self, job: u32, w: PendingWrite) {
        if job == self.job {
            self.pending.push_back(w);
        }
    }

    fn entry(&self, job: u32, seq: u32) -> Option<&(Block, Modal)> {
        if job != self.job {
            return None;
        }
        let first = self.blocks.front()?.0.seq;
        let i = seq.checked_sub(first)? as usize;
        self.blocks.get(i).filter(|(b, _)| b.seq == seq)
    }

    /// Block `seq` of `job`, if it is still (or already) known.
    pub fn block(&self, job: u32, seq: u32) -> Option<Block> {
        self.entry(job, seq).map(|e| e.0)
    }

    /// What the next MDI starts with.
    pub fn modal_left(&self) -> Option<Modal> {
        self.modal_left
    }

    /// Follows execution with snapshot `s`: hands `apply` the table writes whose block the
    /// path has passed (to apply now, in order). A stopped job's writes that it did not reach
    /// are dropped; a finished job's remaining writes all apply. Allocates nothing, so the
    /// single-threaded harness can run it beside the RT core.
    pub fn observe(&mut self, s: &Snapshot, mut apply: impl FnMut(&PendingWrite)) {
        if self.job == 0 || self.settled == self.job || s.progress.job != self.job {
            return;
        }
        if s.axes.path_v_mm_s > 0.0 {
            self.moved = true;
        }
        if s.progress.finished_job == self.job {
            self.pending.drain(..).for_each(|w| apply(&w));
            self.modal_left = self.blocks.back().map(|e| e.1).or(self.modal_left);
            self.settled = self.job;
        } else if s.progress.aborted_job == self.job {
            self.take_passed(s.progress.block_seq, &mut apply);
            self.pending.clear();
            if self.moved
                && let Some(e) = self.entry(self.job, s.progress.block_seq)
            {
                self.modal_left = Some(e.1);
            }
            self.settled = self.job;
        } else {
            self.take_passed(s.progress.block_seq, &mut apply);
        }
    }

    /// Writes of blocks before the executing block `seq` (once the job's path has moved).
    fn take_passed(&mut self, seq: u32, apply: &mut impl FnMut(&PendingWrite)) {
        if !self.moved {
            return;
        }
        while self.pending.front().is_some_and(|w| w.seq < seq) {
            if let Some(w) = self.pending.pop_front() {
                apply(&w);
            }
        }
    }
}
