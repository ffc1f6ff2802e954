//! The real-time core: the whole bus tick as a pure state machine driven by its caller, in the
//! style of quinn-proto's `Connection`. The caller owns the clock, the sleeping, the rings and
//! the bus; it calls [`RtCore::tick`] once per wake-up with the time it woke and gets the
//! snapshot to publish. The core keeps the deadline grid and accounts lateness and overruns
//! against it, so the same code runs on the RT thread ([`super::rt::run`]) and in the
//! single-threaded simulation harness of the tests, where the clock is seeded, jittery and late.
//!
//! The tick runs at the bus period (`[bus] cycle_ms`, 1..10 ms); the kernel's interpolator
//! keeps its 4 ms period and steps as bus time advances ([`super::resample`]).
//!
//! One bus tick, in phases (one method each): timing → commands → PLC → the 4 ms steps due
//! (segments → motion (interpolator, in-position, spindle ready) → KŘR/spindle → single block
//! → setpoint) → bus exchange of the resampled setpoint → fault reaction, homing, state
//! machine → snapshot. After [`RtCore::new`] no phase allocates, locks or logs.

use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};

use hal::{BusFault, CycleCommand, CycleFeedback, DriveBus, DriveState, HomingState};
use kernel::block::SpindleDir;
use kernel::estop::AxisBrake;
use kernel::interp::{InterpState, Interpolator, TickOut};
use kernel::jog::{Jog, JogRequest};
use kernel::kr::{ControllingAxis, Kr, KrFault, KrInput, KrOutput, Motion, ProgramSpindle};
use kernel::plan::Segment;
use kernel::plc::{PlcArea, PlcWrite};
use kernel::units::{AxesMm, MAX_AXES, TS_NS};

use super::resample::{BusClock, Resampler};
use super::stats::{TickStats, TickSummary};

/// Commands from the non-RT side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RtCommand {
    /// Run the segments of `job` (arriving on the segment ring).
    Start { job: u32, machine: JobMachine },
    /// Brake to rest on the path, drop the rest of the job.
    Stop,
    /// Feed hold.
    Hold,
    /// Continue after a feed hold.
    Resume,
    /// Feed override in percent (0..150).
    Override(f64),
    /// Spindle override in percent (50..120, issue #19).
    SpindleOverride(f64),
    /// Rapid override in percent (0..100, issue #19).
    RapidOverride(f64),
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
    /// Start or renew a jog (idle machine only; issue #15).
    Jog(JogRequest),
    /// Brake a jog to rest.
    JogStop,
    /// Reference run of one axis (idle machine only; issue #15).
    Home(HomeRequest),
}

/// A reference run of one axis: search the home switch, then make its position the reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HomeRequest {
    pub axis: usize,
    /// -1 or +1.
    pub direction: f64,
    pub speed_mm_s: f64,
    pub accel_mm_s2: f64,
    /// The axis's position at the switch once homed.
    pub reference_mm: f64,
    /// Give up (homing failed) after this much travel without the switch.
    pub max_travel_mm: f64,
}

/// A reference run under way.
#[derive(Clone, Copy, Debug)]
struct HomingRun {
    axis: usize,
    reference_mm: f64,
    /// Drive position where the switch was found.
    trigger_mm: Option<f64>,
    /// The drive runs it itself (CiA 402 homing mode): no switch search here.
    by_drive: bool,
}

/// What the RT side reads of a job's machine setup (issue #14): taken with the job's start, so
/// KŘR, the spindle and the G24 window use the same constants as the job's planning. `Copy`:
/// no allocation on the RT thread.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JobMachine {
    /// R67, R329 d3, R580 (the gear table is the configuration's).
    pub kr: kernel::kr::KrConstants,
    /// G24 in-position window per axis (R6, R7), mm.
    pub in_position_mm: AxesMm,
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
    /// An axis is jogged (or brakes at the end of a jog).
    Jog,
    /// An axis runs its reference run (homing).
    Homing,
}

/// What the RT thread publishes every tick. `Copy`, fixed size: written without allocation.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Snapshot {
    /// Increases by one per tick (bus period).
    pub sequence: u64,
    /// Commands the core has taken from its ring so far: the controller's n-th command has
    /// been acted on once this reaches n (the status pump may lag the core by many ticks, so
    /// a tick count cannot tell).
    pub commands_taken: u64,
    /// The tick's period: the bus period `[bus] cycle_ms`, ns (0 before the core exists).
    pub cycle_ns: u64,
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
    /// Spindle override in force, percent (issue #19).
    pub spindle_override_pct: f64,
    /// Rapid override in force, percent (issue #19).
    pub rapid_override_pct: f64,
    pub spindle_rpm: f64,
    /// PLC memory area 1 as in force this tick.
    pub plc: PlcArea,
    /// Single-block mode is on.
    pub single_block: bool,
    /// A cut waits for the spindle: at rest for it to reach its speed, or a feed per
    /// revolution held because the spindle is below 1 rpm (stopped, stalled by load).
    pub waiting_for_spindle: bool,
    /// Constant cutting speed (KŘR) output this tick (SPEC §6).
    pub kr: KrOutput,
    /// A KŘR fault stopped the machine (cleared by Reset).
    pub kr_fault: Option<KrFault>,
    /// Optional stop is on: M1 stops the program.
    pub optional_stop: bool,
    /// Held at a program stop (M0, or M1 with optional stop on).
    pub program_stop: bool,
    /// Largest distance of the tool from the programmed path the last fault stop caused, mm.
    pub fault_path_deviation_mm: f64,
    /// Axes homed since power-on (bit i: axis i).
    pub homed: u8,
    /// Axes whose last reference run failed (switch not found, stopped, fault).
    pub homing_failed: u8,
}

impl Snapshot {
    /// The snapshot before the first tick: at `start`, override 100 %.
    pub fn initial(axes: usize, start: AxesMm) -> Snapshot {
        Snapshot {
            axes,
            commanded: start,
            actual: start,
            override_pct: 100.0,
            spindle_override_pct: 100.0,
            rapid_override_pct: 100.0,
            ..Snapshot::default()
        }
    }
}

/// 4 ms interpolator steps in `ms` (the counters below count steps, whatever the bus period).
const fn steps_in_ms(ms: u64) -> u32 {
    (ms * 1_000_000 / TS_NS) as u32
}

/// Time the drives get to become operational beyond the bus's own enable deadline
/// ([`hal::DriveBus::enable_timeout_ticks`]), in interpolator steps (1 s): the bus names the
/// drive that is late, so its alarm must come first.
const ENABLE_MARGIN_TICKS: u32 = steps_in_ms(1000);
/// After shutdown braking: interpolator steps to let the drives settle before the thread ends
/// (1 s); also the settle timeout of the fault reaction.
const SETTLE_TICKS: u32 = steps_in_ms(1000);
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

/// Below this actual spindle speed feed per revolution holds (SPEC §5: V = n·β; a spindle
/// stalled by load must not be fed into), rpm. Above it the feed follows the speed in proportion.
const SPINDLE_HOLD_RPM: f64 = 1.0;

/// The spindle speed feed per revolution follows: the drive's actual speed, or 0 (hold) when
/// it is below [`SPINDLE_HOLD_RPM`] or turns against its setpoint.
fn spindle_feed_rpm(set_rpm: f64, actual_rpm: f64) -> f64 {
    if actual_rpm.abs() < SPINDLE_HOLD_RPM || set_rpm * actual_rpm < 0.0 {
        0.0
    } else {
        actual_rpm.abs()
    }
}

/// Refresh the lateness percentiles every this many bus ticks (a histogram walk).
const STATS_REFRESH_TICKS: u64 = 50;

/// The RT side of the links to the rest of the daemon: two bounded lock-free SPSC rings in and
/// the id of the last job whose planning is complete.
pub struct RtRings {
    pub commands: rtrb::Consumer<RtCommand>,
    pub segments: rtrb::Consumer<Segment>,
    /// Id of the last job whose planning is complete (all its segments are on the ring).
    pub planned_job: Arc<AtomicU32>,
}

/// What the core is built from (once, at start-up).
pub struct RtCoreConfig {
    pub axes: usize,
    pub start: AxesMm,
    /// Constant cutting speed state machine (built from the constants at start-up).
    pub kr: Kr,
    /// Following error under which every axis counts as arrived, for G24 (R06-R07), mm.
    pub in_position_mm: AxesMm,
    /// Stop deceleration of each axis for the fault reaction, mm/s² (issue #15).
    pub stop_decel_mm_s2: [f64; MAX_AXES],
    /// Bus period (`[bus] cycle_ms`), ns: the tick of the RT thread. The interpolator keeps
    /// its 4 ms period ([`super::resample`]).
    pub cycle_ns: u64,
}

/// The real-time core. Everything the tick owns; the caller owns time, rings and bus.
pub struct RtCore {
    axes: usize,
    kr: Kr,
    in_position_mm: AxesMm,
    interp: Interpolator,
    stats: TickStats,
    snap: Snapshot,
    /// The interpolator's (4 ms) setpoints and spindle speed.
    cmd: CycleCommand,
    /// What the bus gets this bus tick: `cmd` resampled at the bus tick's time.
    bus_cmd: CycleCommand,
    fb: CycleFeedback,
    /// Interpolator steps against bus ticks.
    bus_clock: BusClock,
    /// The bus setpoint from the last interpolator setpoints.
    resampler: Resampler,
    /// The interpolator's output of its last step.
    out: TickOut,
    /// Next deadline of the absolute grid, ns of the caller's clock.
    deadline_ns: u64,
    /// Job whose segments are accepted (0: none).
    active_job: u32,
    /// Interpolator steps (4 ms) spent enabling.
    enable_ticks: u32,
    /// Enabling window in interpolator steps: the bus's deadline plus a margin.
    enable_window_ticks: u32,
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
    /// Fault reaction (issue #15): every healthy axis brakes on its own.
    brake: AxisBrake,
    /// Setpoints sent the tick before the last one (the brake starts from their speed).
    prev_setpoint: AxesMm,
    /// Ticks since the brake came to rest; the drives go to their safe state once settled.
    brake_rest_ticks: u32,
    safe_state_sent: bool,
    /// Jogging one axis by hand.
    jog: Jog,
    /// Reference run under way.
    homing: Option<HomingRun>,
}

impl RtCore {
    /// Builds the core (allocates: call before the RT loop starts), asks the bus to enable the
    /// drives and puts the first deadline one period after `now_ns`.
    pub fn new(cfg: RtCoreConfig, bus: &mut dyn DriveBus, now_ns: u64) -> RtCore {
        let mut cmd = CycleCommand::default();
        cmd.positions_mm[..cfg.axes].copy_from_slice(&cfg.start.0[..cfg.axes]);
        let has_spindle = bus.has_spindle();
        let bus_clock = BusClock::new(cfg.cycle_ns);
        // The bus counts its deadline in its own ticks; the window counts 4 ms steps.
        let bus_window = bus_clock.steps_in(u64::from(bus.enable_timeout_ticks()));
        let enable_window_ticks = u32::try_from(bus_window)
            .unwrap_or(u32::MAX)
            .saturating_add(ENABLE_MARGIN_TICKS);
        bus.enable();
        RtCore {
            axes: cfg.axes,
            interp: Interpolator::new(cfg.axes, cfg.start),
            snap: Snapshot {
                cycle_ns: cfg.cycle_ns,
                ..Snapshot::initial(cfg.axes, cfg.start)
            },
            kr: cfg.kr,
            in_position_mm: cfg.in_position_mm,
            stats: TickStats::new(),
            cmd,
            bus_cmd: cmd,
            fb: CycleFeedback::default(),
            bus_clock,
            resampler: Resampler::new(cfg.cycle_ns, cfg.start),
            out: TickOut::default(),
            deadline_ns: now_ns + cfg.cycle_ns,
            active_job: 0,
            enable_ticks: 0,
            enable_window_ticks,
            shutting_down: false,
            settle_ticks: 0,
            plc: PlcArea::new(),
            sb_seq: u32::MAX,
            has_spindle,
            spindle_off: false,
            brake: AxisBrake::new(cfg.axes, cfg.stop_decel_mm_s2),
            prev_setpoint: cfg.start,
            brake_rest_ticks: 0,
            safe_state_sent: false,
            jog: Jog::default(),
            homing: None,
        }
    }

    /// After the loop has ended ([`RtCore::finished`]): the bus switches its drives off in
    /// order (CANopen: disable step by step, heartbeat watch cleared, NMT pre-operational),
    /// still on the tick grid, holding the last setpoints. `sleep_until_ns` waits for a
    /// deadline. Bounded by the bus's own step timeouts.
    pub fn shut_down_bus(&mut self, bus: &mut dyn DriveBus, mut sleep_until_ns: impl FnMut(u64)) {
        let mut deadline = self.deadline_ns;
        let cycle_ns = self.bus_clock.cycle_ns();
        hal::shut_down(bus, &self.bus_cmd, &mut self.fb, || {
            sleep_until_ns(deadline);
            deadline += cycle_ns;
        });
        self.deadline_ns = deadline;
    }

    /// The absolute time the next tick is due: sleep until then, then call [`RtCore::tick`].
    pub fn next_deadline_ns(&self) -> u64 {
        self.deadline_ns
    }

    /// The last snapshot.
    pub fn snapshot(&self) -> &Snapshot {
        &self.snap
    }

    /// A `Shutdown` command has brought the axes to rest: the loop should end.
    pub fn finished(&self) -> bool {
        self.shutting_down && self.settle_ticks >= SETTLE_TICKS
    }

    /// One tick at `now_ns` (the time the caller woke, at or after [`RtCore::next_deadline_ns`]).
    /// Never allocates, locks or blocks.
    ///
    /// The tick is a bus tick. The 4 ms interpolator steps due by its time run first (none,
    /// one, or several: [`super::resample`]); each step's after-feedback phases (fault
    /// reaction, homing, state machine) run after the next step's feedback is in, the last
    /// one after this tick's exchange. At a 4 ms bus that is one step per tick, as before.
    pub fn tick(&mut self, now_ns: u64, rings: &mut RtRings, bus: &mut dyn DriveBus) -> &Snapshot {
        self.timing(now_ns);
        self.commands(&mut rings.commands, bus);
        // PLC writes staged since the last tick take effect now.
        self.plc.begin_tick();
        let steps = self.bus_clock.begin_tick();
        for k in 0..steps {
            if k > 0 {
                self.after_feedback(rings, bus);
            }
            self.interpolator_step(&mut rings.segments);
        }
        self.exchange(bus);
        if steps > 0 {
            self.after_feedback(rings, bus);
        }
        self.publish(now_ns)
    }

    /// One 4 ms step of the kernel: segments, interpolator, KŘR, single block, and the axes'
    /// setpoint (path, jog or fault brake) handed to the resampler.
    fn interpolator_step(&mut self, segments: &mut rtrb::Consumer<Segment>) {
        self.feed_segments(segments);
        let out = self.motion();
        self.spindle(&out);
        self.single_block_check(out.seq, out.path_v_mm_s);
        self.setpoint(&out);
        self.out = out;
    }

    /// What follows a step once feedback is in: fault reaction, homing, the state machine.
    fn after_feedback(&mut self, rings: &RtRings, bus: &mut dyn DriveBus) {
        self.fault_reaction(bus);
        self.homing_step(bus);
        let planned = rings.planned_job.load(Ordering::Acquire);
        self.update_state(planned, rings.segments.is_empty());
    }

    /// Deadline grid of the bus period: a tick that woke after the next deadline skips the
    /// missed ones and stays on the grid (no drift). The trajectory advances one bus period per
    /// executed tick, so no setpoint jumps either.
    fn timing(&mut self, now_ns: u64) {
        let cycle_ns = self.bus_clock.cycle_ns();
        let lateness_ns = now_ns.saturating_sub(self.deadline_ns);
        let missed = lateness_ns / cycle_ns;
        self.deadline_ns += (missed + 1) * cycle_ns;
        self.stats.record(lateness_ns, missed);
        if self.snap.sequence.is_multiple_of(STATS_REFRESH_TICKS) {
            self.stats.refresh();
        }
    }

    /// The interpolator's setpoint of this tick. G24 waits at a stop until every axis has caught
    /// up with its setpoint (SPEC §7.1); a cut starts from rest only with the spindle at the
    /// speed commanded last tick.
    fn motion(&mut self) -> TickOut {
        let in_position = (0..self.axes).all(|i| {
            (self.snap.commanded[i] - self.snap.actual[i]).abs() <= self.in_position_mm[i]
        });
        self.interp.set_in_position(in_position);
        self.interp.set_spindle_ready(
            !self.has_spindle || spindle_at_speed(self.cmd.spindle_rpm, self.fb.spindle_rpm),
        );
        // Feed per revolution follows the speed the drive reported last tick; without a
        // spindle drive there is no feedback and the planned (nominal) feed runs.
        self.interp.set_spindle_feed_rpm(if self.has_spindle {
            spindle_feed_rpm(self.cmd.spindle_rpm, self.fb.spindle_rpm)
        } else {
            f64::INFINITY
        });
        self.interp.tick()
    }

    /// The axes' 4 ms setpoint of this step: the path, a jog, or the fault brake.
    fn setpoint(&mut self, out: &TickOut) {
        let axes = self.axes;
        self.prev_setpoint = AxesMm(self.cmd.positions_mm);
        // After a fault the brake, not the path, commands the axes.
        let setpoint = if self.brake.active() {
            self.brake.tick()
        } else if self.jog.active() {
            let mut p = out.position;
            p[self.jog.axis()] = self.jog.tick();
            p
        } else {
            out.position
        };
        self.cmd.positions_mm[..axes].copy_from_slice(&setpoint.0[..axes]);
        self.resampler.push(AxesMm(self.cmd.positions_mm));
    }

    /// Setpoints out (resampled at the bus tick's time), feedback in; a bus fault stops the
    /// machine.
    fn exchange(&mut self, bus: &mut dyn DriveBus) {
        let axes = self.axes;
        self.bus_cmd.spindle_rpm = self.cmd.spindle_rpm;
        self.resampler
            .sample(axes, self.bus_clock.phase(), &mut self.bus_cmd.positions_mm);
        let result = bus.cycle(&self.bus_cmd, &mut self.fb);
        for i in 0..axes {
            self.snap.actual[i] = self.fb.axes[i].position_mm;
        }
        if let Err(fault) = result {
            self.fault(fault);
        }
    }

    fn publish(&mut self, now_ns: u64) -> &Snapshot {
        let out = &self.out;
        let s = &mut self.snap;
        s.sequence += 1;
        s.time_ns = now_ns;
        // What the drives were sent: following error and in-position compare against it.
        s.commanded = AxesMm(self.bus_cmd.positions_mm);
        s.path_v_mm_s = out.path_v_mm_s;
        s.block_seq = out.seq;
        s.block_n = out.n;
        s.line = out.line;
        s.ticks = self.stats.summary();
        s.spindle_rpm = self.fb.spindle_rpm;
        s.waiting_for_spindle = self.interp.waiting_for_spindle();
        s.program_stop = self.interp.at_program_stop();
        s.plc = self.plc;
        &self.snap
    }

    fn commands(&mut self, commands: &mut rtrb::Consumer<RtCommand>, bus: &mut dyn DriveBus) {
        while let Ok(c) = commands.pop() {
            self.snap.commands_taken += 1;
            match c {
                RtCommand::Start { job, machine } => {
                    if self.snap.state == MachineState::Idle && !self.shutting_down {
                        self.kr.set_constants(machine.kr);
                        self.in_position_mm = machine.in_position_mm;
                        self.active_job = job;
                        self.snap.job = job;
                        self.sb_seq = u32::MAX;
                        self.spindle_off = false;
                        self.snap.state = MachineState::Running;
                    }
                }
                RtCommand::Stop => {
                    self.jog.stop();
                    self.stop_drive_homing(bus);
                    self.abort();
                }
                RtCommand::Jog(r) => self.jog_request(r),
                RtCommand::JogStop => self.jog.stop(),
                RtCommand::Home(r) => self.home_request(r, bus),
                // Only a job is held (the controller's check may have read an older
                // snapshot: the job may have ended since).
                RtCommand::Hold if self.active_job != 0 => self.interp.hold(),
                RtCommand::Hold => {}
                RtCommand::Resume => self.interp.resume(),
                RtCommand::Override(pct) => {
                    self.interp.set_override(pct);
                    self.snap.override_pct = pct.clamp(0.0, 150.0);
                }
                RtCommand::SpindleOverride(pct) => self.spindle_override(pct),
                RtCommand::RapidOverride(pct) => {
                    self.interp.set_rapid_override(pct);
                    self.snap.rapid_override_pct = pct.clamp(0.0, 100.0);
                }
                RtCommand::Reset => {
                    if self.snap.state == MachineState::Fault
                        && self.interp.state() == InterpState::Idle
                    {
                        self.snap.fault = None;
                        self.snap.kr_fault = None;
                        self.brake.clear();
                        self.safe_state_sent = false;
                        self.kr.reset();
                        bus.reset();
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
                    self.jog.stop();
                    self.stop_drive_homing(bus);
                    self.shutting_down = true;
                    self.abort();
                }
            }
        }
    }

    /// Spindle override: KŘR scales the commanded speed from the next tick, within the gear
    /// range (the per-rev feed follows the actual spindle speed already).
    fn spindle_override(&mut self, pct: f64) {
        self.kr.set_override(pct);
        let (lo, hi) = (
            *kernel::kr::SPINDLE_OVERRIDE_PCT.start(),
            *kernel::kr::SPINDLE_OVERRIDE_PCT.end(),
        );
        self.snap.spindle_override_pct = pct.clamp(lo, hi);
    }

    /// Constant cutting speed and the spindle setpoint (SPEC §6): computed from the spindle
    /// state of the block being executed and the commanded position of the controlling axis.
    fn spindle(&mut self, out: &TickOut) {
        let motion = if out.path_v_mm_s <= 0.0 {
            Motion::Stationary
        } else if out.rapid {
            Motion::Rapid
        } else {
            Motion::Feed
        };
        let axis = self.kr.config().controlling_axis;
        // After a stop the spindle stops once the axes are at rest; on a fault at once.
        let off = self.snap.fault.is_some()
            || (self.spindle_off && self.interp.state() == InterpState::Idle);
        let input = KrInput {
            program: ProgramSpindle {
                dir: if off {
                    SpindleDir::Stopped
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
        let k = self.kr.tick(&input, &mut self.plc);
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
        self.forget_reference(fault);
        if self.snap.fault.is_none() {
            self.snap.fault = Some(fault);
            self.start_fault_stop(fault);
            self.abort();
        }
    }

    /// A jog starts only on an idle machine (or renews the running jog); its speed is scaled
    /// by the feed override in force.
    fn jog_request(&mut self, mut r: JogRequest) {
        let free = matches!(self.snap.state, MachineState::Idle | MachineState::Jog)
            && self.active_job == 0
            && !self.shutting_down
            && r.axis < self.axes;
        if !free {
            return;
        }
        r.speed_mm_s *= self.snap.override_pct / 100.0;
        let here = self.cmd.positions_mm[r.axis];
        if self.jog.request(r, here) {
            self.snap.state = MachineState::Jog;
        }
    }

    /// Starts a reference run: the axis moves toward its switch like a jog (no lease: the
    /// operator started it and Stop ends it), at most `max_travel_mm`.
    fn home_request(&mut self, r: HomeRequest, bus: &mut dyn DriveBus) {
        let free = self.snap.state == MachineState::Idle
            && self.active_job == 0
            && !self.shutting_down
            && r.axis < self.axes;
        if !free {
            return;
        }
        let bit = 1u8 << r.axis;
        self.snap.homed &= !bit;
        self.snap.homing_failed &= !bit;
        if bus.drive_homes() {
            // The drive moves on its own (its settings are the bus's); the axis's setpoint
            // is not used until the run ends.
            bus.start_homing(r.axis);
            self.homing = Some(HomingRun {
                axis: r.axis,
                reference_mm: r.reference_mm,
                trigger_mm: None,
                by_drive: true,
            });
            self.snap.state = MachineState::Homing;
            return;
        }
        let here = self.cmd.positions_mm[r.axis];
        let jog = JogRequest {
            axis: r.axis,
            target_mm: here + r.direction.signum() * r.max_travel_mm,
            speed_mm_s: r.speed_mm_s,
            accel_mm_s2: r.accel_mm_s2,
            lease_ticks: u32::MAX,
        };
        if self.jog.request(jog, here) {
            self.homing = Some(HomingRun {
                axis: r.axis,
                reference_mm: r.reference_mm,
                trigger_mm: None,
                by_drive: false,
            });
            self.snap.state = MachineState::Homing;
        }
    }

    /// The reference run after this tick's feedback: brake at the switch; once at rest the
    /// switch position becomes the reference (drive and setpoint shift together: no jump).
    fn homing_step(&mut self, bus: &mut dyn DriveBus) {
        let Some(mut h) = self.homing else { return };
        if h.by_drive {
            return self.drive_homing_step(h.axis, bus);
        }
        if h.trigger_mm.is_none() && bus.home_switch(h.axis) {
            h.trigger_mm = Some(self.fb.axes[h.axis].position_mm);
            self.jog.stop();
        }
        if self.jog.active() {
            self.homing = Some(h);
            return;
        }
        let bit = 1u8 << h.axis;
        match h.trigger_mm {
            Some(t) => {
                bus.set_home(h.axis, t, h.reference_mm);
                // Setpoint and this tick's feedback shift with the drive's position.
                let shift = h.reference_mm - t;
                self.cmd.positions_mm[h.axis] += shift;
                self.bus_cmd.positions_mm[h.axis] += shift;
                self.resampler.shift(h.axis, shift);
                self.fb.axes[h.axis].position_mm += shift;
                self.snap.actual[h.axis] += shift;
                self.snap.homed |= bit;
            }
            None => self.snap.homing_failed |= bit,
        }
        self.homing = None;
    }

    /// A reference run by the drive: once it ends the drive follows setpoints again from where
    /// it stands, so the axis's commanded position is re-based on the drive's (homed)
    /// position: the first setpoint equals it, no jump.
    fn drive_homing_step(&mut self, axis: usize, bus: &mut dyn DriveBus) {
        let bit = 1u8 << axis;
        match bus.homing_state(axis) {
            HomingState::Idle | HomingState::Running => return,
            HomingState::Done => self.snap.homed |= bit,
            HomingState::Aborted => self.snap.homing_failed |= bit,
        }
        let here = self.fb.axes[axis].position_mm;
        self.cmd.positions_mm[axis] = here;
        self.prev_setpoint[axis] = here;
        self.homing = None;
    }

    /// Stop or shutdown during a reference run by the drive: the drive stops it; the run
    /// ends (aborted) when the drive stands.
    fn stop_drive_homing(&mut self, bus: &mut dyn DriveBus) {
        if let Some(h) = self.homing.filter(|h| h.by_drive) {
            bus.stop_homing(h.axis);
        }
    }

    /// A drive that refused or did not confirm the reference of a reference run: the axis
    /// was marked homed when the run ended, but it is not.
    fn forget_reference(&mut self, fault: BusFault) {
        use hal::FaultReason::{HomingRefused, HomingTimeout};
        if let (Some(a), HomingRefused | HomingTimeout) = (fault.axis, fault.reason)
            && usize::from(a) < self.axes
        {
            self.snap.homed &= !(1 << a);
            self.snap.homing_failed |= 1 << a;
        }
    }

    /// Fault reaction (issue #15): a faulted axis no longer follows, so braking along the path
    /// would pull the tool off it. Every healthy axis brakes on its own at its stop
    /// deceleration from the speed of its last setpoints; a faulted axis keeps its setpoint
    /// where it stands.
    fn start_fault_stop(&mut self, fault: BusFault) {
        // The brake takes over from the jog's last setpoints.
        self.jog.cancel();
        let homing = self.homing.take();
        if let Some(h) = homing {
            self.snap.homing_failed |= 1 << h.axis;
        }
        let now = AxesMm(self.cmd.positions_mm);
        self.brake
            .start(&self.prev_setpoint, &now, self.interp.current_path());
        // A drive homing on its own is not where its setpoint is: it stops where it stands.
        if let Some(h) = homing.filter(|h| h.by_drive) {
            self.brake
                .hold_axis(h.axis, self.fb.axes[h.axis].position_mm);
        }
        if let Some(a) = fault.axis.map(usize::from).filter(|&a| a < self.axes) {
            self.brake.hold_axis(a, self.fb.axes[a].position_mm);
        }
        self.brake_rest_ticks = 0;
        self.safe_state_sent = false;
        self.snap.fault_path_deviation_mm = 0.0;
    }

    /// While the fault stop runs: measure the deviation from the path; once every axis is at
    /// rest (setpoints still, drives caught up, or a settle timeout), bring the drives to
    /// their safe state (CiA 402 quick stop / disable).
    fn fault_reaction(&mut self, bus: &mut dyn DriveBus) {
        if !self.brake.active() {
            return;
        }
        self.brake.observe(&self.snap.actual);
        self.snap.fault_path_deviation_mm = self.brake.deviation_mm();
        if self.safe_state_sent || !self.brake.at_rest() {
            return;
        }
        let settled = (0..self.axes)
            .all(|i| (self.cmd.positions_mm[i] - self.snap.actual[i]).abs() < SETTLED_MM);
        self.brake_rest_ticks += 1;
        if settled || self.brake_rest_ticks >= SETTLE_TICKS {
            bus.safe_state();
            self.safe_state_sent = true;
        }
    }

    fn feed_segments(&mut self, segments: &mut rtrb::Consumer<Segment>) {
        while self.interp.has_room() {
            match segments.pop() {
                Ok(seg) if seg.job == self.active_job && self.active_job != 0 => {
                    // Cannot fail: room was checked and we are not stopping this job.
                    let _ = self.interp.push(seg);
                }
                Ok(_) => {} // a stopped job's leftovers
                Err(_) => break,
            }
        }
    }

    /// The machine state after this tick. `planned_job`: the last job whose planning is
    /// complete; `ring_empty`: no segment waits on the ring.
    fn update_state(&mut self, planned_job: u32, ring_empty: bool) {
        let is = self.interp.state();
        if self.shutting_down {
            self.update_shutdown(is);
            return;
        }
        let s = &mut self.snap;
        if s.fault.is_some() || s.kr_fault.is_some() {
            s.state = MachineState::Fault;
            return;
        }
        match s.state {
            MachineState::Enabling => self.update_enabling(),
            MachineState::Running | MachineState::Hold | MachineState::Stopping => {
                self.update_running(is, planned_job, ring_empty)
            }
            MachineState::Jog if !self.jog.active() => {
                // The jog ended at rest: the path continues from where the axis is now.
                let here = AxesMm(self.cmd.positions_mm);
                if self.interp.set_position(here) {
                    s.state = MachineState::Idle;
                }
            }
            MachineState::Homing if self.homing.is_none() => {
                let here = AxesMm(self.cmd.positions_mm);
                if self.interp.set_position(here) {
                    s.state = MachineState::Idle;
                }
            }
            MachineState::Jog
            | MachineState::Homing
            | MachineState::Idle
            | MachineState::Fault
            | MachineState::Shutdown => {}
        }
    }

    /// Shutting down: count the ticks the axes have been at rest (the drives are disabled
    /// once they settled).
    fn update_shutdown(&mut self, is: InterpState) {
        let s = &mut self.snap;
        s.state = MachineState::Shutdown;
        if is == InterpState::Idle {
            let settled = (0..self.axes).all(|i| (s.commanded[i] - s.actual[i]).abs() < SETTLED_MM);
            self.settle_ticks = if settled {
                SETTLE_TICKS
            } else {
                self.settle_ticks + 1
            };
        }
    }

    /// Enabling: idle once every drive is operational (commanding from where the drives
    /// are), a bus fault when the enable window passes first.
    fn update_enabling(&mut self) {
        let s = &mut self.snap;
        // The spindle drive, where there is one, must be ready too: a program's M3
        // would otherwise go to a drive that cannot turn yet.
        let ready = self.fb.axes[..self.axes]
            .iter()
            .all(|a| a.state == DriveState::Operational)
            && (!self.has_spindle || self.fb.spindle_state == DriveState::Operational);
        self.enable_ticks += 1;
        if ready {
            // Drives report where they are: command from there (after a fault or at
            // power-on they may be elsewhere than the last setpoint).
            let mut here = s.commanded;
            for i in 0..self.axes {
                here[i] = self.fb.axes[i].position_mm;
            }
            if self.interp.set_position(here) {
                s.commanded = here;
                self.cmd.positions_mm[..self.axes].copy_from_slice(&here.0[..self.axes]);
                self.bus_cmd.positions_mm[..self.axes].copy_from_slice(&here.0[..self.axes]);
                // Taken over from the drives: a step on purpose, not smoothed.
                self.resampler.reset(here);
            }
            s.state = MachineState::Idle;
        } else if self.enable_ticks > self.enable_window_ticks {
            s.fault = Some(BusFault {
                axis: None,
                node: None,
                reason: hal::FaultReason::Timeout,
            });
            s.state = MachineState::Fault;
        }
    }

    /// Running, holding or stopping: the job finishes when it is planned, drained and at
    /// rest; otherwise the state follows the interpolator's.
    fn update_running(&mut self, is: InterpState, planned_job: u32, ring_empty: bool) {
        let s = &mut self.snap;
        // The bus setpoint must have arrived at the end too (the smoothing of a bus
        // period other than 4 ms lags: `resample`).
        let job_done = self.active_job != 0
            && planned_job == self.active_job
            && ring_empty
            && is == InterpState::Idle
            && self.resampler.settled();
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
}
