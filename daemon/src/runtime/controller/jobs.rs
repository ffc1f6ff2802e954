//! Jobs: starting the selected program or a text (MDI, single-block runs) on its planner
//! thread, the execution record (blocks near the executing one, pending `G92` writes, the
//! modal state left for MDI), feed hold, resume and stop.

use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use kernel::block::Block;
use kernel::pipeline::{Observer, Options};

use super::ControlError;
use super::rt_link::RtLink;
use super::selection::{Blocks, Selection};
use super::tables::Tables;
use crate::runtime::config::Config;
use crate::runtime::homing;
use crate::runtime::job::{self, JobLink, JobSpec};
use crate::runtime::library::ProgramText;
use crate::runtime::logging::BlockNo;
use crate::runtime::pipeline::Execution;
use crate::runtime::rt::{JobMachine, MachineState, RtCommand, Snapshot};

pub(super) struct Jobs {
    config: Arc<Config>,
    /// The selected program; the validation passes.
    selection: Selection,
    next_job: AtomicU32,
    run: Mutex<Option<Run>>,
    link: Arc<JobLink>,
    /// Last alarm raised outside the RT thread (a planning failure): its diagnostic's stable
    /// code and its text, for status and the MTConnect CONDITION's nativeCode.
    alarm: Arc<Mutex<Option<(&'static str, String)>>>,
    /// The running job's pass: blocks near the executing one, pending `G92` writes, the modal
    /// state left for MDI. Shared with the status thread, which follows execution.
    execution: Arc<Mutex<Execution>>,
    /// A feed hold was asked for and not yet resumed or stopped (the RT thread may not have
    /// published the hold yet).
    hold_requested: AtomicBool,
}

/// How a text runs (`Jobs::start_text`).
#[derive(Clone, Copy, Debug, Default)]
pub struct TextRun {
    /// Every block ends at rest (G98): single-block runs.
    pub stop_at_blocks: bool,
    /// MDI: starts in the modal state the last program or MDI left.
    pub mdi: bool,
    /// A restart from a block.
    pub restart: Option<TextRestart>,
    /// The language of the text.
    pub dialect: kernel::program::Dialect,
}

/// A text run as a restart from a block (the selected program's single-block run).
#[derive(Clone, Copy, Debug)]
pub struct TextRestart {
    pub from_block: u32,
    /// Where the blocks before it are interpreted from (`LoadedProgram::restart_origin`).
    pub origin_mm: kernel::units::AxesMm,
}

/// The planner thread of the current job.
struct Run {
    cancel: Arc<AtomicBool>,
    thread: JoinHandle<()>,
}

impl Jobs {
    pub(super) fn new(
        config: Arc<Config>,
        link: JobLink,
        execution: Arc<Mutex<Execution>>,
    ) -> Jobs {
        Jobs {
            config,
            selection: Selection::default(),
            next_job: AtomicU32::new(1),
            run: Mutex::new(None),
            link: Arc::new(link),
            alarm: Arc::new(Mutex::new(None)),
            execution,
            hold_requested: AtomicBool::new(false),
        }
    }

    pub(super) fn selection(&self) -> &Selection {
        &self.selection
    }

    pub(super) fn alarm(&self) -> Option<(&'static str, String)> {
        self.alarm.lock().unwrap().clone()
    }

    /// Block `seq` of `job` if the job is running (or just ran) and the block is near the
    /// executing one: the modal state for status.
    pub(super) fn block_at(&self, job: u32, seq: u32) -> Option<Block> {
        self.execution.lock().unwrap().block(job, seq)
    }

    /// FAILED_PRECONDITION while an axis that needs a reference run has not had one.
    fn require_homed(&self, rt: &RtLink, what: &str) -> Result<(), ControlError> {
        homing::require_homed(&self.config, &rt.snapshot(), what)
    }

    /// Starts the selected program, or restarts it from the block numbered `from_block`
    /// (`kernel::restart`: the blocks before it without motion, an approach to its start).
    /// Returns the job id, and `obs` when the job made a validation pass of its own (which
    /// `obs` saw).
    pub(super) fn start_program<O: Observer>(
        &self,
        rt: &RtLink,
        tables: &Tables,
        from_block: Option<u32>,
        mut obs: O,
    ) -> Result<(u32, Option<O>), ControlError> {
        self.require_homed(rt, "a program")?;
        let program = self
            .selection
            .program()
            .ok_or_else(|| ControlError::WrongState("no program is loaded".into()))?;
        let mut run = self.run.lock().unwrap();
        let snap = rt.idle_for_start()?;
        // The job's snapshot of the machine, taken now: every stage of the run reads it.
        let setup = tables
            .machine_setup(rt.snapshot().axes.commanded)?
            .with_dialect(program.dialect)
            .with_restart_origin(from_block.map(|_| program.restart_origin()));
        let start_mm = setup.program().start;
        let opts = Options {
            from_block,
            ..Options::default()
        };
        // Validated with another setup (the axes moved by MDI or another job, constants or
        // offsets changed) or restarted: validate again with this one, so the run cannot fail
        // half-way.
        let revalidate = !program.validated_as(&snap, tables.generation(), self.config.axes.len())
            || from_block.is_some();
        if revalidate {
            let v = program.text.validate_into(&setup, opts, &mut obs);
            if v.has_errors() {
                return Err(ControlError::InvalidProgram(v.diagnostics));
            }
        }
        let spec = JobSpec {
            text: program.text.clone(),
            setup,
            opts,
            execution: self.execution.clone(),
            status: rt.subscribe(),
        };
        let job = self.spawn_job(rt, &mut run, spec, &program.name, program.block_count)?;
        if from_block.is_none() {
            program.note_run_start(start_mm);
        }
        Ok((job, revalidate.then_some(obs)))
    }

    /// Runs `text` as a job without changing the selected program (MDI, single-block runs).
    /// With `stop_at_blocks` every block ends at rest (G98), so single-block holds land on
    /// block ends. MDI (`mdi`) starts in the modal state the last program or MDI left.
    /// Returns the job id, the blocks it runs and `obs`, which saw the job's validation pass.
    pub(super) fn start_text<O: Observer>(
        &self,
        rt: &RtLink,
        tables: &Tables,
        name: &str,
        text: &str,
        how: TextRun,
        obs: O,
    ) -> Result<(u32, Arc<Vec<Block>>, O), ControlError> {
        let TextRun {
            stop_at_blocks,
            mdi,
            restart,
            dialect,
        } = how;
        self.require_homed(rt, "MDI")?;
        let mut run = self.run.lock().unwrap();
        rt.idle_for_start()?;
        let opts = Options {
            job: 0,
            stop_at_blocks,
            from_block: restart.map(|r| r.from_block),
        };
        let modal = if mdi {
            self.execution.lock().unwrap().modal_left()
        } else {
            None
        };
        let mut pass = (Blocks::default(), obs);
        let origin = restart.map(|r| r.origin_mm);
        let (v, setup, _) = self
            .selection
            .validate_by(rt, tables, modal, dialect, |setup| {
                let setup = setup.clone().with_restart_origin(origin);
                kernel::pipeline::validate_into(text, &setup, opts, &mut pass)
            })?;
        let setup = setup.with_restart_origin(origin);
        let (blocks, obs) = pass;
        if v.has_errors() {
            return Err(ControlError::InvalidProgram(v.diagnostics));
        }
        let spec = JobSpec {
            text: ProgramText::Memory(Arc::from(text)),
            setup,
            opts,
            execution: self.execution.clone(),
            status: rt.subscribe(),
        };
        let job = self.spawn_job(rt, &mut run, spec, name, v.blocks)?;
        Ok((job, Arc::new(blocks.0), obs))
    }

    /// Starts the planner thread of a new job and tells the RT thread to run it with the
    /// job's machine setup.
    fn spawn_job(
        &self,
        rt: &RtLink,
        run: &mut Option<Run>,
        mut spec: JobSpec,
        name: &str,
        blocks: u32,
    ) -> Result<u32, ControlError> {
        let job = self.next_job.fetch_add(1, Ordering::Relaxed);
        spec.opts.job = job;
        self.hold_requested.store(false, Ordering::Relaxed);
        *self.alarm.lock().unwrap() = None;
        self.execution.lock().unwrap().begin(job);
        let machine = JobMachine {
            kr: spec
                .setup
                .kr_constants()
                .expect("the daemon's setup has KŘR"),
            in_position_mm: spec.setup.in_position_mm(),
        };
        rt.send(RtCommand::Start { job, machine })?;
        let cancel = Arc::new(AtomicBool::new(false));
        let link = self.link.clone();
        let c = cancel.clone();
        let alarm_slot = self.alarm.clone();
        let thread = std::thread::Builder::new()
            .name(format!("cnc-plan-{job}"))
            .stack_size(crate::runtime::rt::THREAD_STACK_BYTES)
            .spawn(move || {
                if let Err(d) = job::run(spec, &link, &c) {
                    tracing::error!(job, block = %BlockNo(d.block), line = d.line, "planning failed: {}", d.message);
                    *alarm_slot.lock().unwrap() = Some((d.code.as_str(), d.to_string()));
                }
            })
            .map_err(|e| ControlError::WrongState(format!("cannot start the planner: {e}")))?;
        tracing::info!(job, program = %name, blocks, "job started");
        *run = Some(Run { cancel, thread });
        Ok(job)
    }

    /// Cancels the planning of the current job (its thread ends at the next segment).
    fn cancel(&self) {
        if let Some(r) = self.run.lock().unwrap().as_ref() {
            r.cancel.store(true, Ordering::Relaxed);
        }
    }

    /// Stops motion: brake on the path, drop the rest of the program; the spindle stops once
    /// the axes are at rest. Never refused.
    pub(super) fn stop(&self, rt: &RtLink) -> Result<(), ControlError> {
        self.cancel();
        self.hold_requested.store(false, Ordering::Relaxed);
        rt.send(RtCommand::Stop)
    }

    /// Shutdown, first half: the planning of the current job is cancelled.
    pub(super) fn cancel_for_shutdown(&self) {
        self.cancel();
    }

    /// Shutdown, second half (the RT thread has ended): waits for the planner thread.
    pub(super) fn join(&self) {
        if let Some(r) = self.run.lock().unwrap().take() {
            let _ = r.thread.join();
        }
    }

    /// A job was started and has neither ended nor been stopped: it runs, is held, or the RT
    /// thread has not taken its start yet.
    fn job_active(&self, snap: &Snapshot) -> bool {
        let last = self.next_job.load(Ordering::Relaxed).saturating_sub(1);
        let pending = last != 0
            && snap.progress.job != last
            && snap.progress.finished_job != last
            && snap.progress.aborted_job != last;
        pending
            || matches!(
                snap.state,
                MachineState::Running | MachineState::Hold | MachineState::Stopping
            )
    }

    /// Feed hold. FAILED_PRECONDITION when nothing runs.
    pub(super) fn hold(&self, rt: &RtLink) -> Result<(), ControlError> {
        let snap = rt.snapshot();
        if !self.job_active(&snap) || snap.state == MachineState::Stopping {
            return Err(ControlError::WrongState(format!(
                "nothing runs to hold: the machine is {:?}",
                snap.state
            )));
        }
        self.hold_requested.store(true, Ordering::Relaxed);
        rt.send(RtCommand::Hold)
    }

    /// Continues after a feed hold, a single-block hold or a program stop (M0/M1).
    /// FAILED_PRECONDITION when nothing is held (idle, after a stop, while stopping).
    pub(super) fn resume(&self, rt: &RtLink) -> Result<(), ControlError> {
        let snap = rt.snapshot();
        let held = snap.state == MachineState::Hold
            || (self.hold_requested.load(Ordering::Relaxed)
                && self.job_active(&snap)
                && snap.state != MachineState::Stopping);
        if !held {
            return Err(ControlError::WrongState(format!(
                "nothing is held to resume: the machine is {:?}",
                snap.state
            )));
        }
        self.hold_requested.store(false, Ordering::Relaxed);
        rt.send(RtCommand::Resume)
    }

    /// Start while held (feed hold or a program stop M0/M1) continues the job: returns its
    /// id; `None` when nothing is held.
    pub(super) fn start_resumes(&self, rt: &RtLink) -> Result<Option<u32>, ControlError> {
        let snap = rt.snapshot();
        if snap.state != MachineState::Hold {
            return Ok(None);
        }
        self.hold_requested.store(false, Ordering::Relaxed);
        rt.send(RtCommand::Resume)?;
        Ok(Some(snap.progress.job))
    }
}
