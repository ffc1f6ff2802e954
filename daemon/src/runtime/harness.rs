//! The single-threaded simulation harness (in the style of quinn's test `Pair` or TigerBeetle's
//! simulator): the daemon's rings, planner pipeline, RT core and a drive bus (the simulated
//! machine of the `sim` crate, or a test's wrapper of it) stepped in one thread under a seeded
//! [`SimClock`] with jitter, late ticks and missed deadlines.
//!
//! Built from the daemon's own configuration and wiring (the same constants, KŘR, planner and
//! compensation settings, the same `pipeline::run`, the same rings and [`RtCore`]); only the
//! threads and the wall clock are gone. The planner runs inline: it fills the segment ring and,
//! whenever the ring is full, the harness runs RT ticks until there is room, so the RT core
//! never starves and a run is a pure function of the program, the configuration and the seed.
//! Hours of machining take seconds, and a replay with the same seed is bit-identical
//! ([`Harness::setpoint_hash`], [`Harness::timeline_hash`]).

use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use hal::DriveBus;
use kernel::Diagnostic;
use kernel::constants::Constants;
use kernel::machine::MachineSetup;
use kernel::pipeline::{self, Options};
use kernel::plan::Segment;
use tokio::sync::watch;

use super::clock::SimClock;
use super::config::Config;
use super::controller::{Pump, StartError, load_storage, machine_config, rt_core_config};
use super::homing;
use super::job::{JobSpec, plan_into};
use super::library::ProgramText;
use super::rt_core::{JobMachine, MachineState, RtCommand, RtCore, RtRings, Snapshot};
use super::storage::OffsetStore;

/// Ring capacities: as in the daemon.
const SEGMENT_RING: usize = 4096;
const COMMAND_RING: usize = 64;

/// Why a run did not end as asked.
#[derive(Debug, thiserror::Error)]
pub enum HarnessError {
    #[error("the program has errors")]
    InvalidProgram(Vec<Diagnostic>),
    #[error("planning failed: {0}")]
    Planning(Diagnostic),
    #[error("machine setup: constant cutting speed: {0}")]
    Setup(#[source] kernel::kr::KrConfigError),
    #[error("the command ring is full")]
    CommandRingFull,
    #[error("not reached within {ticks} ticks: {snapshot:?}")]
    Timeout { ticks: u64, snapshot: Box<Snapshot> },
    /// Refused or failed as the controller refuses it (e.g. a program before homing).
    #[error("{0}")]
    Control(#[from] super::controller::ControlError),
}

/// How a job ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JobEnd {
    Finished,
    /// Stopped, or ended by a fault.
    Aborted,
}

/// The daemon's pipeline and RT core on one thread, under a simulated clock.
pub struct Harness {
    config: Config,
    /// What the RT thread owns in the daemon.
    rt: SimRt,
    /// The controller's ends of the RT link.
    link: Link,
    /// What the controller keeps to start jobs and follow them.
    jobs: Jobs,
    hashes: Hashes,
}

/// The RT side: the core, its ends of the rings, the drive bus and the simulated clock.
struct SimRt {
    core: RtCore,
    rings: RtRings,
    bus: Box<dyn DriveBus>,
    clock: SimClock,
}

impl SimRt {
    /// One tick: the clock wakes at (or after) the core's next deadline, the core ticks.
    fn tick(&mut self) -> Snapshot {
        let now = self.clock.wake(self.core.next_deadline_ns());
        *self.core.tick(now, &mut self.rings, self.bus.as_mut())
    }
}

/// The controller's side of the RT link: the rings' producer ends, commands waiting for their
/// tick, the snapshot channel the planner reads, and whether the planning is cancelled.
struct Link {
    commands: rtrb::Producer<RtCommand>,
    segments: rtrb::Producer<Segment>,
    /// Commands to send before the tick of the given sequence number (sorted by the caller's
    /// order of adding; several per tick allowed).
    scheduled: Vec<(u64, RtCommand)>,
    status: (watch::Sender<Snapshot>, watch::Receiver<Snapshot>),
    /// The planning of the current job is cancelled (the controller cancels it on Stop and
    /// Shutdown; on a fault it runs on and the RT core drops the leftovers).
    cancel: bool,
}

/// Jobs: the constants a job starts with (and whether they came from a file), the execution
/// record with the offset table, and the next job id.
struct Jobs {
    constants: (Constants, bool),
    /// Work offsets G54..G59.3 as start-up read them.
    work: kernel::offsets::WorkOffsets,
    /// Follows execution and applies `G92` writes when their block executes, as the
    /// controller's status thread does.
    pump: Pump,
    next_job: u32,
}

/// The replay hashes of a run (see [`Harness::setpoint_hash`], [`Harness::timeline_hash`]).
struct Hashes {
    setpoint: Fnv,
    timeline: Fnv,
}

impl Hashes {
    fn record(&mut self, s: &Snapshot) {
        for v in &s.axes.commanded.0[..s.axes.count] {
            self.setpoint.write(v.to_bits());
            self.timeline.write(v.to_bits());
        }
        self.setpoint.write(s.spindle.kr.spindle_rpm.to_bits());
        self.timeline.write(s.spindle.kr.spindle_rpm.to_bits());
        self.timeline.write(s.tick.time_ns);
        self.timeline.write(s.tick.stats.overruns);
        self.timeline.write(u64::from(s.tick.stats.lateness_max_us));
    }
}

impl Harness {
    /// The machine of `config` on `bus` (the daemon's storage directory is read as at start-up).
    pub fn new(
        config: Config,
        mut bus: Box<dyn DriveBus>,
        mut clock: SimClock,
    ) -> Result<Self, StartError> {
        // Late wake-ups are late by whole ticks of the configured bus period.
        clock.period_ns = config.bus.cycle_ns();
        let stored = load_storage(&config)?;
        let (constants, offsets) = (stored.constants, stored.offsets);
        let work = stored.work.table();
        let axis_names = config.axis_names();
        let cfg = rt_core_config(&config, &constants, offsets.memory())?;
        let (commands, cmd_rx) = rtrb::RingBuffer::new(COMMAND_RING);
        let (segments, seg_rx) = rtrb::RingBuffer::new(SEGMENT_RING);
        let core = RtCore::new(cfg, bus.as_mut(), clock.now_ns());
        let status = watch::channel(*core.snapshot());
        Ok(Harness {
            config,
            rt: SimRt {
                core,
                rings: RtRings {
                    commands: cmd_rx,
                    segments: seg_rx,
                    planned_job: Arc::new(AtomicU32::new(0)),
                },
                bus,
                clock,
            },
            link: Link {
                commands,
                segments,
                scheduled: Vec::new(),
                status,
                cancel: false,
            },
            jobs: Jobs {
                constants,
                work,
                pump: Pump {
                    execution: Arc::default(),
                    offsets: Arc::new(Mutex::new(offsets)),
                    generation: Arc::new(AtomicU64::new(0)),
                    axis_names,
                },
                next_job: 1,
            },
            hashes: Hashes {
                setpoint: Fnv::new(),
                timeline: Fnv::new(),
            },
        })
    }

    /// The daemon's configuration.
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// The RT core (deadline grid, state).
    pub fn core(&self) -> &RtCore {
        &self.rt.core
    }

    /// The latest snapshot.
    pub fn snapshot(&self) -> Snapshot {
        *self.rt.core.snapshot()
    }

    pub fn clock(&self) -> &SimClock {
        &self.rt.clock
    }

    /// The offset table (file and memory), as the daemon holds it.
    pub fn offsets(&self) -> Arc<Mutex<OffsetStore>> {
        self.jobs.pump.offsets.clone()
    }

    /// Hash of every setpoint (positions and spindle speed) sent so far: the same for the same
    /// program whatever the clock did (the trajectory advances one bus period per executed
    /// tick).
    pub fn setpoint_hash(&self) -> u64 {
        self.hashes.setpoint.0
    }

    /// Hash of every setpoint with the time of its tick and the tick statistics: the same for
    /// the same seed, bit for bit.
    pub fn timeline_hash(&self) -> u64 {
        self.hashes.timeline.0
    }

    /// Sends a command now (it acts at the next tick). Stop and Shutdown also cancel the
    /// planning of the running job, as the controller does.
    pub fn send(&mut self, cmd: RtCommand) -> Result<(), HarnessError> {
        if matches!(cmd, RtCommand::Stop | RtCommand::Shutdown) {
            self.link.cancel = true;
        }
        self.link
            .commands
            .push(cmd)
            .map_err(|_| HarnessError::CommandRingFull)
    }

    /// Sends `cmd` just before the tick with snapshot sequence `sequence` runs.
    pub fn at_tick(&mut self, sequence: u64, cmd: RtCommand) {
        self.link.scheduled.push((sequence, cmd));
    }

    /// One RT tick: the clock wakes at (or after) the core's next deadline, the core ticks.
    pub fn step(&mut self) -> Snapshot {
        let next = self.rt.core.snapshot().tick.sequence + 1;
        let mut i = 0;
        while i < self.link.scheduled.len() {
            if self.link.scheduled[i].0 <= next {
                let (_, cmd) = self.link.scheduled.remove(i);
                // A full command ring in a test is a defect of the test.
                self.send(cmd).expect("command ring full");
            } else {
                i += 1;
            }
        }
        let snap = self.rt.tick();
        self.hashes.record(&snap);
        self.link.status.0.send_replace(snap);
        self.jobs.pump.apply_executed_writes(&snap);
        snap
    }

    /// Shuts down as cncd does on SIGTERM: `Shutdown` brakes the axes to rest and ends the
    /// loop (at most `max_ticks`), then the bus switches its drives off in order.
    pub fn shut_down(&mut self, max_ticks: u64) -> Result<(), HarnessError> {
        self.send(RtCommand::Shutdown)?;
        let mut ticks = 0;
        while !self.rt.core.finished() {
            if ticks == max_ticks {
                return Err(HarnessError::Timeout {
                    ticks,
                    snapshot: Box::new(self.snapshot()),
                });
            }
            self.step();
            ticks += 1;
        }
        let rt = &mut self.rt;
        let clock = &mut rt.clock;
        rt.core.shut_down_bus(rt.bus.as_mut(), |t| {
            clock.wake(t);
        });
        Ok(())
    }

    /// Ticks until `done` holds for a snapshot; at most `max_ticks`.
    pub fn run_until(
        &mut self,
        max_ticks: u64,
        mut done: impl FnMut(&Snapshot) -> bool,
    ) -> Result<Snapshot, HarnessError> {
        for _ in 0..max_ticks {
            let s = self.step();
            if done(&s) {
                return Ok(s);
            }
        }
        Err(HarnessError::Timeout {
            ticks: max_ticks,
            snapshot: Box::new(self.snapshot()),
        })
    }

    /// Ticks until the machine is in `state`; at most `max_ticks`.
    pub fn wait_state(
        &mut self,
        state: MachineState,
        max_ticks: u64,
    ) -> Result<Snapshot, HarnessError> {
        if self.snapshot().state == state {
            return Ok(self.snapshot());
        }
        self.run_until(max_ticks, |s| s.state == state)
    }

    /// Sets machine constants as `SetConstants` does on an idle machine: in force for the next
    /// job (the constants then count as coming from a file).
    pub fn set_constants(&mut self, values: &[(u16, f64)]) {
        for &(r, v) in values {
            self.jobs.constants.0.set(r, v);
        }
        self.jobs.constants.1 = true;
    }

    /// The machine setup a job started now takes (as the controller's): configuration,
    /// constants and memory offsets, from where the axes are commanded now.
    pub fn machine_setup(&self) -> Result<MachineSetup, kernel::kr::KrConfigError> {
        let offsets = self.jobs.pump.offsets.lock().unwrap();
        MachineSetup::new(
            &machine_config(&self.config),
            &self.jobs.constants.0,
            self.jobs.constants.1,
            offsets.memory(),
            self.snapshot().axes.commanded,
        )
        .map(|s| s.with_work_offsets(self.jobs.work))
    }

    /// Validates `text` as the controller does at loading, starts it as a job, plans it inline
    /// (ticking whenever the segment ring is full) and returns the job id once every segment
    /// is on the ring. The machine must be idle.
    pub fn start_program(&mut self, text: &str) -> Result<u32, HarnessError> {
        self.start_job(text, false)
    }

    /// As [`Harness::start_program`]; with `stop_at_blocks` every block ends at rest (the
    /// single-block runs of the API).
    pub fn start_job(&mut self, text: &str, stop_at_blocks: bool) -> Result<u32, HarnessError> {
        homing::require_homed(&self.config, &self.snapshot(), "a program")?;
        let setup = self.machine_setup().map_err(HarnessError::Setup)?;
        let job = self.jobs.next_job;
        let opts = Options {
            job,
            stop_at_blocks,
            ..Options::default()
        };
        let v = pipeline::validate(text, &setup, opts);
        if v.has_errors() {
            return Err(HarnessError::InvalidProgram(v.diagnostics));
        }
        self.jobs.next_job += 1;
        self.link.cancel = false;
        self.jobs.pump.execution.lock().unwrap().begin(job);
        let machine = JobMachine {
            kr: setup.kr_constants().expect("the daemon's setup has KŘR"),
            in_position_mm: setup.in_position_mm(),
        };
        self.send(RtCommand::Start { job, machine })?;
        let spec = JobSpec {
            text: ProgramText::Memory(Arc::from(text)),
            setup,
            opts,
            execution: self.jobs.pump.execution.clone(),
            status: self.link.status.1.clone(),
        };
        let result = plan_into(&spec, HarnessLink(self));
        self.rt.rings.planned_job.store(job, Ordering::Release);
        result.map_err(HarnessError::Planning)?;
        Ok(job)
    }

    /// Pushes one segment, running RT ticks while the ring is full (the controller's planner
    /// thread waits instead). False (cancel the planning) once the job was stopped.
    fn push_segment(&mut self, mut seg: Segment) -> bool {
        loop {
            if self.link.cancel {
                return false;
            }
            match self.link.segments.push(seg) {
                Ok(()) => return true,
                Err(rtrb::PushError::Full(s)) => {
                    seg = s;
                    self.step();
                }
            }
        }
    }

    /// Ticks until job `job` ends (ran to its end, or was stopped / ended by a fault).
    pub fn finish_job(&mut self, job: u32, max_ticks: u64) -> Result<JobEnd, HarnessError> {
        let s = self.run_until(max_ticks, |s| {
            s.progress.finished_job == job || s.progress.aborted_job == job
        })?;
        Ok(if s.progress.finished_job == job {
            JobEnd::Finished
        } else {
            JobEnd::Aborted
        })
    }

    /// Starts `text` and runs it to its end; an aborted job is an error of the caller's test.
    pub fn run_program(&mut self, text: &str, max_ticks: u64) -> Result<JobEnd, HarnessError> {
        self.wait_state(MachineState::Idle, max_ticks)?;
        let job = self.start_program(text)?;
        self.finish_job(job, max_ticks)
    }
}

impl Harness {
    /// Reference run of `axes` (all that need one when empty) as `cncctl home` runs it: in
    /// the configured order, one axis after the other, each started on an idle machine.
    /// Returns the letters homed; a failed run is the controller's error (ABORTED).
    pub fn home(&mut self, axes: &str, max_ticks: u64) -> Result<String, HarnessError> {
        let mut done = String::new();
        for i in homing::homing_order(&self.config, axes)? {
            self.wait_state(MachineState::Idle, max_ticks)?;
            self.send(RtCommand::Home(homing::home_request(&self.config, i)))?;
            self.step();
            let s = self.run_until(max_ticks, |s| s.state != MachineState::Homing)?;
            if s.axes.homed & (1 << i) == 0 {
                return Err(homing::failure(&self.config, &s, i).into());
            }
            done.push(self.config.axes[i].name);
        }
        Ok(done)
    }
}

/// FNV-1a over whole 64-bit words (one multiply per word, cheap enough for every tick of hours
/// of machining): stable across platforms and releases, unlike `DefaultHasher`.
struct Fnv(u64);

impl Fnv {
    fn new() -> Fnv {
        Fnv(0xcbf2_9ce4_8422_2325)
    }

    fn write(&mut self, word: u64) {
        self.0 = (self.0 ^ word).wrapping_mul(0x0100_0000_01b3);
    }
}

/// The harness as a run's link: segments onto the ring (ticking while it is full), and a
/// tick for each wait (the planner thread sleeps instead).
struct HarnessLink<'a>(&'a mut Harness);

impl super::job::RunLink for HarnessLink<'_> {
    fn segment(&mut self, s: Segment) -> bool {
        self.0.push_segment(s)
    }

    fn wait(&mut self) -> Option<Snapshot> {
        (!self.0.link.cancel).then(|| self.0.step())
    }
}
