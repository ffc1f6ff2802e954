//! The cyclic CANopen master for CiA 402 drives: axes in Cyclic Synchronous Position mode
//! (CSP), and an optional spindle drive in Cyclic Synchronous Velocity mode (CSV) that gets
//! the spindle speed setpoint and reports the actual speed. The spindle node goes through the
//! same start-up, enable sequence, watchdogs and fault handling as the axis nodes. The digital
//! I/O of `cfg.io` travels on CiA 401 modules (booted, configured and watched like the drives,
//! without a power stage: `io_module.rs`) and in the drives' PDO2 (0x60FD, 0x60FE:1), as
//! resolved once in `io_plan.rs`.
//!
//! Everything happens inside [`DriveBus::cycle`], once per tick, without blocking or
//! allocating:
//! 1. drain the received frames (TPDOs answering the last SYNC, heartbeats, EMCY, SDO
//!    answers, error frames);
//! 2. advance each node through its [`Phase`]: NMT reset → boot-up → SDO configuration →
//!    (all configured) NMT start → running, where the CiA 402 phase machine every bus shares
//!    ([`crate::cia402::Drive`]) enables the drive, watches its statusword and hands it the
//!    setpoints; watch TPDOs and heartbeats; on shutdown walk the power stage down and leave
//!    the bus;
//! 3. send SYNC (once a node is started), then one RPDO (controlword, target position) per
//!    node in NMT operational (and its RPDO2 with 0x60FE:1 where mapped), then one RPDO per
//!    I/O module with its outputs.
//!
//! Drives latch the RPDO at the next SYNC and answer each SYNC with their TPDO, so feedback is
//! one tick old. Timeouts are counted in ticks, so a late tick never causes a false alarm.
//!
//! The master keeps the bus (the port, SYNC, RPDOs, its heartbeat, error frames) and
//! dispatches; each node is a state machine driven by it without a port. Child modules
//! (issue #22): `node.rs` (a node's phases and its advance by one tick, the frames it sends
//! collected in an outbox), `receive.rs` (what a node makes of its frames), `startup.rs` (the
//! start-up SDO plan, the settings check), `homing.rs` (the drive's reference run in homing
//! mode 6, the safe state after a fault stop), `master_tests.rs`.

use std::time::Duration;

use crate::{
    AxisFeedback, BusFault, CycleCommand, CycleFeedback, DriveBus, DriveState, FaultReason,
    HomingState, MAX_AXES,
};

use super::emcy::{self, Emcy};
use super::pdo::{self, OpMode, Rpdo, Tpdo};
use super::sdo::{self, Response};
use super::{
    CanOpenError, CanPort, Frame, NodeId, PortError, RxEvent, cia401, cob, err_class, nmt,
};
use crate::cia402::{Drive, DrivePhase, PowerState, cw, sw};
pub use crate::cia402::{FaultReaction, ShutdownMode};
use crate::units::to_units;

#[path = "homing.rs"]
mod homing;
#[path = "io_module.rs"]
mod io_module;
#[path = "io_plan.rs"]
mod io_plan;
#[path = "node.rs"]
mod node;
#[path = "receive.rs"]
mod receive;
#[path = "startup.rs"]
mod startup;
use homing::Home;
pub use homing::HomingParams;
use io_module::IoModule;
use io_plan::IoPlan;
use node::{Node, Off, Outbox, Phase, Timing};
use receive::SdoAnswer;
use startup::{Step, check_config, startup_steps, step_object, ticks};

/// One drive on the bus (one axis).
#[derive(Clone, Debug, PartialEq)]
pub struct NodeConfig {
    pub node_id: NodeId,
    /// Drive position units (0x607A, 0x6064) per mm or degree.
    pub increments_per_mm: f64,
    /// Following-error window written to 0x6065 at start-up, increments; `None` keeps the
    /// drive's own setting.
    pub following_window_increments: Option<u32>,
    /// The axis's highest speed, mm/s. One tick's travel at it is the largest target step the
    /// master accepts when an enabled drive is handed from holding its own position over to
    /// the commanded positions.
    pub max_velocity_mm_s: f64,
    /// The drive's reference run (CiA 402 homing mode 6); `None`: the axis cannot be homed
    /// on this bus.
    pub homing: Option<HomingParams>,
}

impl NodeConfig {
    /// A drive with its own following window, a speed limit of 200 mm/s and no homing.
    pub fn new(node_id: NodeId, increments_per_mm: f64) -> NodeConfig {
        NodeConfig {
            node_id,
            increments_per_mm,
            following_window_increments: None,
            max_velocity_mm_s: 200.0,
            homing: None,
        }
    }
}

/// The spindle drive (CiA 402 in cyclic synchronous velocity mode).
#[derive(Clone, Debug, PartialEq)]
pub struct SpindleNodeConfig {
    /// Not used by an axis.
    pub node_id: NodeId,
    /// Drive velocity units (0x60FF, 0x606C) per rpm, e.g. 1 for a drive in rpm, 10 for
    /// 0.1 rpm, or encoder increments per second per rpm (increments per revolution / 60).
    pub units_per_rpm: f64,
}

/// Bus-wide settings. Times are counted in ticks of `cycle` (rounded up), so a late tick
/// never causes a false alarm.
#[derive(Clone, Debug, PartialEq)]
pub struct CanOpenConfig {
    /// Axis drives, in axis order.
    pub nodes: Vec<NodeConfig>,
    /// Digital I/O on this bus (docs/io.md): CiA 401 modules (`IoPoint::Module`) and the
    /// drives' own 0x60FD/0x60FE (`IoPoint::Drive`); other points are not this bus's.
    pub io: crate::io::IoMap,
    /// Heartbeat consumer time the master sets on each I/O module (0x1016): a module that
    /// hears no master heartbeat for this long sets its outputs to their safe values by
    /// itself (error mode 0x6206, error values 0x6207).
    pub io_consumer_timeout: Duration,
    /// The spindle drive, if the spindle is on this bus.
    pub spindle: Option<SpindleNodeConfig>,
    /// The master's own node id: it produces a heartbeat the drives consume (0x1016).
    pub master_node_id: NodeId,
    /// Tick period, 1..=10 ms in whole ms (0x1006 and 0x60C2 of the drives follow it; the
    /// caller must call `cycle` at this period).
    pub cycle: Duration,
    /// Time without a TPDO before a drive counts as silent (also bounds a transmit queue
    /// that stays full).
    pub tpdo_timeout: Duration,
    /// Heartbeat period the drives produce (0x1017, whole ms up to 65535).
    pub drive_heartbeat: Duration,
    /// Master side: a drive heartbeat older than this is lost.
    pub heartbeat_timeout: Duration,
    /// Period of the master's heartbeat (zero: none, and the drives do not watch it).
    pub master_heartbeat: Duration,
    /// Drive side: the master heartbeat older than this is lost (0x1016, whole ms up to
    /// 65535).
    pub drive_consumer_timeout: Duration,
    /// Answer time allowed for each SDO request (one retry follows).
    pub sdo_timeout: Duration,
    /// Time allowed from NMT reset to boot-up, and from NMT start to the first TPDO.
    pub boot_timeout: Duration,
    /// Time allowed for the enable sequence (and for the disable walk at shutdown).
    pub enable_timeout: Duration,
    /// Master-side following-error check (setpoint minus actual), mm; `None`: only the
    /// drive's own check (statusword bit 13, EMCY 8611h).
    pub following_error_limit_mm: Option<f64>,
    /// Error frames (decaying by one every 10 ticks) tolerated before a fault.
    pub error_frame_limit: u32,
    /// How the orderly shutdown switches the drives off.
    pub shutdown: ShutdownMode,
    /// What the drives do after a fault stop.
    pub fault_reaction: FaultReaction,
    /// Time allowed for a drive's reference run, from its start to the return to CSP.
    pub homing_timeout: Duration,
}

impl CanOpenConfig {
    /// Defaults with margins for a loaded Linux machine (see docs/buses.md).
    pub fn new(nodes: Vec<NodeConfig>) -> CanOpenConfig {
        let ms = Duration::from_millis;
        CanOpenConfig {
            nodes,
            io: crate::io::IoMap::default(),
            io_consumer_timeout: ms(500),
            spindle: None,
            master_node_id: NodeId::MASTER_DEFAULT,
            cycle: ms(4),
            tpdo_timeout: ms(100),
            drive_heartbeat: ms(100),
            heartbeat_timeout: ms(500),
            master_heartbeat: ms(100),
            drive_consumer_timeout: ms(500),
            sdo_timeout: ms(200),
            boot_timeout: ms(3000),
            enable_timeout: ms(2000),
            following_error_limit_mm: None,
            error_frame_limit: 20,
            shutdown: ShutdownMode::Disable,
            fault_reaction: FaultReaction::QuickStop,
            homing_timeout: ms(60_000),
        }
    }
}

/// Drives configured and started by this master over a [`CanPort`].
pub struct CanOpenMaster<P: CanPort> {
    port: P,
    name: String,
    cfg: CanOpenConfig,
    /// Axis nodes first (`[..axes]`), then the spindle node if configured.
    nodes: Vec<Node>,
    /// The CiA 401 I/O modules of `cfg.io`, in the order first named.
    modules: Vec<IoModule>,
    /// Where each input and output of `cfg.io` travels.
    io: IoPlan,
    axes: usize,
    timing: Timing,
    /// The frames a node's step sends, emptied onto the bus after each step.
    outbox: Outbox,
    tick: u64,
    enabled: bool,
    shutting_down: bool,
    bus_fault: Option<FaultReason>,
    error_score: u32,
    tx_blocked_ticks: u32,
}

/// Faults a reset can clear at the drive (fault reset over the PDO) instead of a restart,
/// provided the node is still in NMT operational.
fn is_drive_level(r: FaultReason) -> bool {
    matches!(
        r,
        FaultReason::DriveFault { .. }
            | FaultReason::FollowingError
            | FaultReason::DriveDisabled { .. }
            | FaultReason::EnableTimeout { .. }
    )
}

impl<P: CanPort> CanOpenMaster<P> {
    /// A master for `cfg.nodes` (one per axis, in axis order) on `port`; `name` is the
    /// interface name for logs. Nothing is sent before [`DriveBus::enable`].
    pub fn new(port: P, name: &str, cfg: CanOpenConfig) -> Result<Self, CanOpenError> {
        check_config(&cfg)?;
        io_plan::check_modules(&cfg)?;
        let module_ids = cfg.io.modules();
        let io = IoPlan::new(&cfg, &module_ids)?;
        let mut nodes: Vec<Node> = cfg
            .nodes
            .iter()
            .map(|n| Node::new(&cfg, n.clone(), OpMode::Csp))
            .collect();
        if let Some(sp) = &cfg.spindle {
            let n = NodeConfig {
                following_window_increments: None,
                ..NodeConfig::new(sp.node_id, sp.units_per_rpm)
            };
            nodes.push(Node::new(&cfg, n, OpMode::Csv));
        }
        for (i, n) in nodes.iter_mut().enumerate() {
            n.set_io(io.drive_io(i));
        }
        let modules = module_ids
            .iter()
            .enumerate()
            .map(|(i, &node)| {
                let (input_groups, output_groups) = io.module_groups(i);
                let plan = cia401::ModulePlan {
                    node,
                    input_groups,
                    output_groups,
                    safe_outputs: io.module_bits(i, cfg.io.safe_outputs),
                };
                IoModule::new(&cfg, plan)
            })
            .collect();
        Ok(CanOpenMaster {
            port,
            name: name.to_owned(),
            axes: cfg.nodes.len(),
            modules,
            io,
            timing: Timing::new(&cfg),
            outbox: Outbox::new(),
            cfg,
            nodes,
            tick: 0,
            enabled: false,
            shutting_down: false,
            bus_fault: None,
            error_score: 0,
            tx_blocked_ticks: 0,
        })
    }

    /// The port, e.g. for a test to inspect what was sent.
    pub fn port_mut(&mut self) -> &mut P {
        &mut self.port
    }

    fn send(&mut self, f: &Frame) {
        match self.port.send(f) {
            Ok(()) => {}
            Err(PortError::WouldBlock) => self.tx_blocked_ticks += 1,
            Err(PortError::Down) => {
                self.bus_fault.get_or_insert(FaultReason::BusError);
            }
        }
    }

    /// Sends what the last node step put in the outbox, in order.
    fn flush(&mut self) {
        for f in self.outbox.take() {
            self.send(&f);
        }
    }

    /// The node of a frame's node id.
    fn node_index(&self, node_id: u8) -> Option<usize> {
        self.nodes
            .iter()
            .position(|n| n.cfg.node_id.get() == node_id)
    }

    /// The axis a fault of node `i` names: its index, or the spindle.
    fn axis_of(&self, i: usize) -> u8 {
        if i < self.axes {
            i as u8
        } else {
            crate::SPINDLE_AXIS
        }
    }

    /// A received frame, to the node or module it comes from.
    fn on_frame(&mut self, f: &Frame) {
        let (code, node_id) = cob::split(f.id);
        let Some(i) = self.node_index(node_id) else {
            return self.on_module_frame(code, node_id, f);
        };
        let (now, n) = (self.tick, &mut self.nodes[i]);
        match code {
            cob::TPDO1 => n.on_tpdo(f),
            cob::TPDO2 => n.on_tpdo2(f),
            cob::EMCY => n.on_emcy(f.payload()),
            cob::HEARTBEAT => {
                if let Some(&state) = f.payload().first() {
                    n.on_heartbeat(now, state);
                }
            }
            cob::SDO_TX => {
                if let Some(r) = sdo::parse_response(f.payload()) {
                    n.on_sdo_response(now, r, &mut self.outbox);
                    self.flush();
                }
            }
            _ => {}
        }
    }

    /// A received frame of an I/O module (or of no node of ours).
    fn on_module_frame(&mut self, code: u16, node_id: u8, f: &Frame) {
        let Some(m) = self.modules.iter_mut().find(|m| m.id == node_id) else {
            return;
        };
        match code {
            cob::TPDO1 => m.on_tpdo(f),
            cob::EMCY => m.on_emcy(f.payload()),
            cob::HEARTBEAT => {
                if let Some(&state) = f.payload().first() {
                    m.on_heartbeat(self.tick, state);
                }
            }
            cob::SDO_TX => {
                if let Some(r) = sdo::parse_response(f.payload()) {
                    m.on_sdo_response(self.tick, r, &mut self.outbox);
                    self.flush();
                }
            }
            _ => {}
        }
    }

    /// NMT start for every configured node and module once none is still being configured:
    /// SYNC and PDOs begin only after all of them have their configuration.
    fn start_configured(&mut self) {
        let busy = |p: Phase| {
            matches!(
                p,
                Phase::ResetPending { .. } | Phase::Booting { .. } | Phase::Configuring { .. }
            )
        };
        if self.shutting_down
            || self.nodes.iter().any(|n| busy(n.phase))
            || self.modules.iter().any(|m| busy(m.phase))
        {
            return;
        }
        for i in 0..self.nodes.len() {
            if self.nodes[i].phase == Phase::Configured {
                self.nodes[i].nmt_start(self.tick, &mut self.outbox);
                self.flush();
            }
        }
        for i in 0..self.modules.len() {
            if self.modules[i].phase == Phase::Configured {
                self.modules[i].nmt_start(self.tick, &mut self.outbox);
                self.flush();
            }
        }
    }

    fn on_error_frame(&mut self, class: u32) {
        if class & err_class::BUS_OFF != 0 {
            self.bus_fault.get_or_insert(FaultReason::BusOff);
        } else if class
            & (err_class::CONTROLLER
                | err_class::PROTOCOL
                | err_class::BUS_ERROR
                | err_class::NO_ACK)
            != 0
        {
            self.error_score += 1;
            if self.error_score > self.cfg.error_frame_limit {
                self.bus_fault.get_or_insert(FaultReason::ErrorFrames);
            }
        }
    }

    /// `d` in ticks, rounded up.
    fn ticks(&self, d: Duration) -> u64 {
        ticks(d, self.cfg.cycle)
    }

    /// The spindle node, if configured.
    fn spindle(&self) -> Option<&Node> {
        self.nodes.get(self.axes)
    }

    fn state_of(n: &Node) -> DriveState {
        match n.phase {
            Phase::Idle | Phase::ShuttingDown(_) => DriveState::Disabled,
            // The drive homes on its own, enabled: the axis counts as operational.
            Phase::Homing(_) => DriveState::Operational,
            Phase::Faulted(_) => DriveState::Fault,
            Phase::Running => match n.drive.phase() {
                DrivePhase::Enabled => DriveState::Operational,
                DrivePhase::Faulted(_) => DriveState::Fault,
                DrivePhase::Enabling { .. } => DriveState::Enabling,
                DrivePhase::Off | DrivePhase::Stopped | DrivePhase::PoweringDown { .. } => {
                    DriveState::Disabled
                }
            },
            _ => DriveState::Enabling,
        }
    }

    /// This tick's setpoint of node `i` in drive units.
    fn target_of(&self, i: usize, cmd: &CycleCommand) -> i32 {
        let value = if i < self.axes {
            cmd.positions_mm[i]
        } else if cmd.spindle_rpm.is_finite() {
            cmd.spindle_rpm
        } else {
            // A setpoint that is not a number stops the spindle rather than the bus.
            0.0
        };
        to_units(value, self.nodes[i].cfg.increments_per_mm)
    }

    /// SYNC (once a node is started), one RPDO per node in NMT operational (and its RPDO2
    /// with 0x60FE:1 if it carries outputs), one RPDO per I/O module with its outputs, the
    /// heartbeat.
    fn send_cyclic(&mut self, outputs: crate::io::IoBits) {
        if self.nodes.iter().any(Node::gets_rpdo) || self.modules.iter().any(IoModule::needs_sync) {
            self.send(&pdo::sync());
        }
        for i in 0..self.nodes.len() {
            let n = &self.nodes[i];
            if n.gets_rpdo() {
                let id = n.cfg.node_id.get();
                let f = Rpdo {
                    controlword: n.drive.controlword(),
                    target_increments: n.drive.target_increments(),
                }
                .encode(id);
                let io_out = n.io.outputs;
                self.send(&f);
                if io_out {
                    let bits = self.io.drive_bits(i, outputs);
                    self.send(&cia401::encode_u32(cob::RPDO2 + u16::from(id), bits));
                }
            }
        }
        for i in 0..self.modules.len() {
            if self.modules[i].gets_rpdo() {
                let f = self.modules[i].rpdo(self.io.module_bits(i, outputs));
                self.send(&f);
            }
        }
        let hb = self.ticks(self.cfg.master_heartbeat);
        if hb > 0 && self.tick.is_multiple_of(hb) {
            let id = self.cfg.master_node_id.get();
            self.send(&nmt::heartbeat(id, nmt::state::OPERATIONAL));
        }
    }

    fn drain(&mut self) {
        for _ in 0..MAX_RX_PER_TICK {
            match self.port.try_recv() {
                Ok(Some(RxEvent::Frame(f))) => self.on_frame(&f),
                Ok(Some(RxEvent::Error { class, .. })) => self.on_error_frame(class),
                Ok(None) | Err(PortError::WouldBlock) => break,
                Err(PortError::Down) => {
                    self.bus_fault.get_or_insert(FaultReason::BusError);
                    break;
                }
            }
        }
        if self.tick.is_multiple_of(10) {
            self.error_score = self.error_score.saturating_sub(1);
        }
    }

    fn fill_feedback(&self, feedback: &mut CycleFeedback) {
        for (fb, n) in feedback.axes.iter_mut().zip(&self.nodes[..self.axes]) {
            *fb = AxisFeedback {
                position_mm: f64::from(n.drive.actual_increments()) / n.cfg.increments_per_mm,
                state: Self::state_of(n),
            };
        }
        let (spindle_rpm, spindle_state) = match self.spindle() {
            Some(n) if Self::state_of(n) == DriveState::Operational => (
                f64::from(n.drive.actual_increments()) / n.cfg.increments_per_mm,
                DriveState::Operational,
            ),
            Some(n) => (0.0, Self::state_of(n)),
            None => (0.0, DriveState::Disabled),
        };
        feedback.spindle_rpm = spindle_rpm;
        feedback.spindle_state = spindle_state;
        feedback.inputs = self
            .io
            .inputs_from(|m| self.modules[m].inputs, |n| self.nodes[n].digital_inputs);
    }

    /// During shutdown, once every drive is off: the modules leave the bus. Until then they
    /// keep getting the caller's outputs (the safe ones by then).
    fn shut_down_modules(&mut self) {
        if !self.shutting_down || !self.nodes.iter().all(Node::is_off) {
            return;
        }
        for i in 0..self.modules.len() {
            self.modules[i].shut_down(self.tick, &mut self.outbox);
            self.flush();
        }
    }

    /// A fault anywhere on the bus interrupts every reference run: the machine stops.
    fn interrupt_homing_on_fault(&mut self) {
        if self.first_fault().is_ok() {
            return;
        }
        for i in 0..self.axes {
            if matches!(self.nodes[i].phase, Phase::Homing(Home::Running { .. })) {
                self.nodes[i].stop_homing(self.tick, &mut self.outbox);
                self.flush();
            }
        }
    }

    /// The fault to report this tick: the bus's, else the first faulted node's.
    fn first_fault(&self) -> Result<(), BusFault> {
        if let Some(reason) = self.bus_fault {
            return Err(BusFault {
                axis: None,
                node: None,
                reason,
            });
        }
        for (i, n) in self.nodes.iter().enumerate() {
            if let Some(reason) = n.fault_reason() {
                return Err(BusFault {
                    axis: Some(self.axis_of(i)),
                    node: Some(n.cfg.node_id.get()),
                    reason,
                });
            }
        }
        // A module's fault names its node and no axis.
        for m in &self.modules {
            if let Some(reason) = m.fault_reason() {
                return Err(BusFault {
                    axis: None,
                    node: Some(m.id),
                    reason,
                });
            }
        }
        Ok(())
    }
}

/// Largest number of received frames handled per tick, so a babbling node cannot stall the
/// tick (the rest waits in the socket buffer for the next tick).
const MAX_RX_PER_TICK: usize = 256;

impl<P: CanPort> DriveBus for CanOpenMaster<P> {
    fn name(&self) -> &str {
        &self.name
    }

    fn axes(&self) -> usize {
        self.axes
    }

    fn has_spindle(&self) -> bool {
        self.spindle().is_some()
    }

    fn cycle(&mut self, cmd: &CycleCommand, feedback: &mut CycleFeedback) -> Result<(), BusFault> {
        self.tick += 1;
        self.drain();
        let blocked_before = self.tx_blocked_ticks;
        for i in 0..self.nodes.len() {
            let target = self.target_of(i, cmd);
            self.nodes[i].tick(self.tick, target, &self.timing, &mut self.outbox);
            self.flush();
        }
        for i in 0..self.modules.len() {
            self.modules[i].tick(self.tick, &self.timing, &mut self.outbox);
            self.flush();
        }
        self.interrupt_homing_on_fault();
        self.start_configured();
        if self.enabled {
            self.send_cyclic(cmd.outputs);
        }
        self.shut_down_modules();
        if self.shutting_down
            && self.nodes.iter().all(Node::is_off)
            && self.modules.iter().all(IoModule::is_off)
        {
            // Every drive and module has left: SYNC and the master's heartbeat stop.
            self.enabled = false;
        }
        // A transmit queue that stays full (nobody acknowledges, bus jammed) is a bus fault.
        if self.tx_blocked_ticks == blocked_before {
            self.tx_blocked_ticks = 0;
        } else if u64::from(self.tx_blocked_ticks) > self.timing.tpdo {
            self.bus_fault.get_or_insert(FaultReason::BusError);
        }
        self.fill_feedback(feedback);
        self.first_fault()
    }

    fn enable(&mut self) {
        if self.shutting_down {
            return;
        }
        self.enabled = true;
        for n in &mut self.nodes {
            if matches!(n.phase, Phase::Idle) {
                n.phase = Phase::ResetPending {
                    command: nmt::Command::ResetNode,
                };
            }
        }
        for m in &mut self.modules {
            if matches!(m.phase, Phase::Idle) {
                m.phase = Phase::ResetPending {
                    command: nmt::Command::ResetNode,
                };
            }
        }
    }

    fn reset(&mut self) {
        if self.shutting_down {
            return;
        }
        self.enabled = true;
        let whole_bus = self.bus_fault.take().is_some();
        self.error_score = 0;
        self.tx_blocked_ticks = 0;
        for n in &mut self.nodes {
            n.reset(self.tick, whole_bus, &self.timing);
        }
        for m in &mut self.modules {
            m.reset(whole_bus);
        }
    }

    fn enable_timeout_ticks(&self) -> u32 {
        // The slowest path a node may take before it is operational or faulted by its own
        // timeouts: boot-up, every SDO with its retry, NMT start to the first TPDO, enable.
        let t = &self.timing;
        let node_steps = self.nodes.iter().map(|n| n.steps.len());
        let module_steps = self.modules.iter().map(|m| m.steps.len());
        let steps = node_steps.chain(module_steps).max().unwrap_or(0) as u64;
        let boot = t.boot + 1;
        let sdo = 2 * (t.sdo + 1);
        let total = 2 * boot + steps * sdo + self.ticks(self.cfg.enable_timeout) + 2;
        u32::try_from(total).unwrap_or(u32::MAX)
    }

    fn shutdown(&mut self) {
        if self.shutting_down {
            return;
        }
        self.shutting_down = true;
        for i in 0..self.nodes.len() {
            self.nodes[i].shut_down(self.tick, &mut self.outbox);
            self.flush();
        }
    }

    fn is_shut_down(&self) -> bool {
        self.shutting_down && !self.enabled
    }

    /// After a fault stop with the healthy axes at rest: every drive still enabled goes to
    /// the configured safe state (its target holds where it stands).
    fn safe_state(&mut self) {
        if let Some(controlword) = self.cfg.fault_reaction.controlword() {
            for n in &mut self.nodes {
                n.enter_safe_state(controlword);
            }
        }
    }

    fn supports_homing(&self) -> bool {
        self.nodes[..self.axes]
            .iter()
            .any(|n| n.cfg.homing.is_some())
    }

    fn drive_homes(&self) -> bool {
        true
    }

    fn start_homing(&mut self, axis: usize) {
        if axis < self.axes {
            self.nodes[axis].start_homing(self.tick, &mut self.outbox);
            self.flush();
        }
    }

    fn stop_homing(&mut self, axis: usize) {
        if axis < self.axes {
            self.nodes[axis].stop_homing(self.tick, &mut self.outbox);
            self.flush();
        }
    }

    fn homing_state(&self, axis: usize) -> HomingState {
        self.nodes
            .get(axis)
            .filter(|_| axis < self.axes)
            .map_or(HomingState::Idle, |n| n.homing)
    }
}

#[cfg(test)]
#[path = "master_tests.rs"]
mod tests;
