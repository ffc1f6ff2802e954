//! Phase *statistics and snapshot*: the deadline grid and the lateness it accounts at the start
//! of a tick, and the snapshot published at its end.

use hal::BusFault;
use kernel::kr::{KrFault, KrOutput};
use kernel::plc::PlcArea;
use kernel::units::AxesMm;

use super::super::resample::BusClock;
use super::super::stats::{TickStats, TickSummary};
use super::{MachineState, RtCore};

/// What the RT thread publishes every tick, grouped by concern. `Copy`, fixed size: written
/// without allocation.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Snapshot {
    /// The tick itself: its count, period, time, the commands taken, lateness statistics.
    pub tick: TickInfo,
    pub state: MachineState,
    /// What stopped the machine: a drive or bus fault, a KŘR fault.
    pub alarm: Alarms,
    /// Where the axes are and whether they are homed.
    pub axes: AxesStatus,
    /// The job and the block it executes.
    pub progress: Progress,
    /// What the operator set: overrides and switches in force.
    pub operator: OperatorSettings,
    pub spindle: SpindleStatus,
    /// PLC memory area 1 as in force this tick.
    pub plc: PlcArea,
    /// The machine's inputs and outputs (docs/io.md).
    pub io: super::IoStatus,
    /// The last probing move and the probe (docs/setup.md).
    pub probe: super::ProbeStatus,
    /// The last probing move of a program (G38.x, G31).
    pub program_probe: super::ProgramProbe,
}

/// The tick: its count and time, and the lateness statistics of the deadline grid.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TickInfo {
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
    pub stats: TickSummary,
}

/// The faults in force (cleared by Reset) and what the last fault stop cost.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Alarms {
    /// A drive or bus fault.
    pub fault: Option<BusFault>,
    /// A KŘR fault stopped the machine (cleared by Reset).
    pub kr_fault: Option<KrFault>,
    /// Largest distance of the tool from the programmed path the last fault stop caused, mm.
    pub fault_path_deviation_mm: f64,
}

/// The axes: positions, path velocity, reference state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AxesStatus {
    /// Configured axes (the first `count` entries of the positions are used).
    pub count: usize,
    /// What the drives were sent, mm.
    pub commanded: AxesMm,
    pub actual: AxesMm,
    pub path_v_mm_s: f64,
    /// Axes homed since power-on (bit i: axis i).
    pub homed: u8,
    /// Axes whose last reference run failed (switch not found, stopped, fault).
    pub homing_failed: u8,
}

/// The job and the block it executes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Progress {
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
    /// Held at a program stop (M0, or M1 with optional stop on).
    pub program_stop: bool,
    /// Held at a tool change (M6): the tool to put in the spindle.
    pub tool_change: Option<u8>,
    /// Held at the end of a block in single-block mode: `block_seq`, `block_n` and `line`
    /// name the block just finished.
    pub block_stop: bool,
}

/// What the operator set: the overrides and switches in force.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OperatorSettings {
    /// Feed override in force, percent.
    pub feed_override_pct: f64,
    /// Spindle override in force, percent (issue #19).
    pub spindle_override_pct: f64,
    /// Rapid override in force, percent (issue #19).
    pub rapid_override_pct: f64,
    /// Single-block mode is on.
    pub single_block: bool,
    /// Optional stop is on: M1 stops the program.
    pub optional_stop: bool,
}

/// The spindle: its speed and the constant cutting speed (KŘR) output.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SpindleStatus {
    pub rpm: f64,
    /// A cut waits for the spindle: at rest for it to reach its speed, or a feed per
    /// revolution held because the spindle is below 1 rpm (stopped, stalled by load).
    pub waiting: bool,
    /// Constant cutting speed (KŘR) output this tick (SPEC §6).
    pub kr: KrOutput,
}

impl Snapshot {
    /// The snapshot before the first tick: at `start`, overrides 100 %.
    pub fn initial(axes: usize, start: AxesMm) -> Snapshot {
        Snapshot {
            axes: AxesStatus {
                count: axes,
                commanded: start,
                actual: start,
                ..AxesStatus::default()
            },
            operator: OperatorSettings {
                feed_override_pct: 100.0,
                spindle_override_pct: 100.0,
                rapid_override_pct: 100.0,
                ..OperatorSettings::default()
            },
            ..Snapshot::default()
        }
    }
}

/// The tick's time: the absolute deadline grid, interpolator steps against bus ticks, lateness.
pub(super) struct Timing {
    /// Next deadline of the absolute grid, ns of the caller's clock.
    pub(super) deadline_ns: u64,
    /// Interpolator steps against bus ticks.
    pub(super) bus_clock: BusClock,
    pub(super) stats: TickStats,
}

/// Refresh the lateness percentiles every this many bus ticks (a histogram walk).
const STATS_REFRESH_TICKS: u64 = 50;

impl RtCore {
    /// Deadline grid of the bus period: a tick that woke after the next deadline skips the
    /// missed ones and stays on the grid (no drift). The trajectory advances one bus period per
    /// executed tick, so no setpoint jumps either.
    pub(super) fn advance_deadline(&mut self, now_ns: u64) {
        let cycle_ns = self.timing.bus_clock.cycle_ns();
        let lateness_ns = now_ns.saturating_sub(self.timing.deadline_ns);
        let missed = lateness_ns / cycle_ns;
        self.timing.deadline_ns += (missed + 1) * cycle_ns;
        self.timing.stats.record(lateness_ns, missed);
        if self.snap.tick.sequence.is_multiple_of(STATS_REFRESH_TICKS) {
            self.timing.stats.refresh();
        }
    }

    pub(super) fn publish(&mut self, now_ns: u64) -> &Snapshot {
        let out = &self.motion.out;
        let s = &mut self.snap;
        s.tick.sequence += 1;
        s.tick.time_ns = now_ns;
        // What the drives were sent: following error and in-position compare against it.
        s.axes.commanded = AxesMm(self.io.bus_cmd.positions_mm);
        s.axes.path_v_mm_s = out.path_v_mm_s;
        s.progress.block_seq = out.seq;
        s.progress.block_n = out.n;
        s.progress.line = out.line;
        s.tick.stats = self.timing.stats.summary();
        s.spindle.rpm = self.io.fb.spindle_rpm;
        s.spindle.waiting = self.motion.interp.waiting_for_spindle();
        // An automatic change is no program stop and prompts nobody.
        let auto = self.changer.cfg.automatic() && self.motion.interp.tool_change().is_some();
        s.progress.program_stop = self.motion.interp.at_program_stop() && !auto;
        s.progress.tool_change = self.motion.interp.tool_change().filter(|_| !auto);
        s.progress.block_stop = self.motion.interp.at_block_stop();
        s.plc = self.logic.plc;
        &self.snap
    }
}
