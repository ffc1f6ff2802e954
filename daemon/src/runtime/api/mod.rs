//! The gRPC API (`cnc.v1`) over the [`Controller`]: services `Machine` (programs, control,
//! status, alarms), `Offsets`, `Plc`, `Constants` and `Preview`.
//!
//! Every RPC first checks the caller's role ([`auth::require`]); the API never blocks the RT
//! thread: it sends `RtCommand`s and reads snapshots. CPU or disk work (parsing, planning,
//! file writes) runs in `spawn_blocking`.

pub mod alarms;
pub mod auth;
mod diagnostics;
pub mod files_watch;
pub(crate) mod fuzz_rig;
mod interpret;
pub mod io;
pub mod job_journal;
mod job_view;
mod jog;
mod machine;
pub mod preview;
mod preview_outline;
mod probe;
mod programs;
mod receiving;
mod stream_budget;
mod tables;
mod touch_off;
mod trajectory;
pub mod upload_fuzz;
pub mod upload_session;
mod validate_stream;
pub mod velocity_plots;

use std::sync::Arc;

use proto::v1 as pb;
use tonic::Status;

use kernel::block::{ArcDir, Block, BlockKind, Comp, Continuity, Feed, Path, Plane};
use kernel::plc::CellId;
use kernel::program::Dialect;

use super::controller::{Controller, LoadedProgram};
use super::library::{Library, ProgramText};
use super::rt::{MachineState, Snapshot};

use job_view::{JobView, PlanInfo, RunInfo, RunMode};
use stream_budget::StreamBudget;

pub use diagnostics::{
    DETAILS_MAX_BYTES, bounded_details, counts_pb, diagnostic_to_pb, invalid_with_diagnostics,
    refused, status_of,
};
pub use machine::MachineSvc;
pub use preview::PreviewSvc;
pub use programs::ProgramsSvc;
pub use tables::{ConstantsSvc, OffsetsSvc, PlcSvc};
pub use trajectory::TrajectorySvc;

/// Highest status stream rate: one snapshot per tick.
pub const MAX_STATUS_HZ: u32 = 250;
const DEFAULT_STATUS_HZ: u32 = 25;
/// Programs larger than this are not planned at load for the status junction field.
const JUNCTION_CLASSIFY_MAX_BLOCKS: usize = 200_000;

/// Why the state shared by the services could not be built.
#[derive(Debug, thiserror::Error)]
pub enum ApiStateError {
    #[error("storage.programs_dir: cannot open {}: {source}", dir.display())]
    Library {
        dir: std::path::PathBuf,
        #[source]
        source: std::io::Error,
    },
}

impl ApiStateError {
    /// Stable code (tests and logs match it; the message may improve).
    pub fn code(&self) -> &'static str {
        match self {
            ApiStateError::Library { .. } => "api_library",
        }
    }
}

/// State shared by every service, by concern: the controller it drives, the program library,
/// the alarm log, unary uploads, the open streams, the jog sources and the API's view of jobs.
pub struct ApiState {
    pub ctl: Arc<Controller>,
    library: Arc<Library>,
    pub alarms: Arc<alarms::AlarmLog>,
    /// Unary uploads in progress (`Programs.UploadBegin`..`UploadFinish`).
    pub uploads: Arc<upload_session::UploadSessions>,
    /// Status and alarm streams: their budget and their end at shutdown.
    streams: StreamBudget,
    /// The streamed and the leased continuous jog (issue #31: one motion source at a time).
    jog: jog::JogSources,
    /// The selection's recorded pass, the started job, single block, the start lock.
    job: JobView,
    /// The inputs and outputs as the configuration names them (docs/io.md).
    pub io: io::IoCatalogue,
    /// `GetPreview`'s velocity plots: one at a time, bounded in machining time.
    pub velocity_plots: velocity_plots::VelocityPlots,
}

impl ApiState {
    /// Builds the state and starts the alarm watcher (needs a tokio runtime).
    pub fn new(ctl: Arc<Controller>) -> Result<Arc<ApiState>, ApiStateError> {
        let api = &ctl.config().api;
        let st = &ctl.config().storage;
        let library =
            Library::open(&st.programs_path(), st.programs_max_bytes).map_err(|source| {
                ApiStateError::Library {
                    dir: st.programs_path(),
                    source,
                }
            })?;
        let alarms = Arc::new(alarms::AlarmLog::persistent(
            api.alarm_history as usize,
            st.dir.join(alarms::HISTORY_FILE),
        ));
        let streams = StreamBudget::new(api.max_streams as usize, api.reserved_streams as usize);
        let io = io::IoCatalogue::of(ctl.config());
        let api_plot_ticks = api.velocity_plot_max_ticks();
        let state = Arc::new(ApiState {
            ctl,
            library: Arc::new(library),
            alarms,
            uploads: upload_session::UploadSessions::start(),
            streams,
            jog: jog::JogSources::default(),
            job: JobView::new(),
            io,
            velocity_plots: velocity_plots::VelocityPlots::new(api_plot_ticks),
        });
        alarms::spawn_watcher(state.ctl.clone(), state.alarms.clone());
        files_watch::spawn(state.ctl.clone(), state.alarms.clone());
        job_journal::spawn(Arc::downgrade(&state));
        io::spawn_cycle_start(Arc::downgrade(&state));
        // The program selected before the restart is selected again (validated, not started).
        let st = state.clone();
        tokio::task::spawn_blocking(move || programs::restore_selection(&st));
        Ok(state)
    }

    /// Waits until the RT thread has taken job `job` (at most a few ticks).
    async fn wait_started(&self, job: u32) {
        let t0 = std::time::Instant::now();
        while self.ctl.snapshot().progress.job != job
            && t0.elapsed() < std::time::Duration::from_secs(1)
        {
            tokio::time::sleep(std::time::Duration::from_millis(1)).await;
        }
    }

    /// Ends every open stream (shutdown): the HTTP/2 graceful shutdown waits for open responses,
    /// so a status stream left open would keep the daemon alive until systemd's SIGKILL.
    pub fn close_streams(&self) {
        self.streams.close();
    }

    /// Open status and alarm streams.
    pub fn open_streams(&self) -> usize {
        self.streams.open()
    }

    /// Builds the API status message from a snapshot.
    pub fn status(&self, s: &Snapshot) -> pb::Status {
        let ctl = &self.ctl;
        let program = ctl.program();
        let (mode, run_blocks) = self.job.run_of(s.progress.job);
        let total = match (&run_blocks, &program) {
            (Some(b), _) => b.len() as u32,
            (None, Some(p)) => p.block_count,
            _ => 0,
        };
        let running = matches!(
            s.state,
            MachineState::Running | MachineState::Hold | MachineState::Stopping
        );
        let block = match &run_blocks {
            Some(b) => b.get(s.progress.block_seq as usize).copied(),
            None => self.program_block(s, program.is_some()),
        };
        // Distance to go: only while a block moves (its end point is where the path goes).
        let target = block
            .filter(|_| running)
            .and_then(|b| b.motion())
            .map(|(_, end, _)| end);
        let junction = match (&run_blocks, &program) {
            (None, Some(p)) if s.progress.job != 0 => self
                .job
                .junction_of(Arc::as_ptr(p) as *const () as usize, s.progress.block_seq),
            _ => pb::JunctionClass::Unspecified,
        };
        let (feed_programmed, feed_mode) = feed_of(block.map(|b| b.feed));
        let plc = &s.plc;
        pb::Status {
            state: state_to_pb(s.state) as i32,
            program: program_name(mode, program.as_deref()),
            block: s.progress.block_n,
            line: s.progress.line,
            block_index: s.progress.block_seq,
            blocks_total: total,
            percent: percent_done(s, total, running),
            axes: self.axes_status(s, target),
            path_velocity_mm_s: s.axes.path_v_mm_s,
            ticks: Some(tick_stats(s)),
            sequence: s.tick.sequence,
            job: s.progress.job,
            alarm: alarm_text(ctl, s).unwrap_or_default(),
            finished_job: s.progress.finished_job,
            aborted_job: s.progress.aborted_job,
            override_percent: s.operator.feed_override_pct,
            spindle_override_percent: s.operator.spindle_override_pct,
            rapid_override_percent: s.operator.rapid_override_pct,
            spindle_rpm: s.spindle.rpm,
            mode: mode.to_pb() as i32,
            single_block: s.operator.single_block,
            feed_programmed,
            feed_mode: feed_mode.into(),
            modal_g_codes: block.map(|b| modal_codes(&b)).unwrap_or_default(),
            compensation: block.map(|b| compensation_of(b.comp)),
            junction: junction as i32,
            kr: Some(kr_status(plc)),
            active_alarms: self.alarms.active(),
            dynamic_set: plc.dynam_set().into(),
            waiting_for_spindle: s.spindle.waiting,
            optional_stop: s.operator.optional_stop,
            program_stop: s.progress.program_stop,
            fault_path_deviation_mm: s.alarm.fault_path_deviation_mm,
            block_delete: ctl.block_delete(),
            restart_block: restart_block(s, block.as_ref()),
            block_finished: s.progress.block_stop.then_some(pb::FinishedBlock {
                block: s.progress.block_n,
                line: s.progress.line,
                block_index: s.progress.block_seq,
            }),
            io: Some(self.io.list(s, ctl.simulated())),
            tool_change: s
                .progress
                .tool_change
                .map(|tool| self.tool_change_prompt(tool)),
        }
    }

    /// The block a job of the selected program executes (`selected`: a program is selected).
    fn program_block(&self, s: &Snapshot, selected: bool) -> Option<Block> {
        if selected && s.progress.job != 0 {
            self.ctl.block_at(s.progress.job, s.progress.block_seq)
        } else {
            None
        }
    }

    /// The manual tool change's prompt: the tool and its entry of the offset table.
    fn tool_change_prompt(&self, tool: u8) -> pb::ToolChange {
        let e = self
            .ctl
            .offsets_memory()
            .entry(tool)
            .copied()
            .unwrap_or_default();
        pb::ToolChange {
            tool: tool.into(),
            radius_mm: e.radius_mm,
            length_mm: e.length_mm.to_vec(),
        }
    }

    /// Per-axis status; `target` is the end point of the moving block (distance to go).
    fn axes_status(
        &self,
        s: &Snapshot,
        target: Option<kernel::units::AxesMm>,
    ) -> Vec<pb::AxisStatus> {
        let ctl = &self.ctl;
        let names = ctl.config().axis_names();
        let diameter_axis = ctl.diameter_axis();
        (0..s.axes.count)
            .map(|i| pb::AxisStatus {
                diameter: diameter_axis == Some(i),
                display_mm: s.axes.commanded[i] * if diameter_axis == Some(i) { 2.0 } else { 1.0 },
                name: names.get(i).map(|c| c.to_string()).unwrap_or_default(),
                commanded_mm: s.axes.commanded[i],
                actual_mm: s.axes.actual[i],
                following_error_mm: s.axes.commanded[i] - s.axes.actual[i],
                soft_min_mm: ctl.config().axes.get(i).and_then(|a| a.soft_min_mm),
                soft_max_mm: ctl.config().axes.get(i).and_then(|a| a.soft_max_mm),
                homed: ctl.axis_homed(s, i),
                homing_required: ctl.config().axes[i].homing
                    == crate::runtime::config::HomingMode::Required,
                distance_to_go_mm: target.map_or(0.0, |e| e[i] - s.axes.commanded[i]),
                at_soft_limit: at_soft_limit(ctl.config().axes.get(i), s.axes.commanded[i]),
            })
            .collect()
    }
}

/// The program the status names: MDI, else the selected program's name.
fn program_name(mode: RunMode, program: Option<&LoadedProgram>) -> String {
    match (mode, program) {
        (RunMode::Mdi, _) => "MDI".into(),
        (_, Some(p)) => p.name.clone(),
        _ => String::new(),
    }
}

/// Progress of the job in per cent of its blocks (100 once it finished).
fn percent_done(s: &Snapshot, total: u32, running: bool) -> f64 {
    if s.progress.finished_job == s.progress.job && s.progress.job != 0 && !running {
        100.0
    } else if total > 0 && s.progress.job != 0 {
        (s.progress.block_seq as f64 / total as f64 * 100.0).min(100.0)
    } else {
        0.0
    }
}

/// Programmed feed and its mode word (G94 mm/min, G95 mm/rev).
fn feed_of(feed: Option<Feed>) -> (f64, &'static str) {
    match feed {
        Some(Feed::MmPerMin(f)) => (f, "G94"),
        Some(Feed::MmPerRev(f)) => (f, "G95"),
        None => (0.0, ""),
    }
}

fn compensation_of(comp: Comp) -> pb::Compensation {
    let (code, entry, radius_mm) = match comp {
        Comp::Off => ("G40", 0, 0.0),
        Comp::Left { d, radius_mm } => ("G41", d.into(), radius_mm),
        Comp::Right { d, radius_mm } => ("G42", d.into(), radius_mm),
    };
    pb::Compensation {
        code: code.into(),
        entry,
        radius_mm,
    }
}

/// The constant cutting speed (KR) cells, in their units (PLC cells hold thousandths; the
/// radius eighths of a thousandth).
fn kr_status(plc: &kernel::plc::PlcArea) -> pb::KrStatus {
    pb::KrStatus {
        cutting_speed_m_min: plc.input(CellId::AkrrActV) as f64 / 1000.0,
        speed_limit_rpm: plc.input(CellId::AkrrActSmax) as f64 / 1000.0,
        radius_mm: plc.input(CellId::AkrrActR) as f64 / 8000.0,
        spindle_rpm: plc.input(CellId::AkrrActS) as f64 / 1000.0,
        output: plc.input(CellId::AkrrActOut).max(0) as u32,
        gear_max_rpm: plc.input(CellId::AkrrActP) as f64 / 1000.0,
    }
}

fn tick_stats(s: &Snapshot) -> pb::TickStats {
    pb::TickStats {
        ticks: s.tick.stats.ticks,
        overruns: s.tick.stats.overruns,
        lateness_p50_us: s.tick.stats.lateness_p50_us,
        lateness_p99_us: s.tick.stats.lateness_p99_us,
        lateness_max_us: s.tick.stats.lateness_max_us,
        cycle_us: (s.tick.cycle_ns / 1000) as u32,
    }
}

/// Whether `pos_mm` is at a soft limit of `axis` (within 1 µm): -1 lower, +1 upper, 0 not.
fn at_soft_limit(axis: Option<&crate::runtime::config::AxisConfig>, pos_mm: f64) -> i32 {
    const AT_MM: f64 = 1e-3;
    let Some(a) = axis else { return 0 };
    if a.soft_min_mm.is_some_and(|m| pos_mm <= m + AT_MM) {
        -1
    } else if a.soft_max_mm.is_some_and(|m| pos_mm >= m - AT_MM) {
        1
    } else {
        0
    }
}

/// Modal G codes of a block, as a machinist reads them.
fn modal_codes(b: &Block) -> Vec<String> {
    let mut v = Vec::with_capacity(6);
    if let BlockKind::Motion { path, .. } = b.kind {
        v.push(
            match path {
                Path::Rapid => "G0",
                Path::Line => "G1",
                // (What the block probes with is the dialect's: G38.x or G31.)
                Path::Probe(_) => "G38",
                Path::Arc {
                    dir: ArcDir::Cw, ..
                } => "G2",
                Path::Arc {
                    dir: ArcDir::Ccw, ..
                } => "G3",
            }
            .to_string(),
        );
    }
    v.push(plane_code(b.plane).into());
    v.push(
        match b.comp {
            Comp::Off => "G40",
            Comp::Left { .. } => "G41",
            Comp::Right { .. } => "G42",
        }
        .into(),
    );
    v.push(
        match b.continuity {
            Continuity::G98 => "G98",
            Continuity::G24 => "G24",
            Continuity::G23 => "G23",
        }
        .into(),
    );
    v.push(
        match b.feed {
            Feed::MmPerMin(_) => "G94",
            Feed::MmPerRev(_) => "G95",
        }
        .into(),
    );
    if b.spindle.css {
        v.push("G96".into());
    }
    v
}

pub fn plane_code(p: Plane) -> &'static str {
    match p {
        Plane::G17 => "G17",
        Plane::G18 => "G18",
        Plane::G19 => "G19",
    }
}

/// The alarm in force: a drive/bus fault, else a KŘR fault, else a planning failure.
pub fn alarm_text(ctl: &Controller, s: &Snapshot) -> Option<String> {
    let names = ctl.config().axis_names();
    match (s.alarm.fault, ctl.alarm()) {
        (Some(f), _) => {
            // "axis X, " or "spindle, " (SPINDLE_AXIS).
            let axis = match hal::fault_axis_label(f.axis, &names) {
                Some(l) if f.axis == Some(hal::SPINDLE_AXIS) => format!("{l}, "),
                Some(l) => format!("axis {l}, "),
                None => String::new(),
            };
            let node = f.node.map(|n| format!("node {n}, ")).unwrap_or_default();
            Some(format!(
                "{axis}{node}{}",
                io::fault_text(ctl.config(), &f.reason)
            ))
        }
        (None, a) => match s.alarm.kr_fault {
            Some(k) => Some(format!("constant cutting speed: {k}")),
            None => a,
        },
    }
}

/// The block to restart from after a stop or a fault ended the job early: the programmed
/// block it stopped in (issue #31).
fn restart_block(s: &Snapshot, block: Option<&Block>) -> Option<u32> {
    let ended_early = s.progress.job != 0
        && s.progress.aborted_job == s.progress.job
        && matches!(s.state, MachineState::Idle | MachineState::Fault);
    ended_early
        .then(|| block.and_then(|b| b.n).or(s.progress.block_n))
        .flatten()
}

fn state_to_pb(s: MachineState) -> pb::MachineState {
    match s {
        MachineState::Enabling => pb::MachineState::Enabling,
        MachineState::Idle => pb::MachineState::Idle,
        MachineState::Running => pb::MachineState::Running,
        MachineState::Stopping => pb::MachineState::Stopping,
        MachineState::Hold => pb::MachineState::Hold,
        MachineState::Fault => pb::MachineState::Fault,
        MachineState::Shutdown => pb::MachineState::Shutdown,
        MachineState::Jog => pb::MachineState::Jog,
        MachineState::Homing => pb::MachineState::Homing,
    }
}

/// A request's `dialect` field: `None` when empty; INVALID_ARGUMENT `dialect_unknown` for a
/// language cncd does not read.
pub(crate) fn dialect_field(field: &str) -> Result<Option<Dialect>, Status> {
    crate::runtime::dialect::requested(field)
        .map_err(|e| refused(tonic::Code::InvalidArgument, e.code(), e.to_string()))
}

/// The program a request with a `text` and a `dialect` field means: the text in the field's
/// dialect (else the machine's), or for an empty text the selected program's file in its
/// own dialect (the field overrides it). FAILED_PRECONDITION when no program is selected.
fn requested_program(
    ctl: &Controller,
    text: &str,
    dialect: &str,
) -> Result<(ProgramText, Dialect), Status> {
    let field = dialect_field(dialect)?;
    if !text.is_empty() {
        let d = field.unwrap_or_else(|| ctl.default_dialect());
        return Ok((ProgramText::Memory(Arc::from(text)), d));
    }
    let p = ctl.program().ok_or_else(|| {
        Status::failed_precondition("no program is selected and no text was given")
    })?;
    Ok((p.text.clone(), field.unwrap_or(p.dialect)))
}

/// Where a restart from `from_block` of `text` interprets the blocks before it from: for the
/// selected program (an empty `text`) where its last run started (as `Start` does); for a
/// text given with the request where the axes are (`None`).
fn restart_origin(
    ctl: &Controller,
    text: &str,
    from_block: Option<u32>,
) -> Option<kernel::units::AxesMm> {
    from_block?;
    text.is_empty()
        .then(|| ctl.program().map(|p| p.restart_origin()))
        .flatten()
}

/// `text`, or when it is empty the whole text of the selected program, read into memory,
/// with its dialect (see [`requested_program`]).
fn text_or_selected(
    ctl: &Controller,
    text: String,
    dialect: &str,
) -> Result<(String, Dialect), Status> {
    let (source, d) = requested_program(ctl, &text, dialect)?;
    if !text.is_empty() {
        return Ok((text, d));
    }
    let all = source
        .read_all(ctl.program_encoding())
        .map_err(|e| Status::internal(format!("cannot read the selected program: {e}")))?;
    Ok((all.to_string(), d))
}

/// Runs blocking work off the async workers.
async fn blocking<T: Send + 'static>(f: impl FnOnce() -> T + Send + 'static) -> Result<T, Status> {
    #[cfg(fuzzing)]
    if fuzz_rig::inline_blocking() {
        return Ok(f());
    }
    tokio::task::spawn_blocking(f)
        .await
        .map_err(|e| Status::internal(e.to_string()))
}
