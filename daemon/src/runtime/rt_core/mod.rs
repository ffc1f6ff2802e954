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
//! (segments → motion (interpolator, in-position, spindle ready, single block) → automatic
//! tool change → KŘR/spindle
//! → setpoint) → bus exchange of the resampled setpoint → fault reaction, homing, state
//! machine → snapshot. After [`RtCore::new`] no phase allocates, locks or logs.
//!
//! One file per phase, each with the part of the core's state it owns: `commands` (the command
//! ring, jog requests), `motion` (segments and interpolation, KŘR and the PLC cells, single
//! block, setpoints), `exchange` (bus exchange), `fault` (fault reaction), `homing` (reference
//! runs), `state` (the state machine), `snapshot` (deadline grid, statistics and snapshot),
//! `tool_changer` (the automatic tool change at M6).
//! This file builds the core and runs the phases in order ([`RtCore::tick`]).

mod commands;
mod exchange;
mod fault;
mod homing;
mod io;
mod motion;
mod probe;
mod program_probe;
mod snapshot;
mod state;
#[cfg(test)]
mod tests;
mod tool_changer;

use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};

use hal::{CycleCommand, CycleFeedback, DriveBus};
use kernel::estop::AxisBrake;
use kernel::interp::{Interpolator, TickOut};
use kernel::jog::Jog;
use kernel::kr::Kr;
use kernel::plan::Segment;
use kernel::plc::PlcArea;
use kernel::units::{AxesMm, MAX_AXES};

use super::resample::{BusClock, Resampler};
use super::stats::TickStats;

pub use commands::{HomeRequest, JobMachine, RtCommand};
pub use io::{IoFunctions, IoStatus, bus_fault};
pub use probe::{ProbeOutcome, ProbeRequest, ProbeStatus};
pub use program_probe::ProgramProbe;
pub use snapshot::{
    Alarms, AxesStatus, OperatorSettings, Progress, Snapshot, SpindleStatus, TickInfo,
};
pub use state::MachineState;
pub use tool_changer::{MAX_STEPS, ToolChanger};

use exchange::BusIo;
use fault::FaultStop;
use io::IoLogic;
use motion::{JobRun, MachineLogic, MotionSources};
use snapshot::Timing;
use state::{ENABLE_MARGIN_TICKS, Lifecycle, SETTLE_TICKS};

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
    /// What the machine's inputs and outputs do (docs/io.md).
    pub io: IoFunctions,
    /// The automatic tool changer (default: manual tool change).
    pub tool_changer: ToolChanger,
}

/// The real-time core. Everything the tick owns, by part (each in the file of the phase that
/// drives it); the caller owns time, rings and bus.
pub struct RtCore {
    snap: Snapshot,
    timing: Timing,
    io: BusIo,
    motion: MotionSources,
    job: JobRun,
    logic: MachineLogic,
    fault_stop: FaultStop,
    lifecycle: Lifecycle,
    io_logic: IoLogic,
    changer: tool_changer::ChangerRun,
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
            snap: {
                let mut s = Snapshot::initial(cfg.axes, cfg.start);
                s.tick.cycle_ns = cfg.cycle_ns;
                s
            },
            timing: Timing {
                deadline_ns: now_ns + cfg.cycle_ns,
                bus_clock,
                stats: TickStats::new(),
            },
            io: BusIo {
                axes: cfg.axes,
                cmd,
                bus_cmd: cmd,
                fb: CycleFeedback::default(),
                resampler: Resampler::new(cfg.cycle_ns, cfg.start),
                has_spindle,
            },
            motion: MotionSources {
                interp: Interpolator::new(cfg.axes, cfg.start),
                out: TickOut::default(),
                jog: Jog::default(),
                homing: None,
                probe: probe::ProbeRun::default(),
                program_probe: program_probe::ProgramProbeRun::default(),
            },
            job: JobRun {
                active: 0,
                in_position_mm: cfg.in_position_mm,
                spindle_off: false,
            },
            logic: MachineLogic {
                kr: cfg.kr,
                plc: PlcArea::new(),
            },
            fault_stop: FaultStop {
                brake: AxisBrake::new(cfg.axes, cfg.stop_decel_mm_s2),
                prev_setpoint: cfg.start,
                rest_ticks: 0,
                safe_state_sent: false,
                reset_pending: false,
            },
            io_logic: IoLogic::new(cfg.io),
            changer: tool_changer::ChangerRun::new(cfg.tool_changer),
            lifecycle: Lifecycle {
                enable_ticks: 0,
                enable_window_ticks,
                shutting_down: false,
                settle_ticks: 0,
            },
        }
    }

    /// The absolute time the next tick is due: sleep until then, then call [`RtCore::tick`].
    pub fn next_deadline_ns(&self) -> u64 {
        self.timing.deadline_ns
    }

    /// The last snapshot.
    pub fn snapshot(&self) -> &Snapshot {
        &self.snap
    }

    /// A `Shutdown` command has brought the axes to rest: the loop should end.
    pub fn finished(&self) -> bool {
        self.lifecycle.shutting_down && self.lifecycle.settle_ticks >= SETTLE_TICKS
    }

    /// One tick at `now_ns` (the time the caller woke, at or after [`RtCore::next_deadline_ns`]).
    /// Never allocates, locks or blocks.
    ///
    /// The tick is a bus tick. The 4 ms interpolator steps due by its time run first (none,
    /// one, or several: [`super::resample`]); each step's after-feedback phases (fault
    /// reaction, homing, state machine) run after the next step's feedback is in, the last
    /// one after this tick's exchange. At a 4 ms bus that is one step per tick, as before.
    pub fn tick(&mut self, now_ns: u64, rings: &mut RtRings, bus: &mut dyn DriveBus) -> &Snapshot {
        self.advance_deadline(now_ns);
        self.commands(&mut rings.commands, bus);
        // PLC writes staged since the last tick take effect now.
        self.logic.plc.begin_tick();
        let steps = self.timing.bus_clock.begin_tick();
        for k in 0..steps {
            if k > 0 {
                self.after_feedback(rings, bus);
            }
            self.interpolator_step(&mut rings.segments);
        }
        self.outputs();
        self.exchange(bus);
        // The inputs this exchange read act in this tick (docs/io.md).
        self.inputs();
        if steps > 0 {
            self.after_feedback(rings, bus);
        }
        self.publish(now_ns)
    }

    /// What follows a step once feedback is in: fault reaction, homing, the state machine.
    fn after_feedback(&mut self, rings: &RtRings, bus: &mut dyn DriveBus) {
        self.fault_reaction(bus);
        self.homing_step(bus);
        self.probe_step();
        let planned = rings.planned_job.load(Ordering::Acquire);
        self.update_state(planned, rings.segments.is_empty());
    }
}
