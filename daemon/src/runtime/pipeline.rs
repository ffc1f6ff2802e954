//! The kernel pipeline of a program, streaming: interpret → compensate → plan.
//!
//! Used twice: to validate a whole program when it is loaded (every error and warning, nothing
//! kept but a count), and by the planner thread of a run (segments to the RT thread). Memory
//! stays bounded by the compensation and look-ahead windows whatever the program's length.

use kernel::Diagnostic;
use kernel::block::{Block, BlockKind, Continuity};
use kernel::comp::{CompConfig, Compensator};
use kernel::offsets::TableEdit;
use kernel::plan::{Planner, PlannerConfig, Segment};
use kernel::program::{self, Setup};

use super::job::JobSpec;

/// Diagnostics beyond this many are counted, not listed.
const MAX_LISTED: usize = 1000;

/// Outcome of validating a program.
#[derive(Debug, Default)]
pub struct Validation {
    /// Blocks the program has (the interpreter's count).
    pub blocks: u32,
    /// Every error, warning and information, in the order found.
    pub diagnostics: Vec<Diagnostic>,
}

impl Validation {
    pub fn has_errors(&self) -> bool {
        self.diagnostics.iter().any(Diagnostic::is_error)
    }

    fn add(&mut self, d: Diagnostic) {
        if self.diagnostics.len() < MAX_LISTED
            || d.is_error() && self.diagnostics.len() < 2 * MAX_LISTED
        {
            self.diagnostics.push(d);
        }
    }
}

/// Runs the whole program through interpretation, compensation and planning without motion.
/// A block refused by a stage is reported and skipped (stages change nothing on a refusal), so
/// one pass finds every error.
pub fn validate(text: &str, setup: &Setup, comp: CompConfig, planner: PlannerConfig) -> Validation {
    let mut v = Validation::default();
    let mut stream = program::stream(text, setup);
    let mut comp = Compensator::new(comp);
    let mut planner = Planner::new(planner, 0);
    // Soft limits (issue #15): every planned segment, so with offsets and compensation.
    let drain = |planner: &mut Planner, v: &mut Validation| {
        while let Some(seg) = planner.poll() {
            if let Err(d) = check_limits(&seg, setup) {
                v.add(d);
            }
        }
    };
    let feed = |b: &Block, comp: &mut Compensator, planner: &mut Planner, v: &mut Validation| {
        if let Err(d) = comp.push(b) {
            v.add(d);
        }
        comp.take_diagnostics().into_iter().for_each(|d| v.add(d));
        while let Some(cb) = comp.poll() {
            if let Err(d) = planner.push(&cb) {
                v.add(d);
            }
            drain(planner, v);
        }
    };
    while let Some(item) = stream.next() {
        stream.take_notes().into_iter().for_each(|d| v.add(d));
        match item {
            Ok(b) => {
                v.blocks += 1;
                feed(&b, &mut comp, &mut planner, &mut v);
            }
            Err(d) => v.add(d),
        }
    }
    stream.take_notes().into_iter().for_each(|d| v.add(d));
    comp.finish();
    comp.take_diagnostics().into_iter().for_each(|d| v.add(d));
    while let Some(cb) = comp.poll() {
        if let Err(d) = planner.push(&cb) {
            v.add(d);
        }
        drain(&mut planner, &mut v);
    }
    planner.finish();
    drain(&mut planner, &mut v);
    let listed = v.diagnostics.len();
    if listed >= MAX_LISTED {
        v.diagnostics.push(Diagnostic::info(
            None,
            0,
            0,
            format!("only the first {listed} messages are listed"),
        ));
    }
    v
}

/// Refuses a planned segment that leaves the soft limits of `setup` (issue #15).
fn check_limits(seg: &Segment, setup: &Setup) -> Result<(), Diagnostic> {
    let axes = setup.axis_names.len();
    match setup.soft_limits.check_path(&seg.path, axes) {
        Some(hit) => Err(hit.diagnostic(seg, &setup.axis_names)),
        None => Ok(()),
    }
}

/// The blocks of the running job around the one executing, for status (modal state of the
/// current block) without keeping the whole program: the planner thread records each block it
/// streams; execution trails interpretation by at most the look-ahead and the rings.
pub struct RecentBlocks {
    job: u32,
    blocks: std::collections::VecDeque<Block>,
}

/// Blocks kept: more than compensation window + planner look-ahead + segment ring +
/// interpolator buffer together.
const RECENT_BLOCKS: usize = 16_384;

impl Default for RecentBlocks {
    fn default() -> Self {
        RecentBlocks {
            job: 0,
            blocks: std::collections::VecDeque::with_capacity(RECENT_BLOCKS),
        }
    }
}

impl RecentBlocks {
    fn record(&mut self, job: u32, b: &Block) {
        if job != self.job {
            self.job = job;
            self.blocks.clear();
        }
        if self.blocks.len() == RECENT_BLOCKS {
            self.blocks.pop_front();
        }
        self.blocks.push_back(*b);
    }

    /// Block `seq` of `job`, if it is still (or already) known.
    pub fn get(&self, job: u32, seq: u32) -> Option<Block> {
        if job != self.job {
            return None;
        }
        let first = self.blocks.front()?.seq;
        let i = seq.checked_sub(first)? as usize;
        self.blocks.get(i).filter(|b| b.seq == seq).copied()
    }
}

/// Streams a validated program's segments to `sink` (which returns false to cancel). Stops at
/// the first error. `G92 D..` blocks write the memory offset table when planned (at most the
/// look-ahead before they execute); the interpreter already applied them to its own copy.
pub fn run(spec: &JobSpec, mut sink: impl FnMut(Segment) -> bool) -> Result<(), Diagnostic> {
    let job = spec.job;
    let mut comp = Compensator::new(spec.comp);
    let mut planner = Planner::new(spec.planner.clone(), job);
    // The soft limits again, as the segments go out: the program was validated against
    // them, but the offsets may have been edited since (a refusal here ends the run).
    let mut drain = |planner: &mut Planner| -> Result<bool, Diagnostic> {
        while let Some(seg) = planner.poll() {
            check_limits(&seg, &spec.setup)?;
            if !sink(seg) {
                return Ok(false);
            }
        }
        Ok(true)
    };
    for item in program::stream(&spec.text, &spec.setup) {
        let mut b = item?;
        if spec.stop_at_blocks {
            b.continuity = Continuity::G98;
        }
        spec.recent
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .record(job, &b);
        if let BlockKind::TableWrite { entry, values } = b.kind {
            let edit = TableEdit { entry, values };
            spec.offsets
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .program_write(&edit)
                .map_err(|m| Diagnostic::error(b.n, b.line, 0, m))?;
        }
        comp.push(&b)?;
        while let Some(cb) = comp.poll() {
            // DYNAM_SET as the PLC has it now (cell 0..3 = set 1..4; acts after the look-ahead).
            planner.set_dynam_set_cell(spec.status.borrow().plc.dynam_set() - 1);
            planner.push(&cb)?;
            if !drain(&mut planner)? {
                return Ok(());
            }
        }
    }
    comp.finish();
    while let Some(cb) = comp.poll() {
        planner.push(&cb)?;
        if !drain(&mut planner)? {
            return Ok(());
        }
    }
    planner.finish();
    drain(&mut planner)?;
    Ok(())
}
