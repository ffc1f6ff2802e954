//! The controller: owns the RT thread, the loaded program and the planner threads, and offers
//! the operations the API calls. Everything here runs outside the RT thread.
//!
//! [`Controller`] is a facade over parts, each owning its state and its lock (the file says
//! where a state lives):
//!
//! - `rt_link.rs`: the command ring, the snapshot subscription, the RT thread, shutdown;
//! - `pump.rs`: the status thread (snapshots to the watch channel, `G92` writes applied as
//!   their block executes);
//! - `tables.rs`: constants and the offset table (files, memory copies, restart rules) and
//!   the setup generation that counts their changes;
//! - `jobs.rs`: the planner thread, the execution record (`G92` writes, the MDI modal
//!   state), hold, resume and stop; it owns
//! - `selection.rs`: validation passes and the selected program;
//! - `motion.rs`: homing, jog, overrides, single block, optional stop, fault reset;
//! - `startup.rs`: data files loaded and checked, what the RT core and jobs are built from.
//!
//! A part reaches another only through arguments the facade passes (`&RtLink`, `&Tables`),
//! so the lock order stays visible: a start holds the run lock, then takes the execution
//! record or the constants, then the offsets; the status thread takes the execution record,
//! then the offsets.

mod jobs;
mod motion;
pub use motion::JogRefusal;
pub use probing::{BoreCentre, ProbeError, ProbeMove};
mod probing;
mod pump;
mod rt_link;
mod selection;
mod startup;
mod tables;

use std::sync::{Arc, Mutex};

use kernel::Diagnostic;
use kernel::block::Block;
use kernel::machine::MachineSetup;
use kernel::pipeline::{self, Observer, Options, Validation};
use tokio::sync::watch;

use kernel::constants::Constants;
use kernel::offsets::work_file::WorkEdit;
use kernel::offsets::{OffsetTable, TableEdit, WorkOffsets};
use kernel::plc::{PlcError, PlcWrite};
use kernel::program::Dialect;
use kernel::program::dry_run::Move;
use kernel::units::AxesMm;

use super::buses::{IoWiring, open_bus};
use super::config::{BusConfig, Config};
use super::library::ProgramText;
use super::pipeline::Execution;
use super::rt::{RtCommand, Snapshot};
use super::storage::StorageError;

use jobs::Jobs;
use motion::Motion;
use rt_link::RtLink;
use selection::NoObserver;
use tables::Tables;

pub use motion::JOG_LEASE_TICKS;
pub(crate) use pump::Pump;
pub use selection::{LoadedProgram, SetupStamp};
pub use startup::StartError;
pub(crate) use startup::{load_storage, machine_config, rt_core_config};
pub use tables::{FilesSync, needs_restart};

/// Which clock drives the tick loop of the RT thread. Simulated time is not a clock of the
/// threaded daemon: tests that need it step the RT core in the single-threaded harness
/// ([`super::harness`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClockKind {
    Monotonic,
}

#[derive(Debug, thiserror::Error)]
pub enum ControlError {
    #[error("the program has errors")]
    InvalidProgram(Vec<Diagnostic>),
    #[error("{0}")]
    WrongState(String),
    #[error("the real-time thread is not running")]
    RtGone,
    #[error("{0}")]
    Storage(#[from] StorageError),
    #[error("{0}")]
    Plc(#[from] PlcError),
    #[error("{0}")]
    Invalid(String),
    /// An operation was started and did not complete (e.g. a reference run failed).
    #[error("{0}")]
    Aborted(String),
}

/// The facade the API calls: each method delegates to the part that owns the state.
pub struct Controller {
    config: Arc<Config>,
    rt: RtLink,
    tables: Tables,
    jobs: Jobs,
    motion: Motion,
    /// The simulated machine's input handle (`cncctl io sim-set`); `None` on a real bus.
    sim_inputs: Mutex<Option<sim::io::SimInputs>>,
}

impl Controller {
    /// Opens the bus, starts the RT thread and the status pump.
    pub fn start(config: Config, clock: ClockKind) -> Result<Arc<Controller>, StartError> {
        let mut io = IoWiring::of(&config);
        let handle = sim::io::SimInputs::default();
        io.sim_handle = Some(handle.clone());
        let bus = open_bus(&config.bus, &config.axes, &config.sim, &io).map_err(StartError::Bus)?;
        let sim_inputs = matches!(config.bus, BusConfig::Sim { .. }).then_some(handle);
        let c = Self::start_with_bus(config, clock, bus)?;
        *c.sim_inputs.lock().unwrap_or_else(|e| e.into_inner()) = sim_inputs;
        Ok(c)
    }

    /// As [`Controller::start`], on a bus the caller built (tests wrap the simulated bus to
    /// record every setpoint).
    pub fn start_with_bus(
        config: Config,
        clock: ClockKind,
        bus: Box<dyn hal::DriveBus>,
    ) -> Result<Arc<Controller>, StartError> {
        let config = Arc::new(config);
        let can_home = bus.supports_homing();
        rt_link::warn_without_spindle(bus.as_ref());
        let stored = load_storage(&config)?;
        let core = rt_core_config(&config, &stored.constants, stored.offsets.memory())?;
        let tables = Tables::new(config.clone(), stored);
        let execution: Arc<Mutex<Execution>> = Arc::default();
        let pump = Pump {
            execution: execution.clone(),
            offsets: tables.offsets_shared(),
            generation: tables.generation_shared(),
            axis_names: config.axis_names(),
        };
        let (rt, job_link) = RtLink::start(&config, clock, bus, core, pump)?;
        Ok(Arc::new(Controller {
            jobs: Jobs::new(config.clone(), job_link, execution),
            motion: Motion::new(config.clone(), can_home),
            sim_inputs: Mutex::new(None),
            config,
            rt,
            tables,
        }))
    }

    pub fn config(&self) -> &Config {
        &self.config
    }

    // ---- the RT link ----

    /// Latest snapshot.
    pub fn snapshot(&self) -> Snapshot {
        self.rt.snapshot()
    }

    /// A receiver that sees every snapshot the pump publishes.
    pub fn subscribe(&self) -> watch::Receiver<Snapshot> {
        self.rt.subscribe()
    }

    /// Writes a PLC input cell; in force from the next tick. Refusals change nothing.
    pub fn plc_write(&self, write: PlcWrite) -> Result<(), ControlError> {
        self.rt.send(RtCommand::Plc(write))
    }

    /// Brings the axes to rest and ends the RT thread (SIGTERM/SIGINT path). Blocking.
    pub fn shutdown(&self) {
        self.jobs.cancel_for_shutdown();
        self.rt.shutdown_rt();
        self.jobs.join();
        self.rt.stop_pump();
    }

    // ---- validation and selection ----

    pub fn program(&self) -> Option<Arc<LoadedProgram>> {
        self.jobs.selection().program()
    }

    /// The machine setup a job started now would take: the configuration, the constants in
    /// force and the memory offset table, decoded once (issue #14), from where the axes are
    /// commanded now.
    pub fn machine_setup(&self) -> Result<MachineSetup, ControlError> {
        self.tables.machine_setup(self.rt.snapshot().axes.commanded)
    }

    /// As [`Controller::machine_setup`], for a program in `dialect`.
    pub fn machine_setup_in(&self, dialect: Dialect) -> Result<MachineSetup, ControlError> {
        Ok(self.machine_setup()?.with_dialect(dialect))
    }

    /// The machine's default program language (`[program] dialect`).
    pub fn default_dialect(&self) -> Dialect {
        self.config.program.dialect()
    }

    /// The language of program `name`: `explicit` (the API's field, or the library's record),
    /// else by its name, else the machine's default (`runtime::dialect`).
    pub fn dialect_of(&self, name: &str, explicit: Option<Dialect>) -> Dialect {
        super::dialect::of_program(explicit, name, self.default_dialect())
    }

    /// The code page of program files (`[program] encoding`, issue #31).
    pub fn program_encoding(&self) -> kernel::program::encoding::TextEncoding {
        self.machine_setup()
            .map(|s| s.program().encoding)
            .unwrap_or_default()
    }

    /// The R325 listing of `text` under the setup in force (SPEC §4.6): the text with E
    /// written, the refinements, the program's messages.
    pub fn refinement_listing(
        &self,
        text: &str,
        dialect: Dialect,
    ) -> Result<(String, Vec<kernel::program::arc::Refined>, Vec<Diagnostic>), ControlError> {
        let setup = self.machine_setup_in(dialect)?;
        Ok(kernel::program::refinement_listing(text, setup.program()))
    }

    /// The dry run of `text` in `dialect` (`kernel::program::dry_run`): its moves and every
    /// message, with the machine's setup (axes, constants, TAB0.KOR, work offsets) from
    /// `start` (machine zero when `None`). Changes nothing: a `G10` acts within the run.
    pub fn interpret(
        &self,
        text: &str,
        dialect: Dialect,
        start: Option<AxesMm>,
    ) -> Result<(Vec<Move>, Vec<Diagnostic>), ControlError> {
        let commanded = start.unwrap_or(AxesMm::ZERO);
        let setup = self.tables.machine_setup(commanded)?.with_dialect(dialect);
        Ok(kernel::program::dry_run::moves(text, setup.program()))
    }

    /// Validates `text` through the whole pipeline (interpretation, compensation, planning)
    /// against the machine as it is now, passing what the stages produce to `obs`. Nothing is
    /// selected or run. The verdict of validate, upload, load, previews, start and MDI.
    pub fn validate_with(
        &self,
        text: &str,
        dialect: Dialect,
        opts: Options,
        modal: Option<kernel::program::Modal>,
        obs: &mut impl Observer,
    ) -> Result<(Validation, MachineSetup, u64), ControlError> {
        let selection = self.jobs.selection();
        selection.validate_by(&self.rt, &self.tables, modal, dialect, |setup| {
            pipeline::validate_into(text, setup, opts, obs)
        })
    }

    /// As [`Controller::validate_with`] for a text in memory or a stored program's file
    /// (streamed line by line: memory bounded whatever its size).
    pub fn validate_program_with(
        &self,
        text: &ProgramText,
        dialect: Dialect,
        opts: Options,
        obs: &mut impl Observer,
    ) -> Result<(Validation, MachineSetup, u64), ControlError> {
        let selection = self.jobs.selection();
        selection.validate_by(&self.rt, &self.tables, None, dialect, |setup| {
            text.validate_into(setup, opts, obs)
        })
    }

    /// The approach of a restart of `text` from block `from_block` with the axes where they
    /// are, the blocks before it interpreted from `origin` (`LoadedProgram::restart_origin`
    /// for the selected program; `None`: from where the axes are): the legs in order, and
    /// the pass's verdict (a block the program lacks is `restart_block_not_found`).
    pub fn restart_approach(
        &self,
        text: &ProgramText,
        dialect: Dialect,
        from_block: u32,
        origin: Option<kernel::units::AxesMm>,
    ) -> Result<(Validation, Vec<Block>), ControlError> {
        let opts = Options {
            from_block: Some(from_block),
            ..Options::default()
        };
        let mut legs = selection::ApproachLegs::default();
        let selection = self.jobs.selection();
        let (rt, tables) = (&self.rt, &self.tables);
        let (v, _, _) = selection.validate_by(rt, tables, None, dialect, |setup| {
            let setup = setup.clone().with_restart_origin(origin);
            text.validate_into(&setup, opts, &mut legs)
        })?;
        Ok((v, legs.0))
    }

    /// Validates `text` (in `dialect`) through the whole pipeline against the machine as it
    /// is now, without selecting or running it.
    pub fn validate_text(&self, text: &str, dialect: Dialect) -> Result<Validation, ControlError> {
        let opts = Options::default();
        Ok(self
            .validate_with(text, dialect, opts, None, &mut NoObserver)?
            .0)
    }

    /// Validates `text` in `dialect` (see [`Controller::validate_program_with`]) into a
    /// program that may be selected, with the setup it was validated with (a later pass that
    /// must be the same pass takes it); `obs` sees the pass. Errors: the program's
    /// diagnostics.
    pub fn prepare_program(
        &self,
        name: &str,
        text: ProgramText,
        dialect: Dialect,
        obs: &mut impl Observer,
    ) -> Result<(Arc<LoadedProgram>, MachineSetup), ControlError> {
        let read = text.clone();
        self.prepare_program_by(name, text, dialect, |setup| {
            read.validate_into(setup, Options::default(), obs)
        })
    }

    /// As [`Controller::prepare_program`], the text read by `pass` (an upload validated as it
    /// arrives reads it as it is written).
    pub fn prepare_program_by(
        &self,
        name: &str,
        text: ProgramText,
        dialect: Dialect,
        pass: impl FnOnce(&MachineSetup) -> Validation,
    ) -> Result<(Arc<LoadedProgram>, MachineSetup), ControlError> {
        let selection = self.jobs.selection();
        selection.prepare_program(&self.rt, &self.tables, name, text, dialect, pass)
    }

    /// Makes a validated program the selected one. Refused while a program runs.
    pub fn select(&self, loaded: Arc<LoadedProgram>) -> Result<(), ControlError> {
        self.jobs.selection().select(&self.snapshot(), loaded)
    }

    /// Validates `text` (in the dialect its name says, else the machine's) and makes it the
    /// selected program. Nothing moves; on error the previously selected program stays
    /// selected.
    pub fn load_program(&self, name: &str, text: &str) -> Result<Arc<LoadedProgram>, ControlError> {
        let text = ProgramText::Memory(Arc::from(text));
        let dialect = self.dialect_of(name, None);
        let (loaded, _) = self.prepare_program(name, text, dialect, &mut NoObserver)?;
        self.select(loaded.clone())?;
        Ok(loaded)
    }

    /// Whether `program` was validated with the setup a job started now would take: the same
    /// constants and offsets (generation) and the same start position. Its load's pass is then
    /// the pass of the next start.
    pub fn validated_as_now(&self, program: &LoadedProgram, snap: &Snapshot) -> bool {
        program.validated_as(snap, self.tables.generation(), self.config.axes.len())
    }

    /// The stamp of the setup a pass or a job started now would take.
    pub fn setup_stamp(&self) -> SetupStamp {
        SetupStamp {
            generation: self.tables.generation(),
            start: self.rt.snapshot().axes.commanded,
        }
    }

    /// Passes of the pipeline made for validation so far (validate, upload, load, previews
    /// of a text): tests see with it that a preview read load's pass instead of making one.
    pub fn validation_passes(&self) -> u64 {
        self.jobs.selection().passes()
    }

    /// Counts a pass made outside [`Controller::validate_with`] (the preview crate's picture).
    pub fn count_validation_pass(&self) {
        self.jobs.selection().count_pass();
    }

    // ---- jobs ----

    /// The planning failure in force, as text ending with its stable code.
    pub fn alarm(&self) -> Option<String> {
        self.jobs
            .alarm()
            .map(|(code, text)| format!("{text} ({code})"))
    }

    /// The planning failure in force: its diagnostic's stable code and its text.
    pub fn planning_alarm(&self) -> Option<(&'static str, String)> {
        self.jobs.alarm()
    }

    /// Starts the selected program. Returns the job id.
    pub fn start_program(&self) -> Result<u32, ControlError> {
        self.start_program_from(None)
    }

    /// Starts the selected program, or restarts it from the block numbered `from_block`
    /// (`kernel::restart`: the blocks before it without motion, an approach to its start).
    pub fn start_program_from(&self, from_block: Option<u32>) -> Result<u32, ControlError> {
        Ok(self.start_program_observed(from_block, NoObserver)?.0)
    }

    /// As [`Controller::start_program_from`]. When the job validates the program again (a
    /// setup changed since the selection, or a restart), `obs` sees that pass, the job's, and
    /// is returned; `None`: the selection's pass is the job's.
    pub fn start_program_observed<O: Observer>(
        &self,
        from_block: Option<u32>,
        obs: O,
    ) -> Result<(u32, Option<O>), ControlError> {
        self.jobs
            .start_program(&self.rt, &self.tables, from_block, obs)
    }

    /// Runs `text` (in `dialect`) as a job without changing the selected program (MDI,
    /// single-block runs). With `stop_at_blocks` every block ends at rest (G98), so
    /// single-block holds land on block ends. MDI (`mdi`) starts in the modal state the last
    /// program or MDI left. Returns the job id and the blocks it runs.
    pub fn start_text(
        &self,
        name: &str,
        text: &str,
        dialect: Dialect,
        stop_at_blocks: bool,
        mdi: bool,
    ) -> Result<(u32, Arc<Vec<Block>>), ControlError> {
        let how = jobs::TextRun {
            stop_at_blocks,
            mdi,
            restart: None,
            dialect,
        };
        let (job, blocks, _) =
            (self.jobs).start_text(&self.rt, &self.tables, name, text, how, NoObserver)?;
        Ok((job, blocks))
    }

    /// Runs the selected `program`'s `text` with every block ending at rest (the API's
    /// single-block start: the blocks in memory for the holds), from its first block or
    /// restarted from block `from_block` (the blocks before it from the program's
    /// [`LoadedProgram::restart_origin`], then the approach, which holds at its end like a
    /// block). Returns the job id, the blocks it runs and `obs`, which saw the job's pass.
    pub fn start_program_blocks<O: Observer>(
        &self,
        program: &LoadedProgram,
        text: &str,
        from_block: Option<u32>,
        obs: O,
    ) -> Result<(u32, Arc<Vec<Block>>, O), ControlError> {
        let start_mm = self.snapshot().axes.commanded;
        let restart = from_block.map(|from_block| jobs::TextRestart {
            from_block,
            origin_mm: program.restart_origin(),
        });
        let (rt, tables) = (&self.rt, &self.tables);
        let how = jobs::TextRun {
            stop_at_blocks: true,
            mdi: false,
            restart,
            dialect: program.dialect,
        };
        let r = self
            .jobs
            .start_text(rt, tables, &program.name, text, how, obs)?;
        if from_block.is_none() {
            program.note_run_start(start_mm);
        }
        Ok(r)
    }

    /// Block `seq` of `job` if the job is running (or just ran) and the block is near the
    /// executing one: the modal state for status.
    pub fn block_at(&self, job: u32, seq: u32) -> Option<Block> {
        self.jobs.block_at(job, seq)
    }

    /// Stops motion: brake on the path, drop the rest of the program; the spindle stops once
    /// the axes are at rest. Never refused (a stop is always allowed, also to stop a spindle
    /// left turning on an idle machine).
    pub fn stop(&self) -> Result<(), ControlError> {
        self.jobs.stop(&self.rt)
    }

    /// Feed hold. FAILED_PRECONDITION when nothing runs.
    pub fn hold(&self) -> Result<(), ControlError> {
        self.jobs.hold(&self.rt)
    }

    /// Continues after a feed hold, a single-block hold or a program stop (M0/M1).
    /// FAILED_PRECONDITION when nothing is held (idle, after a stop, while stopping).
    pub fn resume(&self) -> Result<(), ControlError> {
        if self.snapshot().io.door_open {
            return Err(ControlError::WrongState(
                "the door is open: close it, then Resume".into(),
            ));
        }
        self.jobs.resume(&self.rt)
    }

    /// Start while held (feed hold or a program stop M0/M1) continues the job: returns its
    /// id; `None` when nothing is held.
    pub fn start_resumes(&self) -> Result<Option<u32>, ControlError> {
        self.jobs.start_resumes(&self.rt)
    }

    // ---- motion ----

    /// Whether axis `i` is referenced: homed since power-on, or needing no reference run.
    pub fn axis_homed(&self, snap: &Snapshot, i: usize) -> bool {
        self.motion.axis_homed(snap, i)
    }

    /// Reference run of `axes` (all when empty), one axis after the other in the configured
    /// order. Returns the letters homed.
    pub async fn home(&self, axes: &str) -> Result<String, ControlError> {
        self.motion.home(&self.rt, axes).await
    }

    /// Starts or renews a continuous jog of `axis` in direction `dir` (sign) at `speed_mm_min`.
    /// The real-time thread stops it by itself unless renewed within [`JOG_LEASE_TICKS`]
    /// (the dead-man). Returns the target: the soft limit in that direction.
    pub fn jog(&self, axis: &str, dir: i32, speed_mm_min: f64) -> Result<f64, ControlError> {
        self.motion.jog(&self.rt, axis, dir, speed_mm_min)
    }

    /// A continuous jog as [`Controller::jog`] whose lease is `lease_ms` (`Machine.JogLease`,
    /// the browser's dead-man): the axis brakes to rest unless renewed within it.
    pub fn jog_leased(
        &self,
        axis: &str,
        dir: i32,
        speed_mm_min: f64,
        lease_ms: u32,
    ) -> Result<f64, ControlError> {
        self.motion
            .jog_leased(&self.rt, axis, dir, speed_mm_min, lease_ms)
    }

    /// Incremental jog: `step_mm` on `axis`, clamped to the soft limits. Returns the target.
    pub fn jog_step(
        &self,
        axis: &str,
        step_mm: f64,
        speed_mm_min: f64,
    ) -> Result<f64, ControlError> {
        self.motion.jog_step(&self.rt, axis, step_mm, speed_mm_min)
    }

    /// Whether a jog step may run: `Err` says why not (beyond a soft limit or any travel).
    pub fn jog_step_check(&self, axis: &str, step_mm: f64) -> Result<(), JogRefusal> {
        self.motion.jog_step_check(&self.rt, axis, step_mm)
    }

    /// The block-delete switch (issue #31): `/` blocks are skipped while it is on.
    pub fn set_block_delete(&self, on: bool) {
        self.tables.set_block_delete(on);
    }

    pub fn block_delete(&self) -> bool {
        self.tables.block_delete()
    }

    /// Brakes a jog to rest (the client let go, or went away).
    pub fn jog_stop(&self) -> Result<(), ControlError> {
        self.motion.jog_stop(&self.rt)
    }

    /// Optional stop switch: M1 stops the program only while it is on.
    pub fn set_optional_stop(&self, on: bool) -> Result<(), ControlError> {
        self.motion.set_optional_stop(&self.rt, on)
    }

    /// Single-block mode on the RT thread: hold when the path enters a new block.
    pub fn set_single_block(&self, on: bool) -> Result<(), ControlError> {
        self.motion.set_single_block(&self.rt, on)
    }

    /// Feed override, 0..150 %.
    pub fn set_override(&self, percent: f64) -> Result<(), ControlError> {
        self.motion.set_override(&self.rt, percent)
    }

    /// Spindle override, 50..120 % (issue #19): the RT core scales the commanded spindle
    /// speed within the gear range from the next tick.
    pub fn set_spindle_override(&self, percent: f64) -> Result<(), ControlError> {
        self.motion.set_spindle_override(&self.rt, percent)
    }

    /// Rapid override, 0..100 % (issue #19): G0 moves run at this share of their speed.
    pub fn set_rapid_override(&self, percent: f64) -> Result<(), ControlError> {
        self.motion.set_rapid_override(&self.rt, percent)
    }

    /// Clears a fault and re-enables the drives.
    pub fn reset(&self) -> Result<(), ControlError> {
        self.motion.reset(&self.rt)
    }

    // ---- inputs and outputs (docs/io.md) ----

    /// Forces output `name` (`None`: releases it).
    pub fn force_output(&self, name: &str, value: Option<bool>) -> Result<(), ControlError> {
        let (_, outputs) = super::io_setup::names(&self.config);
        let k = outputs
            .iter()
            .position(|n| n == name)
            .ok_or_else(|| ControlError::Invalid(format!("there is no output '{name}'")))?;
        self.rt.send(RtCommand::ForceOutput {
            output: k as u8,
            value,
        })
    }

    /// Sets input `name` of the simulated machine (`None`: the model's value again).
    pub fn sim_set_input(&self, name: &str, value: Option<bool>) -> Result<(), ControlError> {
        let (inputs, _) = super::io_setup::names(&self.config);
        let k = inputs
            .iter()
            .position(|n| n == name)
            .ok_or_else(|| ControlError::Invalid(format!("there is no input '{name}'")))?;
        let handle = self.sim_inputs.lock().unwrap_or_else(|e| e.into_inner());
        let Some(h) = handle.as_ref() else {
            return Err(ControlError::WrongState(
                "inputs are set by hand on the simulated machine only".into(),
            ));
        };
        h.set(k, value);
        Ok(())
    }

    /// Waits (bounded, 1 s) until the RT core has taken every command sent so far.
    pub async fn wait_commands_taken(&self) {
        let sent = self.rt.commands_sent();
        self.wait_until(|s| s.tick.commands_taken >= sent).await;
    }

    /// Waits (bounded, 1 s) until `n` more ticks have run.
    pub async fn wait_ticks(&self, n: u64) {
        let from = self.snapshot().tick.sequence;
        self.wait_until(|s| s.tick.sequence >= from + n).await;
    }

    async fn wait_until(&self, done: impl Fn(&Snapshot) -> bool) {
        let t0 = std::time::Instant::now();
        while !done(&self.snapshot()) && t0.elapsed() < std::time::Duration::from_secs(1) {
            tokio::time::sleep(std::time::Duration::from_millis(1)).await;
        }
    }

    /// Whether the machine is the built-in simulated one (its inputs can be set).
    pub fn simulated(&self) -> bool {
        self.sim_inputs
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .is_some()
    }

    // ---- tables ----

    /// The memory offset table (what programs use).
    pub fn offsets_memory(&self) -> OffsetTable {
        self.tables.offsets_memory()
    }

    /// The offset table file as text.
    pub fn offsets_file_text(&self) -> String {
        self.tables.offsets_file_text()
    }

    /// The revision of the offset table file's text (`storage::revision_of`).
    pub fn offsets_revision(&self) -> String {
        self.tables.offsets_revision()
    }

    /// Operator edit of one entry: file and memory (SPEC §3 b), made on the file as it is on
    /// disk (a hand edit saved since is loaded first, issue #31).
    pub fn edit_offset(&self, edit: &TableEdit) -> Result<(), ControlError> {
        self.tables.edit_offset(edit)
    }

    /// Replaces the whole file; memory becomes the file's table (SPEC §3 a). A rejected text
    /// changes nothing. With `base_revision`, refused when the file changed since that revision.
    pub fn replace_offsets_file(
        &self,
        text: &str,
        base_revision: Option<&str>,
    ) -> Result<(), ControlError> {
        self.tables.replace_offsets_file(text, base_revision)
    }

    /// Looks at TAB0.KOR, the constants and the work offsets files on disk (the file watch of
    /// issue #31): a saved edit is loaded into memory, one that does not load is reported and
    /// memory kept.
    pub fn sync_files(&self) -> FilesSync {
        self.tables.sync_files()
    }

    /// The work offsets G54..G59.3 programs start with (the file's; G54 in force).
    pub fn work_offsets(&self) -> WorkOffsets {
        self.tables.work_offsets()
    }

    /// The work offsets file's text ("" without a file) and its revision, as last seen.
    pub fn work_offsets_file(&self) -> (String, String) {
        self.tables.work_offsets_file()
    }

    /// Operator edit of some axes of one work offset system: written to the file, on top of
    /// the file as it is on disk (a hand edit saved since is loaded first and kept). A
    /// running program keeps the offsets it started with.
    pub fn edit_work_offset(&self, edit: &WorkEdit) -> Result<(), ControlError> {
        self.tables.edit_work_offset(edit)
    }

    /// Reloads the table from its file (power-on semantics). Only on an idle machine.
    pub fn reload_offsets(&self) -> Result<(), ControlError> {
        self.rt.idle_or_refuse("reloading the offset table")?;
        self.tables.reload_offsets()
    }

    /// The constants as saved (the file; see [`needs_restart`] for those not yet in force).
    pub fn constants(&self) -> Constants {
        self.tables.constants()
    }

    /// The constants jobs start with now.
    pub fn constants_in_force(&self) -> Constants {
        self.tables.constants_in_force()
    }

    /// The axis programmed (and shown) as a diameter: the controlling axis R67 in force when
    /// `[kr] radius_input = "diameter"` (docs/lathe.md). Its machine coordinates are radii.
    pub fn diameter_axis(&self) -> Option<usize> {
        self.tables.diameter_axis()
    }

    /// Sets machine constants and saves the constants file. Only on an idle machine. Each is
    /// in force for every stage from the next start, except those of [`needs_restart`], which
    /// are saved and used from the next daemon start only. Refused (nothing changed) when the
    /// machine could not run with them. Returns the constants that need a restart.
    pub fn set_constants(&self, values: &[(u16, f64)]) -> Result<Vec<u16>, ControlError> {
        self.rt.idle_or_refuse("changing machine constants")?;
        self.tables.set_constants(values)
    }
}
