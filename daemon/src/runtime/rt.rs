//! The real-time thread: one tick every 4 ms on an absolute deadline grid.
//!
//! Each tick: drain the command ring, pull planned segments from the segment ring, interpolate one
//! setpoint per axis, exchange setpoints and feedback with the drive bus, publish a snapshot.
//! After start-up this thread never allocates, never takes a lock shared with non-RT code and
//! never formats a log line: it talks to the rest of the daemon only through two bounded
//! lock-free SPSC rings (in) and a triple buffer (out).

use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};

use hal::{BusFault, CycleCommand, CycleFeedback, DriveBus, DriveState};
use kernel::interp::{InterpState, Interpolator};
use kernel::kr::{ControllingAxis, Kr, KrFault, KrInput, KrOutput, Motion, ProgramSpindle};
use kernel::plan::Segment;
use kernel::plc::{PlcArea, PlcWrite};
use kernel::units::{AxesMm, TS_NS};

use super::clock::Clock;
use super::stats::{TickStats, TickSummary};

/// Commands from the non-RT side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RtCommand {
    /// Run the segments of `job` (arriving on the segment ring).
    Start { job: u32 },
    /// Brake to rest on the path, drop the rest of the job.
    Stop,
    /// Feed hold.
    Hold,
    /// Continue after a feed hold.
    Resume,
    /// Feed override in percent (0..150).
    Override(f64),
    /// Clear a fault and re-enable the drives.
    Reset,
    /// Bring the axes to rest and end the thread.
    Shutdown,
    /// A validated write of the PLC side, in force from the next tick (SPEC §6).
    Plc(PlcWrite),
    /// Single-block mode: hold when the path enters a new block (API, issue #8).
    SingleBlock(bool),
    /// Optional stop switch: M1 stops the program while on (issue #15).
    OptionalStop(bool),
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MachineState {
    /// Drives are being enabled.
    #[default]
    Enabling,
    Idle,
    Running,
    Stopping,
    Hold,
    Fault,
    /// Shutting down: braking, then the thread ends.
    Shutdown,
}

/// What the RT thread publishes every tick. `Copy`, fixed size: written without allocation.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Snapshot {
    /// Increases by one per tick.
    pub sequence: u64,
    /// Clock time of the tick, ns.
    pub time_ns: u64,
    pub state: MachineState,
    pub axes: usize,
    pub commanded: AxesMm,
    pub actual: AxesMm,
    pub path_v_mm_s: f64,
    /// Job running, or the last one started.
    pub job: u32,
    /// Last job that ran to its end.
    pub finished_job: u32,
    /// Last job that was stopped or ended by a fault.
    pub aborted_job: u32,
    /// Block being executed: index in the program, `N`, source line.
    pub block_seq: u32,
    pub block_n: Option<u32>,
    pub line: u32,
    pub ticks: TickSummary,
    pub fault: Option<BusFault>,
    pub override_pct: f64,
    pub spindle_rpm: f64,
    /// PLC memory area 1 as in force this tick.
    pub plc: PlcArea,
    /// Single-block mode is on.
    pub single_block: bool,
    /// A cut waits at rest for the spindle to reach its speed.
    pub waiting_for_spindle: bool,
    /// Constant cutting speed (KŘR) output this tick (SPEC §6).
    pub kr: KrOutput,
    /// A KŘR fault stopped the machine (cleared by Reset).
    pub kr_fault: Option<KrFault>,
    /// Optional stop is on: M1 stops the program.
    pub optional_stop: bool,
    /// Held at a program stop (M0, or M1 with optional stop on).
    pub program_stop: bool,
    /// Largest distance from the programmed path the last fault stop caused, mm.
    pub fault_path_deviation_mm: f64,
}

/// Everything the RT thread owns.
pub struct RtParts {
    pub bus: Box<dyn DriveBus>,
    pub clock: Box<dyn Clock>,
    pub commands: rtrb::Consumer<RtCommand>,
    pub segments: rtrb::Consumer<Segment>,
    pub status: triple_buffer::Input<Snapshot>,
    /// Id of the last job whose planning is complete (all its segments are on the ring).
    pub planned_job: Arc<AtomicU32>,
    pub axes: usize,
    pub start: AxesMm,
    /// Constant cutting speed state machine (built from the constants at start-up).
    pub kr: Kr,
    /// Following error under which every axis counts as arrived, for G24 (R06-R07), mm.
    pub in_position_mm: f64,
}

/// Ticks the drives get to become operational before it is a fault.
const ENABLE_TIMEOUT_TICKS: u32 = 2_500;
/// After shutdown braking: ticks to let the drives settle before the thread ends.
const SETTLE_TICKS: u32 = 250;
/// Following error under which an axis counts as settled, mm.
const SETTLED_MM: f64 = 0.001;
/// The spindle counts as at speed within this share of its setpoint (or `SPINDLE_AT_SPEED_RPM`).
const SPINDLE_AT_SPEED_SHARE: f64 = 0.05;
const SPINDLE_AT_SPEED_RPM: f64 = 2.0;

/// Whether the actual spindle speed is close enough to the setpoint (same sign) for a cut.
fn spindle_at_speed(set_rpm: f64, actual_rpm: f64) -> bool {
    (set_rpm - actual_rpm).abs()
        <= (SPINDLE_AT_SPEED_SHARE * set_rpm.abs()).max(SPINDLE_AT_SPEED_RPM)
}

/// Refresh the lateness percentiles every this many ticks (a histogram walk).
const STATS_REFRESH_TICKS: u64 = 50;

struct Rt {
    p: RtParts,
    interp: Interpolator,
    stats: TickStats,
    snap: Snapshot,
    cmd: CycleCommand,
    fb: CycleFeedback,
    /// Job whose segments are accepted (0: none).
    active_job: u32,
    enable_ticks: u32,
    shutting_down: bool,
    settle_ticks: u32,
    plc: PlcArea,
    /// Single block: the block the path was in when last checked (`u32::MAX`: not yet moving
    /// in this job).
    sb_seq: u32,
    /// The bus has a spindle drive (asked once at start-up).
    has_spindle: bool,
    /// A stop ended the job: the spindle stops once the axes are at rest (until the next
    /// start).
    spindle_off: bool,
}

/// Runs the loop until a `Shutdown` command has brought the axes to rest.
pub fn run(parts: RtParts) {
    let interp = Interpolator::new(parts.axes, parts.start);
    let mut cmd = CycleCommand::default();
    cmd.positions_mm[..parts.axes].copy_from_slice(&parts.start.0[..parts.axes]);
    let mut rt = Rt {
        snap: Snapshot {
            axes: parts.axes,
            commanded: parts.start,
            actual: parts.start,
            override_pct: 100.0,
            ..Snapshot::default()
        },
        p: parts,
        interp,
        stats: TickStats::new(),
        cmd,
        fb: CycleFeedback::default(),
        active_job: 0,
        enable_ticks: 0,
        shutting_down: false,
        settle_ticks: 0,
        plc: PlcArea::new(),
        sb_seq: u32::MAX,
        has_spindle: false,
        spindle_off: false,
    };
    rt.has_spindle = rt.p.bus.has_spindle();
    rt.p.bus.enable();
    let mut deadline = rt.p.clock.now_ns() + TS_NS;
    loop {
        rt.p.clock.sleep_until_ns(deadline);
        let now = rt.p.clock.now_ns();
        let lateness = now.saturating_sub(deadline);
        // Stay on the grid: a tick that woke after the next deadline skips the missed ones.
        // The trajectory advances one Ts per executed tick, so no setpoint jumps.
        let missed = lateness / TS_NS;
        deadline += (missed + 1) * TS_NS;
        rt.stats.record(lateness, missed);
        if rt.snap.sequence.is_multiple_of(STATS_REFRESH_TICKS) {
            rt.stats.refresh();
        }
        if !rt.tick(now) {
            break;
        }
        if rt.p.clock.is_virtual() {
            rt.pace_virtual();
        }
    }
}

impl Rt {
    /// One tick. Returns false when the thread should end.
    fn tick(&mut self, now_ns: u64) -> bool {
        self.commands();
        // PLC writes staged since the last tick take effect now.
        self.plc.begin_tick();
        self.feed_segments();
        // G24 waits at a stop until every axis has caught up with its setpoint (SPEC §7.1).
        let in_position = (0..self.p.axes)
            .all(|i| (self.snap.commanded[i] - self.snap.actual[i]).abs() <= self.p.in_position_mm);
        self.interp.set_in_position(in_position);
        // A cut starts from rest only with the spindle at the speed commanded last tick.
        self.interp.set_spindle_ready(
            !self.has_spindle || spindle_at_speed(self.cmd.spindle_rpm, self.fb.spindle_rpm),
        );
        let out = self.interp.tick();
        self.spindle(&out);
        self.single_block_check(out.seq, out.path_v_mm_s);
        let axes = self.p.axes;
        self.cmd.positions_mm[..axes].copy_from_slice(&out.position.0[..axes]);
        let result = self.p.bus.cycle(&self.cmd, &mut self.fb);
        for i in 0..axes {
            self.snap.actual[i] = self.fb.axes[i].position_mm;
        }
        if let Err(fault) = result {
            self.fault(fault);
        }
        self.update_state();

        let s = &mut self.snap;
        s.sequence += 1;
        s.time_ns = now_ns;
        s.commanded = out.position;
        s.path_v_mm_s = out.path_v_mm_s;
        s.block_seq = out.seq;
        s.block_n = out.n;
        s.line = out.line;
        s.ticks = self.stats.summary();
        s.spindle_rpm = self.fb.spindle_rpm;
        s.waiting_for_spindle = self.interp.waiting_for_spindle();
        s.program_stop = self.interp.at_program_stop();
        s.plc = self.plc;
        self.p.status.write(*s);
        !(self.shutting_down && self.settle_ticks >= SETTLE_TICKS)
    }

    fn commands(&mut self) {
        while let Ok(c) = self.p.commands.pop() {
            match c {
                RtCommand::Start { job } => {
                    if self.snap.state == MachineState::Idle && !self.shutting_down {
                        self.active_job = job;
                        self.snap.job = job;
                        self.sb_seq = u32::MAX;
                        self.spindle_off = false;
                        self.snap.state = MachineState::Running;
                    }
                }
                RtCommand::Stop => self.abort(),
                RtCommand::Hold => self.interp.hold(),
                RtCommand::Resume => self.interp.resume(),
                RtCommand::Override(pct) => {
                    self.interp.set_override(pct);
                    self.snap.override_pct = pct.clamp(0.0, 150.0);
                }
                RtCommand::Reset => {
                    if self.snap.state == MachineState::Fault
                        && self.interp.state() == InterpState::Idle
                    {
                        self.snap.fault = None;
                        self.snap.kr_fault = None;
                        self.p.kr.reset();
                        self.p.bus.reset();
                        self.enable_ticks = 0;
                        self.snap.state = MachineState::Enabling;
                    }
                }
                RtCommand::Plc(w) => self.plc.stage(w),
                RtCommand::SingleBlock(on) => {
                    self.snap.single_block = on;
                    self.sb_seq = u32::MAX;
                }
                RtCommand::OptionalStop(on) => {
                    self.interp.set_optional_stop(on);
                    self.snap.optional_stop = on;
                }
                RtCommand::Shutdown => {
                    self.shutting_down = true;
                    self.abort();
                }
            }
        }
    }

    /// Constant cutting speed and the spindle setpoint (SPEC §6): computed from the spindle
    /// state of the block being executed and the commanded position of the controlling axis.
    fn spindle(&mut self, out: &kernel::interp::TickOut) {
        let motion = if out.path_v_mm_s <= 0.0 {
            Motion::Stationary
        } else if out.rapid {
            Motion::Rapid
        } else {
            Motion::Feed
        };
        let axis = self.p.kr.config().controlling_axis;
        // After a stop the spindle stops once the axes are at rest; on a fault at once.
        let off = self.snap.fault.is_some()
            || (self.spindle_off && self.interp.state() == InterpState::Idle);
        let input = KrInput {
            program: ProgramSpindle {
                dir: if off {
                    kernel::block::SpindleDir::Stopped
                } else {
                    out.spindle.dir
                },
                css: out.spindle.css,
                s_word: out.spindle.s,
                limit_rpm: out.spindle.limit_rpm,
                gear: out.spindle.gear,
            },
            motion,
            // The carriage and the offsets in force: KŘR computes at the tool tip, or at the
            // carriage with EXT_AKRR_SUPORT (SPEC §6).
            axis: ControllingAxis::of(out.position[axis], &out.spindle),
        };
        let k = self.p.kr.tick(&input, &mut self.plc);
        self.cmd.spindle_rpm = k.spindle_rpm;
        self.snap.kr = k;
        if let Some(f) = k.fault
            && self.snap.kr_fault.is_none()
        {
            self.snap.kr_fault = Some(f);
            self.abort();
        }
    }

    /// Single-block mode: once the path of the running job moves into another block, hold.
    fn single_block_check(&mut self, seq: u32, v_mm_s: f64) {
        if !self.snap.single_block || self.active_job == 0 {
            return;
        }
        if self.sb_seq == u32::MAX {
            if v_mm_s > 0.0 {
                self.sb_seq = seq;
            }
        } else if seq != self.sb_seq {
            self.sb_seq = seq;
            if self.interp.state() == InterpState::Running {
                self.interp.hold();
            }
        }
    }

    /// Ends the active job: brake on the path and drop what remains.
    fn abort(&mut self) {
        self.spindle_off = true;
        if self.active_job != 0 {
            self.snap.aborted_job = self.active_job;
            self.active_job = 0;
        }
        self.interp.stop();
    }

    fn fault(&mut self, fault: BusFault) {
        if self.snap.fault.is_none() {
            self.snap.fault = Some(fault);
            self.abort();
        }
    }

    fn feed_segments(&mut self) {
        while self.interp.has_room() {
            match self.p.segments.pop() {
                Ok(seg) if seg.job == self.active_job && self.active_job != 0 => {
                    // Cannot fail: room was checked and we are not stopping this job.
                    let _ = self.interp.push(seg);
                }
                Ok(_) => {} // a stopped job's leftovers
                Err(_) => break,
            }
        }
    }

    fn update_state(&mut self) {
        let is = self.interp.state();
        let s = &mut self.snap;
        if self.shutting_down {
            s.state = MachineState::Shutdown;
            if is == InterpState::Idle {
                let settled =
                    (0..self.p.axes).all(|i| (s.commanded[i] - s.actual[i]).abs() < SETTLED_MM);
                self.settle_ticks = if settled {
                    SETTLE_TICKS
                } else {
                    self.settle_ticks + 1
                };
            }
            return;
        }
        if s.fault.is_some() || s.kr_fault.is_some() {
            s.state = MachineState::Fault;
            return;
        }
        match s.state {
            MachineState::Enabling => {
                // The spindle drive, where there is one, must be ready too: a program's M3
                // would otherwise go to a drive that cannot turn yet.
                let ready = self.fb.axes[..self.p.axes]
                    .iter()
                    .all(|a| a.state == DriveState::Operational)
                    && (!self.has_spindle || self.fb.spindle_state == DriveState::Operational);
                self.enable_ticks += 1;
                if ready {
                    // Drives report where they are: command from there (after a fault or at
                    // power-on they may be elsewhere than the last setpoint).
                    let mut here = s.commanded;
                    for i in 0..self.p.axes {
                        here[i] = self.fb.axes[i].position_mm;
                    }
                    if self.interp.set_position(here) {
                        s.commanded = here;
                        self.cmd.positions_mm[..self.p.axes]
                            .copy_from_slice(&here.0[..self.p.axes]);
                    }
                    s.state = MachineState::Idle;
                } else if self.enable_ticks > ENABLE_TIMEOUT_TICKS {
                    s.fault = Some(BusFault {
                        axis: None,
                        node: None,
                        reason: hal::FaultReason::Timeout,
                    });
                    s.state = MachineState::Fault;
                }
            }
            MachineState::Running | MachineState::Hold | MachineState::Stopping => {
                let job_done = self.active_job != 0
                    && self.p.planned_job.load(Ordering::Acquire) == self.active_job
                    && self.p.segments.is_empty()
                    && is == InterpState::Idle;
                if job_done {
                    s.finished_job = self.active_job;
                    self.active_job = 0;
                }
                s.state = match is {
                    _ if self.active_job == 0 && is == InterpState::Idle => MachineState::Idle,
                    InterpState::Stopping => MachineState::Stopping,
                    InterpState::Holding | InterpState::Held => MachineState::Hold,
                    _ => MachineState::Running,
                };
            }
            MachineState::Idle | MachineState::Fault | MachineState::Shutdown => {}
        }
    }

    /// Virtual time only: wait (in real time) for the planner instead of starving, so a virtual
    /// run is deterministic whatever the host load; and don't spin when there is nothing to do.
    fn pace_virtual(&mut self) {
        if self.active_job != 0 {
            while self.interp.has_room()
                && self.p.segments.is_empty()
                && self.p.planned_job.load(Ordering::Acquire) != self.active_job
                && self.p.commands.is_empty()
            {
                std::thread::yield_now();
            }
        } else if self.p.commands.is_empty() && self.snap.state != MachineState::Enabling {
            std::thread::sleep(std::time::Duration::from_micros(200));
        }
    }
}

/// Asks for `SCHED_FIFO` at `priority` for the calling thread.
pub fn set_realtime_priority(priority: i32) -> std::io::Result<()> {
    let param = libc::sched_param {
        sched_priority: priority,
    };
    // SAFETY: plain syscall on the calling thread with a valid parameter struct.
    let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
    if rc == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

/// Locks current and future memory so the RT thread never takes a page fault.
pub fn lock_memory() -> std::io::Result<()> {
    // SAFETY: plain syscall.
    let rc = unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) };
    if rc == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}
