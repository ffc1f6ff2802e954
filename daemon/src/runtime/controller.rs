//! The controller: owns the RT thread, the loaded program and the planner threads, and offers
//! the operations the API calls. Everything here runs outside the RT thread.

use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use kernel::Diagnostic;
use kernel::block::Block;
use kernel::comp::CompConfig;
use kernel::plan::PlannerConfig;
use kernel::program::{self, Setup};
use kernel::units::{AxesMm, MAX_AXES};
use tokio::sync::watch;

use kernel::constants::{AXIS_CODES, Constants};
use kernel::kr::{Gear, Kr, KrConfig, RadiusInput};
use kernel::offsets::{OffsetTable, TableEdit};
use kernel::plc::{PlcError, PlcWrite};

use super::buses::open_bus;
use super::clock::{Clock, MonotonicClock};
use super::config::{Config, RadiusInputConfig};
use super::job::{self, JobLink, JobSpec};
use super::logging::BlockNo;
use super::pipeline;
use super::rt::{self, MachineState, RtCommand, RtCoreConfig, RtParts, Snapshot};
use super::storage::{self, OffsetStore, StorageError};

/// Segment ring capacity (planner → RT).
const SEGMENT_RING: usize = 4096;
/// Command ring capacity (API → RT).
const COMMAND_RING: usize = 64;

/// Which clock drives the tick loop of the RT thread. Simulated time is not a clock of the
/// threaded daemon: tests that need it step the RT core in the single-threaded harness
/// ([`super::harness`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClockKind {
    Monotonic,
}

/// A program that passed validation. Only its text is kept: blocks are streamed again when it
/// runs (a 1,000,000-block program needs no memory for its blocks).
pub struct LoadedProgram {
    pub name: String,
    pub text: Arc<str>,
    /// Number of blocks.
    pub block_count: u32,
    pub warnings: Vec<Diagnostic>,
    /// Where the axes were when it was validated: it runs from there.
    pub start: AxesMm,
    /// What it was interpreted with.
    pub setup: Setup,
}

impl LoadedProgram {
    /// The program's canonical blocks, interpreted again (for previews and diagnostics; costs
    /// memory in proportion to the program).
    pub fn blocks(&self) -> Vec<Block> {
        program::compile(&self.text, &self.setup).blocks
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
}

pub struct Controller {
    config: Config,
    commands: Mutex<rtrb::Producer<RtCommand>>,
    link: Arc<JobLink>,
    status: watch::Receiver<Snapshot>,
    program: Mutex<Option<Arc<LoadedProgram>>>,
    next_job: AtomicU32,
    run: Mutex<Option<Run>>,
    rt_thread: Mutex<Option<JoinHandle<()>>>,
    pump_stop: Arc<AtomicBool>,
    /// Last alarm raised outside the RT thread (e.g. a planning failure), for status.
    alarm: Arc<Mutex<Option<String>>>,
    /// Machine constants in force (SPEC §1) and whether they came from a file.
    constants: Mutex<(Constants, bool)>,
    /// TAB0.KOR: file and memory table (SPEC §3).
    offsets: Arc<Mutex<OffsetStore>>,
    /// Blocks of the running job near the executing one.
    recent: Arc<Mutex<pipeline::RecentBlocks>>,
}

struct Run {
    cancel: Arc<AtomicBool>,
    thread: JoinHandle<()>,
}

impl Controller {
    /// Opens the bus, starts the RT thread and the status pump.
    pub fn start(config: Config, clock: ClockKind) -> Result<Arc<Controller>, String> {
        let bus = open_bus(&config.bus, &config.axes, &config.sim)?;
        Self::start_with_bus(config, clock, bus)
    }

    /// As [`Controller::start`], on a bus the caller built (tests wrap the simulated bus to
    /// record every setpoint).
    pub fn start_with_bus(
        config: Config,
        clock: ClockKind,
        bus: Box<dyn hal::DriveBus>,
    ) -> Result<Arc<Controller>, String> {
        let axes = config.axes.len();
        if !bus.has_spindle() {
            // Said once here: the RT thread keeps computing the speed (KŘR, the PLC cells),
            // but the setpoint has no drive to go to (issue #7).
            tracing::warn!(
                bus = bus.name(),
                "no spindle drive configured on the bus: the spindle speed is computed but not sent to any drive"
            );
        }
        let (constants, offsets) = load_storage(&config)?;
        let core = rt_core_config(&config, &constants.0)?;
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
        let rt_cfg = config.rt.clone();
        let rt_thread = std::thread::Builder::new()
            .name("cnc-rt".into())
            .spawn(move || {
                prepare_rt_thread(rt_cfg.priority, rt_cfg.lock_memory);
                rt::run(parts);
            })
            .map_err(|e| format!("cannot start the real-time thread: {e}"))?;

        let (status_tx, status_rx) = watch::channel(initial);
        let pump_stop = Arc::new(AtomicBool::new(false));
        let stop = pump_stop.clone();
        let names = config.axis_names();
        std::thread::Builder::new()
            .name("cnc-status".into())
            .spawn(move || status_pump(&mut snap_out, &status_tx, &stop, &names))
            .map_err(|e| format!("cannot start the status thread: {e}"))?;

        Ok(Arc::new(Controller {
            config,
            commands: Mutex::new(cmd_tx),
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
            constants: Mutex::new(constants),
            offsets: Arc::new(Mutex::new(offsets)),
            recent: Arc::default(),
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

    /// Validates `text` and makes it the selected program. Nothing moves; on error the
    /// previously selected program stays selected.
    /// What the interpreter needs: axes, where they are, constants and the memory offset table.
    fn setup(&self) -> Setup {
        let mut setup = Setup::new(&self.config.axis_names());
        // Programs start where the axes are commanded now.
        setup.start = self.snapshot().commanded;
        setup.constants = self.constants.lock().unwrap().0.clone();
        setup.offsets = self.offsets.lock().unwrap().memory().clone();
        spindle_setup(&self.config, &mut setup);
        setup
    }

    /// Validates `text` through the whole kernel pipeline (interpretation, compensation,
    /// planning) and makes it the selected program. Nothing moves; on error the previously
    /// selected program stays selected.
    pub fn load_program(&self, name: &str, text: &str) -> Result<Arc<LoadedProgram>, ControlError> {
        let setup = self.setup();
        let v = pipeline::validate(text, &setup, self.comp_config(), self.planner_config());
        if v.has_errors() {
            return Err(ControlError::InvalidProgram(v.diagnostics));
        }
        let loaded = Arc::new(LoadedProgram {
            name: name.to_owned(),
            text: Arc::from(text),
            block_count: v.blocks,
            warnings: v.diagnostics,
            start: setup.start,
            setup,
        });
        let running = matches!(
            self.snapshot().state,
            MachineState::Running | MachineState::Hold | MachineState::Stopping
        );
        if running {
            return Err(ControlError::WrongState(
                "a program is running: stop it before loading another".into(),
            ));
        }
        *self.program.lock().unwrap() = Some(loaded.clone());
        Ok(loaded)
    }

    fn comp_config(&self) -> CompConfig {
        CompConfig::from_constants(&self.constants.lock().unwrap().0)
    }

    fn send(&self, cmd: RtCommand) -> Result<(), ControlError> {
        self.commands
            .lock()
            .unwrap()
            .push(cmd)
            .map_err(|_| ControlError::RtGone)
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

    /// Starts the selected program. Returns the job id.
    pub fn start_program(&self) -> Result<u32, ControlError> {
        let program = self
            .program()
            .ok_or_else(|| ControlError::WrongState("no program is loaded".into()))?;
        let mut run = self.run.lock().unwrap();
        let snap = self.idle_for_start()?;
        // Validated from where the axes were at loading; if they moved since (MDI, another
        // job), validate again from here so the run cannot fail half-way.
        let here = snap.commanded;
        if (0..self.config.axes.len()).any(|i| (program.start[i] - here[i]).abs() > 1e-9) {
            let v = self.validate_text(&program.text);
            if v.has_errors() {
                return Err(ControlError::InvalidProgram(v.diagnostics));
            }
        }
        let spec = JobSpec {
            job: 0,
            text: program.text.clone(),
            setup: self.setup(),
            planner: self.planner_config(),
            comp: self.comp_config(),
            offsets: self.offsets.clone(),
            stop_at_blocks: false,
            recent: self.recent.clone(),
            status: self.status.clone(),
        };
        self.spawn_job(&mut run, spec, &program.name, program.block_count)
    }

    /// Starts the planner thread of a new job and tells the RT thread to run it.
    fn spawn_job(
        &self,
        run: &mut Option<Run>,
        mut spec: JobSpec,
        name: &str,
        blocks: u32,
    ) -> Result<u32, ControlError> {
        let job = self.next_job.fetch_add(1, Ordering::Relaxed);
        spec.job = job;
        *self.alarm.lock().unwrap() = None;
        self.send(RtCommand::Start { job })?;
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

    fn planner_config(&self) -> PlannerConfig {
        let (constants, from_file) = &*self.constants.lock().unwrap();
        planner_config(&self.config, constants, *from_file)
    }

    /// Stops motion: brake on the path, drop the rest of the program.
    pub fn stop(&self) -> Result<(), ControlError> {
        if let Some(r) = self.run.lock().unwrap().as_ref() {
            r.cancel.store(true, Ordering::Relaxed);
        }
        self.send(RtCommand::Stop)
    }

    pub fn hold(&self) -> Result<(), ControlError> {
        self.send(RtCommand::Hold)
    }

    pub fn resume(&self) -> Result<(), ControlError> {
        self.send(RtCommand::Resume)
    }

    pub fn set_override(&self, percent: f64) -> Result<(), ControlError> {
        if !(0.0..=150.0).contains(&percent) {
            return Err(ControlError::WrongState(format!(
                "feed override {percent} % is outside 0..150 %"
            )));
        }
        self.send(RtCommand::Override(percent))
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

    /// Operator edit of one entry: file and memory (SPEC §3 b).
    pub fn edit_offset(&self, edit: &TableEdit) -> Result<(), ControlError> {
        Ok(self.offsets.lock().unwrap().operator_edit(edit)?)
    }

    /// Replaces the whole file; memory becomes the file's table (SPEC §3 a). A rejected text
    /// changes nothing.
    pub fn replace_offsets_file(&self, text: &str) -> Result<(), ControlError> {
        Ok(self.offsets.lock().unwrap().save_file_text(text)?)
    }

    /// Reloads the table from its file (power-on semantics).
    pub fn reload_offsets(&self) -> Result<(), ControlError> {
        self.idle_or_refuse("reloading the offset table")?;
        let path = self.config.storage.offsets_path();
        let fresh = OffsetStore::load_or_empty(path, &self.config.axis_names())?;
        *self.offsets.lock().unwrap() = fresh;
        Ok(())
    }

    pub fn constants(&self) -> Constants {
        self.constants.lock().unwrap().0.clone()
    }

    /// Sets machine constants and saves the constants file. Only on an idle machine: the
    /// planner and compensation read them when a program starts.
    pub fn set_constants(&self, values: &[(u16, f64)]) -> Result<(), ControlError> {
        self.idle_or_refuse("changing machine constants")?;
        let mut guard = self.constants.lock().unwrap();
        let mut next = guard.0.clone();
        for &(r, v) in values {
            if r > kernel::constants::MAX_R {
                return Err(ControlError::Invalid(format!(
                    "R{r} does not exist: constants are R0..R{}",
                    kernel::constants::MAX_R
                )));
            }
            next.set(r, v);
        }
        storage::save_constants(&self.config.storage.constants_path(), &next)?;
        *guard = (next, true);
        Ok(())
    }

    /// Writes a PLC input cell; in force from the next tick. Refusals change nothing.
    pub fn plc_write(&self, write: PlcWrite) -> Result<(), ControlError> {
        self.send(RtCommand::Plc(write))
    }

    // ---- API additions (issue #8): validation, preview configuration, MDI, single block ----

    /// Interprets `text` against the machine as it is now (axes, constants, memory offsets),
    /// without selecting or running it.
    pub fn compile_text(&self, text: &str) -> program::Compiled {
        program::compile(text, &self.setup())
    }

    /// What the interpreter would start a program with now (axes, position, constants, memory
    /// offsets), for previews.
    pub fn current_setup(&self) -> Setup {
        self.setup()
    }

    /// Compensation and planner settings a program started now would run with.
    pub fn run_configs(&self) -> (CompConfig, PlannerConfig) {
        let comp = CompConfig::from_constants(&self.constants.lock().unwrap().0);
        (comp, self.planner_config())
    }

    /// Single-block mode on the RT thread: hold when the path enters a new block.
    pub fn set_single_block(&self, on: bool) -> Result<(), ControlError> {
        self.send(RtCommand::SingleBlock(on))
    }

    /// Runs `text` as a job without changing the selected program (MDI, single-block runs).
    /// With `stop_at_blocks` every block ends at rest (G98), so single-block holds land on
    /// block ends. Returns the job id and the blocks it runs.
    pub fn start_text(
        &self,
        name: &str,
        text: &str,
        stop_at_blocks: bool,
    ) -> Result<(u32, Arc<Vec<Block>>), ControlError> {
        let mut run = self.run.lock().unwrap();
        self.idle_for_start()?;
        let setup = self.setup();
        let (comp, planner) = self.run_configs();
        let v = pipeline::validate(text, &setup, comp, planner.clone());
        if v.has_errors() {
            return Err(ControlError::InvalidProgram(v.diagnostics));
        }
        let mut blocks = program::compile(text, &setup).blocks;
        if stop_at_blocks {
            for b in &mut blocks {
                b.continuity = kernel::block::Continuity::G98;
            }
        }
        let spec = JobSpec {
            job: 0,
            text: Arc::from(text),
            setup,
            planner,
            comp,
            offsets: self.offsets.clone(),
            stop_at_blocks,
            recent: self.recent.clone(),
            status: self.status.clone(),
        };
        let job = self.spawn_job(&mut run, spec, name, v.blocks)?;
        Ok((job, Arc::new(blocks)))
    }

    /// Block `seq` of `job` if the job is running (or just ran) and the block is near the
    /// executing one: the modal state for status.
    pub fn block_at(&self, job: u32, seq: u32) -> Option<Block> {
        self.recent.lock().unwrap().get(job, seq)
    }

    /// Validates `text` through the whole pipeline against the machine as it is now, without
    /// selecting or running it.
    pub fn validate_text(&self, text: &str) -> pipeline::Validation {
        let (comp, planner) = self.run_configs();
        pipeline::validate(text, &self.setup(), comp, planner)
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

/// The planner settings of the machine: axis limits from the configuration, the envelope
/// settings from the constants when they came from a file.
pub(crate) fn planner_config(
    config: &Config,
    constants: &Constants,
    from_file: bool,
) -> PlannerConfig {
    let axes = &config.axes;
    // Path-level defaults from the slowest axis; per-axis limits then from each axis.
    let v_min = axes
        .iter()
        .map(|a| a.max_velocity_mm_min / 60.0)
        .fold(f64::INFINITY, f64::min);
    let a_min = axes
        .iter()
        .map(|a| a.max_accel_mm_s2)
        .fold(f64::INFINITY, f64::min);
    let mut cfg = PlannerConfig::uniform(axes.len(), v_min, a_min);
    for (i, a) in axes.iter().enumerate().take(MAX_AXES) {
        cfg.axis_v_max_mm_s[i] = a.max_velocity_mm_min / 60.0;
        cfg.axis_a_max_mm_s2[i] = a.max_accel_mm_s2;
        cfg.axis_j_max_mm_s3[i] = 50.0 * a.max_accel_mm_s2;
    }
    // The envelope settings (continuity, criteria, dynamic sets) come from the constants
    // when the machine has a constants file; otherwise the axis limits alone apply.
    if from_file {
        cfg = cfg.with_constants(constants);
    }
    cfg
}

/// What the RT core is built from: the axes at their home positions, KŘR from the constants
/// and the `[kr]` section, the in-position window of G24 (R06).
pub(crate) fn rt_core_config(config: &Config, c: &Constants) -> Result<RtCoreConfig, String> {
    let mut start = AxesMm::ZERO;
    for (i, a) in config.axes.iter().enumerate() {
        start[i] = a.home_mm;
    }
    Ok(RtCoreConfig {
        axes: config.axes.len(),
        start,
        kr: Kr::new(kr_config(config, c)?),
        in_position_mm: c.get(6).abs().max(1e-6),
    })
}

/// The KŘR configuration from the constants and the `[kr]` section.
pub(crate) fn kr_config(config: &Config, c: &Constants) -> Result<KrConfig, String> {
    let radius = match config.kr.radius_input {
        RadiusInputConfig::Diameter => RadiusInput::Diameter,
        RadiusInputConfig::Radius => RadiusInput::Radius,
    };
    KrConfig::from_constants(c, radius, gears(config))
        .map_err(|e| format!("constant cutting speed: {e}"))
}

/// The gear table of `[kr.gears]`.
fn gears(config: &Config) -> Vec<Gear> {
    config
        .kr
        .gears
        .iter()
        .map(|g| Gear {
            max_rpm: g.max_rpm,
            output_range: g.output_range,
            m_code: g.m_code,
        })
        .collect()
}

/// What the interpreter needs of the spindle and the feed: the gear table (an M code selects
/// the range whose `m_code` it is; feed per revolution is planned at a nominal speed capped
/// by its P) and the fastest axis speed as Vmax of the βmax warning (SPEC §5, §6).
pub(crate) fn spindle_setup(config: &Config, setup: &mut Setup) {
    setup.gears = gears(config);
    setup.max_feed_mm_min = config
        .axes
        .iter()
        .map(|a| a.max_velocity_mm_min)
        .fold(0.0, f64::max);
}

/// Creates the data directory and loads the constants and the offset table. A file that exists
/// but does not parse stops the start-up: running with wrong offsets scraps parts.
pub(crate) fn load_storage(config: &Config) -> Result<((Constants, bool), OffsetStore), String> {
    let st = &config.storage;
    std::fs::create_dir_all(&st.dir)
        .map_err(|e| format!("storage.dir: cannot create {}: {e}", st.dir.display()))?;
    let cpath = st.constants_path();
    let names = config.axis_names();
    let constants = if cpath.exists() {
        let c = storage::load_constants(&cpath).map_err(|e| e.to_string())?;
        // R0..R5 name the axes the programs use: they must be the configured ones.
        let named = c.axis_names();
        if named[..] != names[..] {
            return Err(format!(
                "{}: R0..R5 name the axes {} but the configuration has {}",
                cpath.display(),
                named.iter().collect::<String>(),
                names.iter().collect::<String>()
            ));
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
    let offsets = OffsetStore::load_or_empty(st.offsets_path(), &config.axis_names())
        .map_err(|e| e.to_string())?;
    tracing::info!(
        constants = %cpath.display(),
        from_file = constants.1,
        offsets = %st.offsets_path().display(),
        "data files loaded"
    );
    Ok((constants, offsets))
}

/// Start-up of the RT thread: real-time priority and locked memory where permitted.
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

/// Copies RT snapshots into the watch channel and logs state changes and alarms (formatting
/// happens here, never on the RT thread).
fn status_pump(
    out: &mut triple_buffer::Output<Snapshot>,
    tx: &watch::Sender<Snapshot>,
    stop: &AtomicBool,
    axis_names: &[char],
) {
    let mut last = *out.read();
    while !stop.load(Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(1));
        if !out.update() {
            continue;
        }
        let s = *out.output_buffer();
        if s.fault != last.fault
            && let Some(f) = s.fault
        {
            let axis = hal::fault_axis_label(f.axis, axis_names).unwrap_or_else(|| "-".into());
            tracing::error!(axis, node = ?f.node, block = %BlockNo(s.block_n), line = s.line, "alarm: {}", f.reason);
        }
        if s.state != last.state {
            tracing::info!(state = ?s.state, job = s.job, block = %BlockNo(s.block_n), line = s.line, "machine state");
        }
        last = s;
        tx.send_replace(s);
    }
}
