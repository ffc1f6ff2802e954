//! The controller: owns the RT thread, the loaded program and the planner threads, and offers
//! the operations the API calls. Everything here runs outside the RT thread.

use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use kernel::Diagnostic;
use kernel::block::Block;
use kernel::machine::{AxisLimits, MachineConfig, MachineSetup};
use kernel::pipeline::{self, Observer, Options, Validation};
use kernel::units::{AxesMm, MAX_AXES};
use tokio::sync::watch;

use kernel::constants::{AXIS_CODES, Constants};
use kernel::jog::{Jog, JogRequest};
use kernel::kr::{Gear, Kr, RadiusInput};
use kernel::offsets::{OffsetTable, TableEdit};
use kernel::plc::{PlcError, PlcWrite};

use super::buses::open_bus;
use super::clock::{Clock, MonotonicClock};
use super::config::{Config, RadiusInputConfig};
use super::homing;
use super::job::{self, JobLink, JobSpec};
use super::library::ProgramText;
use super::logging::BlockNo;
use super::pipeline::Execution;
use super::rt::{self, JobMachine, MachineState, RtCommand, RtCoreConfig, RtParts, Snapshot};
use super::storage::{self, ConstantsFile, DiskChange, OffsetStore, StorageError};

/// Segment ring capacity (planner → RT).
const SEGMENT_RING: usize = 4096;
/// Command ring capacity (API → RT).
const COMMAND_RING: usize = 64;
/// A continuous jog stops by itself unless renewed within this many ticks (0.5 s): the
/// dead-man of a client that goes away without a word (the API renews it every 100 ms).
pub const JOG_LEASE_TICKS: u32 = 125;

/// Which clock drives the tick loop of the RT thread. Simulated time is not a clock of the
/// threaded daemon: tests that need it step the RT core in the single-threaded harness
/// ([`super::harness`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClockKind {
    Monotonic,
}

/// A program that passed validation. Only its text is kept (in memory, or the open file of a
/// stored program): blocks are streamed again when it runs, so a program of any size needs no
/// memory for its blocks.
pub struct LoadedProgram {
    pub name: String,
    pub text: ProgramText,
    /// Number of blocks.
    pub block_count: u32,
    pub warnings: Vec<Diagnostic>,
    /// Where the axes were when it was validated.
    pub start: AxesMm,
    /// The setup generation it was validated with (see `Controller::generation`).
    generation: u64,
}

/// Why the controller did not start (the message names the key or file to fix).
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    /// The bus could not be opened (`open_bus`: the message names the interface or port).
    #[error(transparent)]
    Bus(#[from] super::buses::OpenBusError),
    #[error("storage.dir: cannot create {}: {source}", dir.display())]
    StorageDir {
        dir: std::path::PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The constants or offsets file exists but does not load.
    #[error(transparent)]
    Storage(#[from] storage::StorageError),
    #[error("{}: R0..R5 name the axes {named} but the configuration has {configured}", path.display())]
    AxisNames {
        path: std::path::PathBuf,
        named: String,
        configured: String,
    },
    #[error("constant cutting speed: {0}")]
    Kr(#[from] kernel::kr::KrConfigError),
    #[error("cannot start the real-time thread: {0}")]
    RtThread(#[source] std::io::Error),
    #[error("cannot start the status thread: {0}")]
    StatusThread(#[source] std::io::Error),
}

impl StartError {
    /// Stable code (tests and logs match it; the message may improve).
    pub fn code(&self) -> &'static str {
        match self {
            StartError::Bus(_) => "start_bus",
            StartError::StorageDir { .. } => "start_storage_dir",
            StartError::Storage(e) => e.code(),
            StartError::AxisNames { .. } => "start_axis_names",
            StartError::Kr(_) => "start_kr",
            StartError::RtThread(_) => "start_rt_thread",
            StartError::StatusThread(_) => "start_status_thread",
        }
    }
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

pub struct Controller {
    config: Config,
    /// The RT core's command ring, and how many commands were pushed into it.
    commands: Mutex<(rtrb::Producer<RtCommand>, u64)>,
    link: Arc<JobLink>,
    status: watch::Receiver<Snapshot>,
    program: Mutex<Option<Arc<LoadedProgram>>>,
    next_job: AtomicU32,
    run: Mutex<Option<Run>>,
    rt_thread: Mutex<Option<JoinHandle<()>>>,
    pump_stop: Arc<AtomicBool>,
    /// Last alarm raised outside the RT thread (e.g. a planning failure), for status.
    alarm: Arc<Mutex<Option<String>>>,
    /// Machine constants (SPEC §1).
    constants: Mutex<ConstantsState>,
    /// The configuration's part of every job's machine setup.
    machine: MachineConfig,
    /// TAB0.KOR: file and memory table (SPEC §3).
    offsets: Arc<Mutex<OffsetStore>>,
    /// The running job's pass: blocks near the executing one, pending `G92` writes, the modal
    /// state left for MDI.
    execution: Arc<Mutex<Execution>>,
    /// Increases whenever something a job's setup is built from changes (constants, offset
    /// table): a program validated under another generation is validated again at start.
    generation: Arc<AtomicU64>,
    /// See [`Controller::validation_passes`].
    validation_passes: AtomicU64,
    /// A feed hold was asked for and not yet resumed or stopped (the RT thread may not have
    /// published the hold yet).
    hold_requested: AtomicBool,
    /// The bus can run reference runs (homing).
    can_home: bool,
}

/// The constants: the file's, and those in force (the file's, except the constants that
/// need a restart, which keep their value from start-up until then).
struct ConstantsState {
    saved: Constants,
    in_force: Constants,
    from_file: bool,
    /// The file's text as a person wrote it (issue #31: edits go into it in place).
    file: ConstantsFile,
}

impl ConstantsState {
    /// A constants file saved by hand since it was last seen becomes the saved constants, in
    /// force at once except those of [`needs_restart`]. Returns whether it changed.
    fn sync_with_disk(&mut self) -> Result<bool, StorageError> {
        let Some(c) = self.file.sync_with_disk()? else {
            return Ok(false);
        };
        let mut in_force = c.clone();
        for r in (0..=kernel::constants::MAX_R).filter(|&r| needs_restart(r)) {
            in_force.set(r, self.in_force.get(r));
        }
        self.saved = c;
        self.in_force = in_force;
        self.from_file = true;
        Ok(true)
    }
}

/// What a look at the data files found (see [`Controller::sync_files`]): per file, whether a
/// saved edit was loaded, or why the file on disk does not load (the memory copy is kept).
#[derive(Debug)]
pub struct FilesSync {
    pub offsets: Result<bool, StorageError>,
    pub constants: Result<bool, StorageError>,
}

/// Constants read only at daemon start: axis codes R0..R5 (checked against the configured
/// axes). Changing them is saved, listed in `restart_required` and not used before.
pub fn needs_restart(r: u16) -> bool {
    r <= 5
}

struct Run {
    cancel: Arc<AtomicBool>,
    thread: JoinHandle<()>,
}

impl Controller {
    /// Opens the bus, starts the RT thread and the status pump.
    pub fn start(config: Config, clock: ClockKind) -> Result<Arc<Controller>, StartError> {
        let bus = open_bus(&config.bus, &config.axes, &config.sim).map_err(StartError::Bus)?;
        Self::start_with_bus(config, clock, bus)
    }

    /// As [`Controller::start`], on a bus the caller built (tests wrap the simulated bus to
    /// record every setpoint).
    pub fn start_with_bus(
        config: Config,
        clock: ClockKind,
        bus: Box<dyn hal::DriveBus>,
    ) -> Result<Arc<Controller>, StartError> {
        let axes = config.axes.len();
        let can_home = bus.supports_homing();
        warn_without_spindle(bus.as_ref());
        let (constants, offsets, constants_file) = load_storage(&config)?;
        let core = rt_core_config(&config, &constants, offsets.memory())?;
        let machine = machine_config(&config);
        let (cmd_tx, cmd_rx) = rtrb::RingBuffer::new(COMMAND_RING);
        let (seg_tx, seg_rx) = rtrb::RingBuffer::new(SEGMENT_RING);
        let initial = Snapshot::initial(axes, core.start);
        let (snap_in, mut snap_out) = triple_buffer::triple_buffer(&initial);
        let planned_job = Arc::new(AtomicU32::new(0));
        let clock: Box<dyn Clock> = match clock {
            ClockKind::Monotonic => Box::new(MonotonicClock),
        };
        let parts = RtParts {
            bus,
            clock,
            commands: cmd_rx,
            segments: seg_rx,
            status: snap_in,
            planned_job: planned_job.clone(),
            core,
        };
        let rt_thread = spawn_rt_thread(config.rt.priority, config.rt.lock_memory, parts)?;

        let (status_tx, status_rx) = watch::channel(initial);
        let pump_stop = Arc::new(AtomicBool::new(false));
        let stop = pump_stop.clone();
        let names = config.axis_names();
        let execution: Arc<Mutex<Execution>> = Arc::default();
        let offsets = Arc::new(Mutex::new(offsets));
        let generation = Arc::new(AtomicU64::new(0));
        let pump = Pump {
            execution: execution.clone(),
            offsets: offsets.clone(),
            generation: generation.clone(),
            axis_names: names,
        };
        std::thread::Builder::new()
            .name("cnc-status".into())
            .spawn(move || pump.run(&mut snap_out, &status_tx, &stop))
            .map_err(StartError::StatusThread)?;
        Ok(Arc::new(Controller {
            config,
            commands: Mutex::new((cmd_tx, 0)),
            link: Arc::new(JobLink {
                segments: Mutex::new(seg_tx),
                planned_job,
            }),
            status: status_rx,
            program: Mutex::new(None),
            next_job: AtomicU32::new(1),
            run: Mutex::new(None),
            rt_thread: Mutex::new(Some(rt_thread)),
            pump_stop,
            alarm: Arc::new(Mutex::new(None)),
            constants: Mutex::new(ConstantsState {
                saved: constants.0.clone(),
                in_force: constants.0,
                from_file: constants.1,
                file: constants_file,
            }),
            machine,
            offsets,
            execution,
            generation,
            validation_passes: AtomicU64::new(0),
            hold_requested: AtomicBool::new(false),
            can_home,
        }))
    }

    pub fn config(&self) -> &Config {
        &self.config
    }

    /// Latest snapshot.
    pub fn snapshot(&self) -> Snapshot {
        *self.status.borrow()
    }

    /// A receiver that sees every snapshot the pump publishes.
    pub fn subscribe(&self) -> watch::Receiver<Snapshot> {
        self.status.clone()
    }

    pub fn program(&self) -> Option<Arc<LoadedProgram>> {
        self.program.lock().unwrap().clone()
    }

    pub fn alarm(&self) -> Option<String> {
        self.alarm.lock().unwrap().clone()
    }

    /// The machine setup a job started now would take: the configuration, the constants in
    /// force and the memory offset table, decoded once (issue #14), from where the axes are
    /// commanded now.
    pub fn machine_setup(&self) -> Result<MachineSetup, ControlError> {
        let c = self.constants.lock().unwrap();
        let offsets = self.offsets.lock().unwrap();
        MachineSetup::new(
            &self.machine,
            &c.in_force,
            c.from_file,
            offsets.memory(),
            self.snapshot().commanded,
        )
        .map_err(|e| ControlError::Invalid(format!("constant cutting speed: {e}")))
    }

    /// The R325 listing of `text` under the setup in force (SPEC §4.6): the text with E
    /// written, the refinements, the program's messages.
    pub fn refinement_listing(
        &self,
        text: &str,
    ) -> Result<(String, Vec<kernel::program::arc::Refined>, Vec<Diagnostic>), ControlError> {
        let setup = self.machine_setup()?;
        Ok(kernel::program::refinement_listing(text, setup.program()))
    }

    /// Validates `text` through the whole pipeline (interpretation, compensation, planning)
    /// against the machine as it is now, passing what the stages produce to `obs`. Nothing is
    /// selected or run. The verdict of validate, upload, load, previews, start and MDI.
    pub fn validate_with(
        &self,
        text: &str,
        opts: Options,
        modal: Option<kernel::program::Modal>,
        obs: &mut impl Observer,
    ) -> Result<(Validation, MachineSetup, u64), ControlError> {
        self.validate_by(modal, |setup| {
            pipeline::validate_into(text, setup, opts, obs)
        })
    }

    /// As [`Controller::validate_with`] for a text in memory or a stored program's file
    /// (streamed line by line: memory bounded whatever its size).
    pub fn validate_program_with(
        &self,
        text: &ProgramText,
        opts: Options,
        obs: &mut impl Observer,
    ) -> Result<(Validation, MachineSetup, u64), ControlError> {
        self.validate_by(None, |setup| text.validate_into(setup, opts, obs))
    }

    /// The setup in force (with `modal`) and its generation, and `pass`'s verdict with it.
    fn validate_by(
        &self,
        modal: Option<kernel::program::Modal>,
        pass: impl FnOnce(&MachineSetup) -> Validation,
    ) -> Result<(Validation, MachineSetup, u64), ControlError> {
        let generation = self.generation.load(Ordering::Acquire);
        let setup = self.machine_setup()?.with_modal(modal);
        self.validation_passes.fetch_add(1, Ordering::Relaxed);
        let v = pass(&setup);
        Ok((v, setup, generation))
    }

    /// Validates `text` (see [`Controller::validate_program_with`]) into a program that may
    /// be selected; `obs` sees the pass. Errors: the program's diagnostics.
    pub fn prepare_program(
        &self,
        name: &str,
        text: ProgramText,
        obs: &mut impl Observer,
    ) -> Result<Arc<LoadedProgram>, ControlError> {
        let (v, setup, generation) = self.validate_program_with(&text, Options::default(), obs)?;
        if v.has_errors() {
            return Err(ControlError::InvalidProgram(v.diagnostics));
        }
        Ok(Arc::new(LoadedProgram {
            name: name.to_owned(),
            text,
            block_count: v.blocks,
            warnings: v.diagnostics,
            start: setup.program().start,
            generation,
        }))
    }

    /// Makes a validated program the selected one. Refused while a program runs.
    pub fn select(&self, loaded: Arc<LoadedProgram>) -> Result<(), ControlError> {
        let running = matches!(
            self.snapshot().state,
            MachineState::Running | MachineState::Hold | MachineState::Stopping
        );
        if running {
            return Err(ControlError::WrongState(
                "a program is running: stop it before loading another".into(),
            ));
        }
        *self.program.lock().unwrap() = Some(loaded);
        Ok(())
    }

    /// Validates `text` and makes it the selected program. Nothing moves; on error the
    /// previously selected program stays selected.
    pub fn load_program(&self, name: &str, text: &str) -> Result<Arc<LoadedProgram>, ControlError> {
        let text = ProgramText::Memory(Arc::from(text));
        let loaded = self.prepare_program(name, text, &mut NoObserver)?;
        self.select(loaded.clone())?;
        Ok(loaded)
    }

    fn send(&self, cmd: RtCommand) -> Result<(), ControlError> {
        self.send_counted(cmd).map(|_| ())
    }

    /// Sends `cmd`; its number: the core has acted on it once `Snapshot::commands_taken`
    /// reaches it.
    fn send_counted(&self, cmd: RtCommand) -> Result<u64, ControlError> {
        let mut ring = self.commands.lock().unwrap();
        ring.0.push(cmd).map_err(|_| ControlError::RtGone)?;
        ring.1 += 1;
        Ok(ring.1)
    }

    /// The latest snapshot if the machine is idle, the refusal to start otherwise.
    fn idle_for_start(&self) -> Result<Snapshot, ControlError> {
        let snap = self.snapshot();
        if snap.state != MachineState::Idle {
            return Err(ControlError::WrongState(format!(
                "the machine is {:?}, it must be idle to start",
                snap.state
            )));
        }
        Ok(snap)
    }

    /// Whether axis `i` is referenced: homed since power-on, or needing no reference run.
    pub fn axis_homed(&self, snap: &Snapshot, i: usize) -> bool {
        homing::axis_homed(&self.config, snap, i)
    }

    /// FAILED_PRECONDITION while an axis that needs a reference run has not had one.
    fn require_homed(&self, what: &str) -> Result<(), ControlError> {
        homing::require_homed(&self.config, &self.snapshot(), what)
    }

    /// Reference run of `axes` (all when empty), one axis after the other in the configured
    /// order. Returns the letters homed.
    pub async fn home(&self, axes: &str) -> Result<String, ControlError> {
        if !self.can_home {
            return Err(ControlError::WrongState(
                "this bus cannot run a reference run (serial: it needs an axis with \
                 homing = \"required\", which switches the link to protocol version 3)"
                    .into(),
            ));
        }
        let order = homing::homing_order(&self.config, axes)?;
        let mut done = String::new();
        for i in order {
            self.home_axis(i).await?;
            done.push(self.config.axes[i].name);
        }
        Ok(done)
    }

    async fn home_axis(&self, i: usize) -> Result<(), ControlError> {
        let snap = self.snapshot();
        if snap.state != MachineState::Idle {
            return Err(ControlError::WrongState(format!(
                "homing needs an idle machine; it is {:?}",
                snap.state
            )));
        }
        let sent = self.send_counted(RtCommand::Home(homing::home_request(&self.config, i)))?;
        let mut rx = self.subscribe();
        let bit = 1u8 << i;
        loop {
            let s = *rx.borrow_and_update();
            if s.commands_taken >= sent && s.state != MachineState::Homing {
                if s.homed & bit != 0 {
                    return Ok(());
                }
                return Err(homing::failure(&self.config, &s, i));
            }
            rx.changed().await.map_err(|_| ControlError::RtGone)?;
        }
    }

    /// Whether `program` was validated with the setup a job started now would take: the same
    /// constants and offsets (generation) and the same start position. Its load's pass is then
    /// the pass of the next start.
    pub fn validated_as_now(&self, program: &LoadedProgram, snap: &Snapshot) -> bool {
        let here = snap.commanded;
        let moved = (0..self.config.axes.len()).any(|i| (program.start[i] - here[i]).abs() > 1e-9);
        !moved && program.generation == self.generation.load(Ordering::Acquire)
    }

    /// Passes of the pipeline made for validation so far (validate, upload, load, previews
    /// of a text): tests see with it that a preview read load's pass instead of making one.
    pub fn validation_passes(&self) -> u64 {
        self.validation_passes.load(Ordering::Relaxed)
    }

    /// Counts a pass made outside [`Controller::validate_with`] (the preview crate's picture).
    pub fn count_validation_pass(&self) {
        self.validation_passes.fetch_add(1, Ordering::Relaxed);
    }

    /// Starts the selected program. Returns the job id.
    pub fn start_program(&self) -> Result<u32, ControlError> {
        self.require_homed("a program")?;
        let program = self
            .program()
            .ok_or_else(|| ControlError::WrongState("no program is loaded".into()))?;
        let mut run = self.run.lock().unwrap();
        let snap = self.idle_for_start()?;
        // The job's snapshot of the machine, taken now: every stage of the run reads it.
        let setup = self.machine_setup()?;
        // Validated with another setup (the axes moved by MDI or another job, constants or
        // offsets changed): validate again with this one, so the run cannot fail half-way.
        if !self.validated_as_now(&program, &snap) {
            let v = program
                .text
                .validate_into(&setup, Options::default(), &mut NoObserver);
            if v.has_errors() {
                return Err(ControlError::InvalidProgram(v.diagnostics));
            }
        }
        let spec = JobSpec {
            text: program.text.clone(),
            setup,
            opts: Options::default(),
            execution: self.execution.clone(),
            status: self.status.clone(),
        };
        self.spawn_job(&mut run, spec, &program.name, program.block_count)
    }

    /// Starts the planner thread of a new job and tells the RT thread to run it with the
    /// job's machine setup.
    fn spawn_job(
        &self,
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
        self.send(RtCommand::Start { job, machine })?;
        let cancel = Arc::new(AtomicBool::new(false));
        let link = self.link.clone();
        let c = cancel.clone();
        let alarm_slot = self.alarm.clone();
        let thread = std::thread::Builder::new()
            .name(format!("cnc-plan-{job}"))
            .spawn(move || {
                if let Err(d) = job::run(spec, &link, &c) {
                    tracing::error!(job, block = %BlockNo(d.block), line = d.line, "planning failed: {}", d.message);
                    *alarm_slot.lock().unwrap() = Some(d.to_string());
                }
            })
            .map_err(|e| ControlError::WrongState(format!("cannot start the planner: {e}")))?;
        tracing::info!(job, program = %name, blocks, "job started");
        *run = Some(Run { cancel, thread });
        Ok(job)
    }

    /// Stops motion: brake on the path, drop the rest of the program; the spindle stops once
    /// the axes are at rest. Never refused (a stop is always allowed, also to stop a spindle
    /// left turning on an idle machine).
    pub fn stop(&self) -> Result<(), ControlError> {
        if let Some(r) = self.run.lock().unwrap().as_ref() {
            r.cancel.store(true, Ordering::Relaxed);
        }
        self.hold_requested.store(false, Ordering::Relaxed);
        self.send(RtCommand::Stop)
    }

    /// A job was started and has neither ended nor been stopped: it runs, is held, or the RT
    /// thread has not taken its start yet.
    fn job_active(&self, snap: &Snapshot) -> bool {
        let last = self.next_job.load(Ordering::Relaxed).saturating_sub(1);
        let pending =
            last != 0 && snap.job != last && snap.finished_job != last && snap.aborted_job != last;
        pending
            || matches!(
                snap.state,
                MachineState::Running | MachineState::Hold | MachineState::Stopping
            )
    }

    /// Feed hold. FAILED_PRECONDITION when nothing runs.
    pub fn hold(&self) -> Result<(), ControlError> {
        let snap = self.snapshot();
        if !self.job_active(&snap) || snap.state == MachineState::Stopping {
            return Err(ControlError::WrongState(format!(
                "nothing runs to hold: the machine is {:?}",
                snap.state
            )));
        }
        self.hold_requested.store(true, Ordering::Relaxed);
        self.send(RtCommand::Hold)
    }

    /// Continues after a feed hold, a single-block hold or a program stop (M0/M1).
    /// FAILED_PRECONDITION when nothing is held (idle, after a stop, while stopping).
    pub fn resume(&self) -> Result<(), ControlError> {
        let snap = self.snapshot();
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
        self.send(RtCommand::Resume)
    }

    /// Start while held (feed hold or a program stop M0/M1) continues the job: returns its
    /// id; `None` when nothing is held.
    pub fn start_resumes(&self) -> Result<Option<u32>, ControlError> {
        let snap = self.snapshot();
        if snap.state != MachineState::Hold {
            return Ok(None);
        }
        self.hold_requested.store(false, Ordering::Relaxed);
        self.send(RtCommand::Resume)?;
        Ok(Some(snap.job))
    }

    /// Axis index of letter `axis`, or INVALID_ARGUMENT.
    fn axis_index(&self, axis: &str) -> Result<usize, ControlError> {
        homing::axis_index(&self.config, axis)
    }

    /// Jog speed in mm/s: the asked speed within the axis's maximum; 0 asks for 10 % of it.
    fn jog_speed(&self, axis: usize, speed_mm_min: f64) -> Result<f64, ControlError> {
        let max = self.config.axes[axis].max_velocity_mm_min;
        if !speed_mm_min.is_finite() || speed_mm_min < 0.0 {
            return Err(ControlError::Invalid(format!(
                "jog speed {speed_mm_min} mm/min must be positive"
            )));
        }
        let v = if speed_mm_min == 0.0 {
            0.1 * max
        } else {
            speed_mm_min.min(max)
        };
        Ok(v / 60.0)
    }

    /// Starts or renews a continuous jog of `axis` in direction `dir` (sign) at `speed_mm_min`.
    /// The real-time thread stops it by itself unless renewed within [`JOG_LEASE_TICKS`]
    /// (the dead-man). Returns the target: the soft limit in that direction.
    pub fn jog(&self, axis: &str, dir: i32, speed_mm_min: f64) -> Result<f64, ControlError> {
        let i = self.axis_index(axis)?;
        if dir == 0 {
            return Err(ControlError::Invalid(
                "jog direction must be +1 or -1".into(),
            ));
        }
        let speed = self.jog_speed(i, speed_mm_min)?;
        let snap = self.snapshot();
        if !self.axis_homed(&snap, i) {
            return Err(ControlError::WrongState(format!(
                "axis {} is not homed: its soft limits mean nothing yet, so it jogs only by \
                 steps until homed (cncctl home {})",
                self.config.axes[i].name, self.config.axes[i].name
            )));
        }
        if !matches!(snap.state, MachineState::Idle | MachineState::Jog) {
            return Err(ControlError::WrongState(format!(
                "jogging needs an idle machine; it is {:?}",
                snap.state
            )));
        }
        let a = &self.config.axes[i];
        let (lo, hi) = (
            a.soft_min_mm.unwrap_or(f64::NEG_INFINITY),
            a.soft_max_mm.unwrap_or(f64::INFINITY),
        );
        let target = Jog::continuous_target(snap.commanded[i], f64::from(dir.signum()), lo, hi);
        self.send(RtCommand::Jog(JogRequest {
            axis: i,
            target_mm: target,
            speed_mm_s: speed,
            accel_mm_s2: a.max_accel_mm_s2,
            lease_ticks: JOG_LEASE_TICKS,
        }))?;
        Ok(if dir > 0 { hi } else { lo })
    }

    /// Incremental jog: `step_mm` on `axis`, clamped to the soft limits. Returns the target.
    pub fn jog_step(
        &self,
        axis: &str,
        step_mm: f64,
        speed_mm_min: f64,
    ) -> Result<f64, ControlError> {
        let i = self.axis_index(axis)?;
        if !step_mm.is_finite() || step_mm == 0.0 {
            return Err(ControlError::Invalid(format!("jog step {step_mm} mm")));
        }
        let speed = self.jog_speed(i, speed_mm_min)?;
        let snap = self.snapshot();
        if snap.state != MachineState::Idle {
            return Err(ControlError::WrongState(format!(
                "a jog step needs an idle machine; it is {:?}",
                snap.state
            )));
        }
        let a = &self.config.axes[i];
        let here = snap.commanded[i];
        let mut target = here + step_mm;
        if let Some(hi) = a.soft_max_mm {
            target = target.min(hi.max(here));
        }
        if let Some(lo) = a.soft_min_mm {
            target = target.max(lo.min(here));
        }
        self.send(RtCommand::Jog(JogRequest {
            axis: i,
            target_mm: target,
            speed_mm_s: speed,
            accel_mm_s2: a.max_accel_mm_s2,
            lease_ticks: u32::MAX,
        }))?;
        Ok(target)
    }

    /// Brakes a jog to rest (the client let go, or went away).
    pub fn jog_stop(&self) -> Result<(), ControlError> {
        self.send(RtCommand::JogStop)
    }

    /// Optional stop switch: M1 stops the program only while it is on.
    pub fn set_optional_stop(&self, on: bool) -> Result<(), ControlError> {
        self.send(RtCommand::OptionalStop(on))
    }

    pub fn set_override(&self, percent: f64) -> Result<(), ControlError> {
        if !(0.0..=150.0).contains(&percent) {
            return Err(ControlError::WrongState(format!(
                "feed override {percent} % is outside 0..150 %"
            )));
        }
        self.send(RtCommand::Override(percent))
    }

    /// Spindle override, 50..120 % (issue #19): the RT core scales the commanded spindle
    /// speed within the gear range from the next tick.
    pub fn set_spindle_override(&self, percent: f64) -> Result<(), ControlError> {
        let range = kernel::kr::SPINDLE_OVERRIDE_PCT;
        if !range.contains(&percent) {
            return Err(ControlError::Invalid(format!(
                "spindle override {percent} % is outside {}..{} %",
                range.start(),
                range.end()
            )));
        }
        self.send(RtCommand::SpindleOverride(percent))
    }

    /// Rapid override, 0..100 % (issue #19): G0 moves run at this share of their speed.
    pub fn set_rapid_override(&self, percent: f64) -> Result<(), ControlError> {
        if !(0.0..=100.0).contains(&percent) {
            return Err(ControlError::Invalid(format!(
                "rapid override {percent} % is outside 0..100 %"
            )));
        }
        self.send(RtCommand::RapidOverride(percent))
    }

    /// Clears a fault and re-enables the drives.
    pub fn reset(&self) -> Result<(), ControlError> {
        if self.snapshot().state != MachineState::Fault {
            return Err(ControlError::WrongState(
                "there is no fault to reset".into(),
            ));
        }
        self.send(RtCommand::Reset)
    }

    fn idle_or_refuse(&self, what: &str) -> Result<(), ControlError> {
        match self.snapshot().state {
            MachineState::Idle | MachineState::Fault | MachineState::Enabling => Ok(()),
            s => Err(ControlError::WrongState(format!(
                "{what} needs an idle machine; it is {s:?}"
            ))),
        }
    }

    /// The memory offset table (what programs use).
    pub fn offsets_memory(&self) -> OffsetTable {
        self.offsets.lock().unwrap().memory().clone()
    }

    /// The offset table file as text.
    pub fn offsets_file_text(&self) -> String {
        self.offsets.lock().unwrap().file_text()
    }

    /// The revision of the offset table file's text (`storage::revision_of`).
    pub fn offsets_revision(&self) -> String {
        self.offsets.lock().unwrap().revision()
    }

    /// Operator edit of one entry: file and memory (SPEC §3 b), made on the file as it is on
    /// disk (a hand edit saved since is loaded first, issue #31).
    pub fn edit_offset(&self, edit: &TableEdit) -> Result<(), ControlError> {
        let r = self.offsets.lock().unwrap().operator_edit(edit);
        // A hand edit may have been loaded even when the edit itself was refused.
        self.generation.fetch_add(1, Ordering::AcqRel);
        Ok(r?)
    }

    /// Replaces the whole file; memory becomes the file's table (SPEC §3 a). A rejected text
    /// changes nothing. With `base_revision`, refused when the file changed since that revision.
    pub fn replace_offsets_file(
        &self,
        text: &str,
        base_revision: Option<&str>,
    ) -> Result<(), ControlError> {
        let r = self
            .offsets
            .lock()
            .unwrap()
            .replace_file_text(text, base_revision);
        self.generation.fetch_add(1, Ordering::AcqRel);
        Ok(r?)
    }

    /// Looks at TAB0.KOR and the constants file on disk (the file watch of issue #31): a saved
    /// edit is loaded into memory (SPEC §3: after every saved edit of the file), one that does
    /// not load is reported and memory kept. Blocks on disk IO.
    pub fn sync_files(&self) -> FilesSync {
        let offsets = self
            .offsets
            .lock()
            .unwrap()
            .sync_with_disk()
            .map(|c| c == DiskChange::Loaded);
        let constants = self.constants.lock().unwrap().sync_with_disk();
        if matches!(offsets, Ok(true)) || matches!(constants, Ok(true)) {
            self.generation.fetch_add(1, Ordering::AcqRel);
        }
        FilesSync { offsets, constants }
    }

    /// Reloads the table from its file (power-on semantics).
    pub fn reload_offsets(&self) -> Result<(), ControlError> {
        self.idle_or_refuse("reloading the offset table")?;
        let path = self.config.storage.offsets_path();
        let fresh = OffsetStore::load_or_empty(path, &self.config.axis_names())?;
        *self.offsets.lock().unwrap() = fresh;
        self.generation.fetch_add(1, Ordering::AcqRel);
        Ok(())
    }

    /// The constants as saved (the file; see [`needs_restart`] for those not yet in force).
    pub fn constants(&self) -> Constants {
        self.constants.lock().unwrap().saved.clone()
    }

    /// The constants jobs start with now.
    pub fn constants_in_force(&self) -> Constants {
        self.constants.lock().unwrap().in_force.clone()
    }

    /// The axis programmed (and shown) as a diameter: the controlling axis R67 in force when
    /// `[kr] radius_input = "diameter"` (docs/lathe.md). Its machine coordinates are radii.
    pub fn diameter_axis(&self) -> Option<usize> {
        if self.config.kr.radius_input != RadiusInputConfig::Diameter {
            return None;
        }
        let letter = {
            let c = self.constants.lock().unwrap();
            kernel::kr::config::controlling_axis_letter(&c.in_force)?
        };
        self.config.axes.iter().position(|a| a.name == letter)
    }

    /// Sets machine constants and saves the constants file. Only on an idle machine. Each is
    /// in force for every stage from the next start, except those of [`needs_restart`], which
    /// are saved and used from the next daemon start only. Refused (nothing changed) when the
    /// machine could not run with them. Returns the constants that need a restart.
    pub fn set_constants(&self, values: &[(u16, f64)]) -> Result<Vec<u16>, ControlError> {
        self.idle_or_refuse("changing machine constants")?;
        let mut guard = self.constants.lock().unwrap();
        // Made on top of the file as it is on disk (issue #31).
        if guard.sync_with_disk()? {
            self.generation.fetch_add(1, Ordering::AcqRel);
        }
        let mut saved = guard.saved.clone();
        let mut in_force = guard.in_force.clone();
        let mut restart = Vec::new();
        for &(r, v) in values {
            if r > kernel::constants::MAX_R {
                return Err(ControlError::Invalid(format!(
                    "R{r} does not exist: constants are R0..R{}",
                    kernel::constants::MAX_R
                )));
            }
            saved.set(r, v);
            if needs_restart(r) {
                if !restart.contains(&r) {
                    restart.push(r);
                }
            } else {
                in_force.set(r, v);
            }
        }
        // The next job's setup must build with them (KŘR refuses some values).
        MachineSetup::new(
            &self.machine,
            &in_force,
            true,
            &OffsetTable::new(),
            AxesMm::ZERO,
        )
        .map_err(|e| ControlError::Invalid(format!("constant cutting speed: {e}")))?;
        let milli: Vec<(u16, i64)> = values.iter().map(|&(r, _)| (r, saved.milli(r))).collect();
        let saved = guard.file.set(&saved, &milli)?;
        guard.saved = saved;
        guard.in_force = in_force;
        guard.from_file = true;
        self.generation.fetch_add(1, Ordering::AcqRel);
        Ok(restart)
    }

    /// Writes a PLC input cell; in force from the next tick. Refusals change nothing.
    pub fn plc_write(&self, write: PlcWrite) -> Result<(), ControlError> {
        self.send(RtCommand::Plc(write))
    }

    // ---- API additions (issue #8): validation, MDI, single block ----

    /// Single-block mode on the RT thread: hold when the path enters a new block.
    pub fn set_single_block(&self, on: bool) -> Result<(), ControlError> {
        self.send(RtCommand::SingleBlock(on))
    }

    /// Runs `text` as a job without changing the selected program (MDI, single-block runs).
    /// With `stop_at_blocks` every block ends at rest (G98), so single-block holds land on
    /// block ends. MDI (`mdi`) starts in the modal state the last program or MDI left.
    /// Returns the job id and the blocks it runs.
    pub fn start_text(
        &self,
        name: &str,
        text: &str,
        stop_at_blocks: bool,
        mdi: bool,
    ) -> Result<(u32, Arc<Vec<Block>>), ControlError> {
        self.require_homed("MDI")?;
        let mut run = self.run.lock().unwrap();
        self.idle_for_start()?;
        let opts = Options {
            job: 0,
            stop_at_blocks,
        };
        let modal = if mdi {
            self.execution.lock().unwrap().modal_left()
        } else {
            None
        };
        let mut blocks = Blocks::default();
        let (v, setup, _) = self.validate_with(text, opts, modal, &mut blocks)?;
        if v.has_errors() {
            return Err(ControlError::InvalidProgram(v.diagnostics));
        }
        let spec = JobSpec {
            text: ProgramText::Memory(Arc::from(text)),
            setup,
            opts,
            execution: self.execution.clone(),
            status: self.status.clone(),
        };
        let job = self.spawn_job(&mut run, spec, name, v.blocks)?;
        Ok((job, Arc::new(blocks.0)))
    }

    /// Block `seq` of `job` if the job is running (or just ran) and the block is near the
    /// executing one: the modal state for status.
    pub fn block_at(&self, job: u32, seq: u32) -> Option<Block> {
        self.execution.lock().unwrap().block(job, seq)
    }

    /// Validates `text` through the whole pipeline against the machine as it is now, without
    /// selecting or running it.
    pub fn validate_text(&self, text: &str) -> Result<Validation, ControlError> {
        Ok(self
            .validate_with(text, Options::default(), None, &mut NoObserver)?
            .0)
    }

    /// Brings the axes to rest and ends the RT thread (SIGTERM/SIGINT path). Blocking.
    pub fn shutdown(&self) {
        if let Some(r) = self.run.lock().unwrap().as_ref() {
            r.cancel.store(true, Ordering::Relaxed);
        }
        let _ = self.send(RtCommand::Shutdown);
        if let Some(t) = self.rt_thread.lock().unwrap().take() {
            let _ = t.join();
        }
        if let Some(r) = self.run.lock().unwrap().take() {
            let _ = r.thread.join();
        }
        // Let the pump publish the final snapshot before it ends.
        std::thread::sleep(Duration::from_millis(10));
        self.pump_stop.store(true, Ordering::Relaxed);
    }
}

impl Drop for Controller {
    fn drop(&mut self) {
        self.pump_stop.store(true, Ordering::Relaxed);
    }
}

/// Fault-reaction deceleration of each axis (`stop_decel_mm_s2`, else its acceleration).
fn stop_decel(config: &Config) -> [f64; MAX_AXES] {
    let mut d = [f64::INFINITY; MAX_AXES];
    for (i, a) in config.axes.iter().enumerate().take(MAX_AXES) {
        d[i] = a.stop_decel();
    }
    d
}

/// What the RT core is built from: the axes at their home positions, KŘR and the G24 window
/// of the machine setup at start-up (each job's Start brings its own, see [`JobMachine`]).
pub(crate) fn rt_core_config(
    config: &Config,
    constants: &(Constants, bool),
    offsets: &OffsetTable,
) -> Result<RtCoreConfig, StartError> {
    let mut start = AxesMm::ZERO;
    for (i, a) in config.axes.iter().enumerate() {
        start[i] = a.home_mm;
    }
    let setup = MachineSetup::new(
        &machine_config(config),
        &constants.0,
        constants.1,
        offsets,
        start,
    )?;
    Ok(RtCoreConfig {
        axes: config.axes.len(),
        start,
        kr: Kr::new(setup.kr().cloned().expect("the daemon's setup has KŘR")),
        in_position_mm: setup.in_position_mm(),
        stop_decel_mm_s2: stop_decel(config),
        cycle_ns: config.bus.cycle_ns(),
    })
}

/// The configuration's part of the machine setup: axis limits, gear table, radius input.
pub(crate) fn machine_config(config: &Config) -> MachineConfig {
    let radius_input = match config.kr.radius_input {
        RadiusInputConfig::Diameter => RadiusInput::Diameter,
        RadiusInputConfig::Radius => RadiusInput::Radius,
    };
    MachineConfig {
        axes: config
            .axes
            .iter()
            .map(|a| AxisLimits {
                name: a.name,
                max_velocity_mm_min: a.max_velocity_mm_min,
                max_accel_mm_s2: a.max_accel_mm_s2,
            })
            .collect(),
        gears: config
            .kr
            .gears
            .iter()
            .map(|g| Gear {
                max_rpm: g.max_rpm,
                output_range: g.output_range,
                m_code: g.m_code,
            })
            .collect(),
        radius_input,
        rotary_pulses_per_rev: config
            .axes
            .iter()
            .map(|a| a.rotary_pulses_per_rev)
            .collect(),
        ij: config.program.ij.into(),
        preprocessor: true,
        min_block_time_s: config.planner.min_block_time_ms / 1000.0,
        soft_limits: config.soft_limits(),
    }
}

/// An observer that keeps nothing (the validation is returned separately).
struct NoObserver;

impl Observer for NoObserver {
    fn segment(&mut self, _s: kernel::plan::Segment) -> pipeline::Flow {
        pipeline::Flow::Go
    }
}

/// Keeps the programmed blocks (MDI and single-block runs: status shows their modal state).
#[derive(Default)]
struct Blocks(Vec<Block>);

impl Observer for Blocks {
    fn programmed(&mut self, b: &Block, _modal: &kernel::program::Modal) {
        self.0.push(*b);
    }
    fn segment(&mut self, _s: kernel::plan::Segment) -> pipeline::Flow {
        pipeline::Flow::Go
    }
}

/// Creates the data directory and loads the constants and the offset table. A file that exists
/// but does not parse stops the start-up: running with wrong offsets scraps parts.
pub(crate) fn load_storage(
    config: &Config,
) -> Result<((Constants, bool), OffsetStore, ConstantsFile), StartError> {
    let st = &config.storage;
    std::fs::create_dir_all(&st.dir).map_err(|source| StartError::StorageDir {
        dir: st.dir.clone(),
        source,
    })?;
    let cpath = st.constants_path();
    let names = config.axis_names();
    let (constants_file, from_file) = ConstantsFile::open(&cpath)?;
    let constants = if let Some(c) = from_file {
        // R0..R5 name the axes the programs use: they must be the configured ones.
        let named = c.axis_names();
        if named[..] != names[..] {
            return Err(StartError::AxisNames {
                path: cpath,
                named: named.iter().collect(),
                configured: names.iter().collect(),
            });
        }
        (c, true)
    } else {
        // Defaults, with the axes of the configuration in R0..R5.
        let mut c = Constants::new();
        for r in 0..6u16 {
            let code = names
                .get(r as usize)
                .and_then(|n| AXIS_CODES.iter().position(|a| a == n))
                .map_or(0.0, |k| (k + 1) as f64);
            c.set(r, code);
        }
        (c, false)
    };
    let offsets = OffsetStore::load_or_empty(st.offsets_path(), &config.axis_names())?;
    tracing::info!(
        constants = %cpath.display(),
        from_file = constants.1,
        offsets = %st.offsets_path().display(),
        "data files loaded"
    );
    Ok((constants, offsets, constants_file))
}

/// Start-up of the RT thread: real-time priority and locked memory where permitted.
/// Said once at start-up: the RT thread keeps computing the spindle speed (KŘR, the PLC
/// cells), but the setpoint has no drive to go to (issue #7).
fn warn_without_spindle(bus: &dyn hal::DriveBus) {
    if !bus.has_spindle() {
        tracing::warn!(
            bus = bus.name(),
            "no spindle drive configured on the bus: the spindle speed is computed but not sent to any drive"
        );
    }
}

/// Starts the real-time thread on `parts` (priority and memory locking first).
fn spawn_rt_thread(
    priority: i32,
    lock_memory: bool,
    parts: RtParts,
) -> Result<JoinHandle<()>, StartError> {
    std::thread::Builder::new()
        .name("cnc-rt".into())
        .spawn(move || {
            prepare_rt_thread(priority, lock_memory);
            rt::run(parts);
        })
        .map_err(StartError::RtThread)
}

fn prepare_rt_thread(priority: i32, lock: bool) {
    match rt::set_realtime_priority(priority) {
        Ok(()) => tracing::info!(priority, "real-time thread runs SCHED_FIFO"),
        Err(e) => tracing::warn!(
            "real-time thread runs without SCHED_FIFO priority {priority} ({e}): expect timing \
             jitter; run as root or grant CAP_SYS_NICE / LimitRTPRIO"
        ),
    }
    if lock {
        match rt::lock_memory() {
            Ok(()) => tracing::info!("memory locked (mlockall)"),
            Err(e) => tracing::warn!(
                "memory not locked ({e}): page faults may delay ticks; grant CAP_IPC_LOCK / \
                 LimitMEMLOCK"
            ),
        }
    }
}

/// The status thread: copies RT snapshots into the watch channel, follows execution (`G92`
/// writes apply when their block executes, SPEC §3 c) and logs state changes and alarms
/// (formatting happens here, never on the RT thread).
pub(crate) struct Pump {
    pub(crate) execution: Arc<Mutex<Execution>>,
    pub(crate) offsets: Arc<Mutex<OffsetStore>>,
    pub(crate) generation: Arc<AtomicU64>,
    pub(crate) axis_names: Vec<char>,
}

impl Pump {
    fn run(
        &self,
        out: &mut triple_buffer::Output<Snapshot>,
        tx: &watch::Sender<Snapshot>,
        stop: &AtomicBool,
    ) {
        let mut last = *out.read();
        while !stop.load(Ordering::Relaxed) {
            std::thread::sleep(Duration::from_millis(1));
            if !out.update() {
                continue;
            }
            let s = *out.output_buffer();
            self.log_changes(&last, &s);
            // Before the snapshot is published: who sees the job ended sees its writes.
            self.apply_executed_writes(&s);
            last = s;
            tx.send_replace(s);
        }
    }

    pub(crate) fn apply_executed_writes(&self, s: &Snapshot) {
        let mut applied = false;
        // Lock order: execution, then offsets (nothing takes them the other way round).
        let mut execution = self.execution.lock().unwrap_or_else(|e| e.into_inner());
        execution.observe(s, |w| {
            let mut offsets = self.offsets.lock().unwrap_or_else(|e| e.into_inner());
            // Validated by the interpreter with the same table; a refusal here means the
            // table changed under the program (operator edit): say so, keep running.
            if let Err(m) = offsets.program_write(&w.edit) {
                tracing::error!(block = %BlockNo(w.n), line = w.line, "G92 write not applied: {m}");
            }
            applied = true;
        });
        if applied {
            self.generation.fetch_add(1, Ordering::AcqRel);
        }
    }

    fn log_changes(&self, last: &Snapshot, s: &Snapshot) {
        if s.fault != last.fault
            && let Some(f) = s.fault
        {
            let axis =
                hal::fault_axis_label(f.axis, &self.axis_names).unwrap_or_else(|| "-".into());
            tracing::error!(axis, node = ?f.node, block = %BlockNo(s.block_n), line = s.line, "alarm: {}", f.reason);
        }
        if s.state != last.state {
            tracing::info!(state = ?s.state, job = s.job, block = %BlockNo(s.block_n), line = s.line, "machine state");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A start-up that cannot use its storage says why, with a code per cause.
    #[test]
    fn storage_refusals_at_start_have_codes() {
        let base = std::env::temp_dir().join(format!("cnc-start-{}", std::process::id()));
        std::fs::create_dir_all(&base).unwrap();
        let mut config = Config::default();
        // The data directory is a file: it cannot be created.
        let file = base.join("plain-file");
        std::fs::write(&file, "x").unwrap();
        config.storage.dir = file;
        let e = load_storage(&config).err().unwrap();
        assert_eq!(e.code(), "start_storage_dir", "{e}");
        // An offset table that does not parse stops the start-up.
        config.storage.dir = base.join("data");
        std::fs::create_dir_all(&config.storage.dir).unwrap();
        std::fs::write(config.storage.offsets_path(), "not an offset table\n").unwrap();
        let e = load_storage(&config).err().unwrap();
        assert_eq!(e.code(), "storage_invalid", "{e}");
        std::fs::remove_dir_all(&base).unwrap();
    }
}
