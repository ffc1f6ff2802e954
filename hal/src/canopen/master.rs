//! The cyclic CANopen master for CiA 402 drives: axes in Cyclic Synchronous Position mode
//! (CSP), and an optional spindle drive in Cyclic Synchronous Velocity mode (CSV) that gets
//! the spindle speed setpoint and reports the actual speed. The spindle node goes through the
//! same start-up, enable sequence, watchdogs and fault handling as the axis nodes.
//!
//! Everything happens inside [`DriveBus::cycle`], once per tick, without blocking or
//! allocating:
//! 1. drain the received frames (TPDOs answering the last SYNC, heartbeats, EMCY, SDO
//!    answers, error frames);
//! 2. advance each node through its [`Phase`]: NMT reset → boot-up → SDO configuration →
//!    (all configured) NMT start → CiA 402 enable sequence → operational; watch TPDOs,
//!    heartbeats, statusword; on shutdown walk the power stage down and leave the bus;
//! 3. send SYNC (once a node is started), then one RPDO (controlword, target position) per
//!    node in NMT operational.
//!
//! Drives latch the RPDO at the next SYNC and answer each SYNC with their TPDO, so feedback is
//! one tick old. Timeouts are counted in ticks, so a late tick never causes a false alarm.

use crate::{
    AxisFeedback, BusFault, CycleCommand, CycleFeedback, DriveBus, DriveState, FaultReason,
    HomingState, MAX_AXES,
};

use super::emcy::{self, Emcy};
use super::pdo::{self, OpMode, Rpdo, Tpdo};
use super::sdo::{self, Response};
use super::{CanPort, Frame, PortError, RxEvent, cob, err_class, nmt};
use crate::cia402::{self, PowerState, cw, sw};

#[path = "homing.rs"]
mod homing;
use homing::Home;
pub use homing::HomingParams;

/// One drive on the bus (one axis).
#[derive(Clone, Debug, PartialEq)]
pub struct NodeConfig {
    /// CANopen node id, 1..=127.
    pub node_id: u8,
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
    pub fn new(node_id: u8, increments_per_mm: f64) -> NodeConfig {
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
    /// CANopen node id, 1..=127, not used by an axis.
    pub node_id: u8,
    /// Drive velocity units (0x60FF, 0x606C) per rpm, e.g. 1 for a drive in rpm, 10 for
    /// 0.1 rpm, or encoder increments per second per rpm (increments per revolution / 60).
    pub units_per_rpm: f64,
}

/// How the orderly shutdown switches an enabled drive off.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ShutdownMode {
    /// Disable operation (07h), shutdown (06h), disable voltage (00h).
    #[default]
    Disable,
    /// Quick stop (02h), then disable voltage (00h): the drive stops by its quick stop
    /// option (0x605A) first.
    QuickStop,
}

/// What the drives do after a fault stop, once the healthy axes are at rest
/// ([`DriveBus::safe_state`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FaultReaction {
    /// Quick stop (controlword 02h): the drives end in Quick Stop Active (or Switch On
    /// Disabled, by their quick stop option 0x605A).
    #[default]
    QuickStop,
    /// Disable voltage (00h): power stage off at once, Switch On Disabled (an axis with a
    /// holding brake needs it; a vertical axis without one may sag).
    DisableVoltage,
    /// The drives stay enabled and hold their last setpoint.
    Hold,
}

/// Bus-wide settings. Times are converted to ticks of `cycle_us`.
#[derive(Clone, Debug, PartialEq)]
pub struct CanOpenConfig {
    /// Axis drives, in axis order.
    pub nodes: Vec<NodeConfig>,
    /// The spindle drive, if the spindle is on this bus.
    pub spindle: Option<SpindleNodeConfig>,
    /// The master's own node id: it produces a heartbeat the drives consume (0x1016).
    pub master_node_id: u8,
    /// Tick period, µs, 1000..=10000 in whole ms (0x1006 and 0x60C2 of the drives follow it;
    /// the caller must call `cycle` at this period).
    pub cycle_us: u32,
    /// Consecutive ticks without a TPDO before a drive counts as silent.
    pub tpdo_missing_ticks: u32,
    /// Heartbeat period the drives produce (0x1017), ms.
    pub drive_heartbeat_ms: u16,
    /// Master side: a drive heartbeat older than this is lost, ms.
    pub heartbeat_timeout_ms: u32,
    /// Period of the master's heartbeat, ms (0: none, and the drives do not watch it).
    pub master_heartbeat_ms: u16,
    /// Drive side: the master heartbeat older than this is lost (0x1016), ms.
    pub drive_consumer_timeout_ms: u16,
    /// Answer time allowed for each SDO request, ms (one retry follows).
    pub sdo_timeout_ms: u32,
    /// Time allowed from NMT reset to boot-up, and from NMT start to the first TPDO, ms.
    pub boot_timeout_ms: u32,
    /// Time allowed for the enable sequence (and for the disable walk at shutdown), ms.
    pub enable_timeout_ms: u32,
    /// Master-side following-error check (setpoint minus actual), mm; `None`: only the
    /// drive's own check (statusword bit 13, EMCY 8611h).
    pub following_error_limit_mm: Option<f64>,
    /// Error frames (decaying by one every 10 ticks) tolerated before a fault.
    pub error_frame_limit: u32,
    /// How the orderly shutdown switches the drives off.
    pub shutdown: ShutdownMode,
    /// What the drives do after a fault stop.
    pub fault_reaction: FaultReaction,
    /// Time allowed for a drive's reference run, from its start to the return to CSP, ms.
    pub homing_timeout_ms: u32,
}

impl CanOpenConfig {
    /// Defaults with margins for a loaded Linux machine (see docs/buses.md).
    pub fn new(nodes: Vec<NodeConfig>) -> CanOpenConfig {
        CanOpenConfig {
            nodes,
            spindle: None,
            master_node_id: 127,
            cycle_us: 4000,
            tpdo_missing_ticks: 25,
            drive_heartbeat_ms: 100,
            heartbeat_timeout_ms: 500,
            master_heartbeat_ms: 100,
            drive_consumer_timeout_ms: 500,
            sdo_timeout_ms: 200,
            boot_timeout_ms: 3000,
            enable_timeout_ms: 2000,
            following_error_limit_mm: None,
            error_frame_limit: 20,
            shutdown: ShutdownMode::Disable,
            fault_reaction: FaultReaction::QuickStop,
            homing_timeout_ms: 60_000,
        }
    }
}

/// One start-up configuration step.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Step {
    Write {
        index: u16,
        subindex: u8,
        value: u32,
        size: u8,
    },
    /// Reads 0x6064 so the target can start at the actual position (CSP only).
    ReadPosition,
    /// Reads the modes of operation display 0x6061 until it shows this mode.
    CheckMode(u8),
}

/// The orderly shutdown of one node, in this order.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Off {
    /// Power stage walked down by the statusword: 07h → 06h → 00h.
    PowerDown { since: u64 },
    /// SDO write 0x1016:1 = 0: the drive stops watching the master's heartbeat, so the
    /// master may go silent without the drive faulting.
    ClearConsumer { sent_at: u64, retried: bool },
    /// NMT pre-operational sent: nothing more goes to this node.
    Done,
}

/// Where a node is. The order of the variants is the order of a start-up; a reset re-enters
/// at `ResetPending` (communication lost) or `Enabling` (drive-level fault).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Phase {
    /// Before `enable()`.
    Idle,
    /// The NMT reset goes out next tick: reset node at the first enable, reset communication
    /// to restart a node after a loss of communication.
    ResetPending {
        command: nmt::Command,
    },
    Booting {
        since: u64,
        command: nmt::Command,
    },
    Configuring {
        step: usize,
        sent_at: u64,
        retried: bool,
    },
    /// Configured; NMT start waits until no node is still being configured, so SYNC and PDOs
    /// start after the configuration.
    Configured,
    /// NMT start sent; waiting for the first TPDO.
    Starting {
        since: u64,
    },
    /// CiA 402 enable sequence, acting on fresh statuswords only.
    Enabling {
        since: u64,
    },
    Operational,
    /// The drive's own reference run (homing mode 6), then back to CSP.
    Homing(Home),
    /// Brought to the safe state after a fault stop ([`FaultReaction`]); a reset enables it
    /// again.
    Stopped,
    Faulted(FaultReason),
    ShuttingDown(Off),
}

struct Node {
    /// For the spindle node `increments_per_mm` holds its velocity units per rpm.
    cfg: NodeConfig,
    mode: OpMode,
    steps: Vec<Step>,
    phase: Phase,
    statusword: u16,
    /// The TPDO's value: actual position (CSP) or actual velocity (CSV), drive units.
    position_increments: i32,
    /// A TPDO arrived in this tick (its statusword is fresh).
    tpdo_seen: bool,
    tpdo_missing: u32,
    last_heartbeat: u64,
    /// The NMT state as last known: from the node's heartbeat or TPDO, or what the master
    /// commanded. RPDOs go only to nodes known operational.
    nmt_state: u8,
    booted: bool,
    controlword: u16,
    target_increments: i32,
    emcy_code: Option<u16>,
    /// The commanded positions have been taken over: until then an enabled drive holds its
    /// own position, so the target never jumps (CSV nodes take the setpoint at once).
    taken_over: bool,
    /// One tick's travel at the axis's highest speed, increments (at least 1).
    max_step_increments: i64,
    /// The drive's reference run, as reported to the controller.
    homing: HomingState,
    /// Tick the reference run started (its timeout counts from there).
    home_since: u64,
    /// The mode of operation may not be CSP (a reference run did not return): a reset
    /// restarts the node so its configuration writes 0x6060 = 8 again.
    mode_changed: bool,
}

/// Drives configured and started by this master over a [`CanPort`].
pub struct CanOpenMaster<P: CanPort> {
    port: P,
    name: String,
    cfg: CanOpenConfig,
    /// Axis nodes first (`[..axes]`), then the spindle node if configured.
    nodes: Vec<Node>,
    axes: usize,
    tick: u64,
    enabled: bool,
    shutting_down: bool,
    bus_fault: Option<FaultReason>,
    error_score: u32,
    tx_blocked_ticks: u32,
}

fn ticks(ms: u32, cycle_us: u32) -> u64 {
    (u64::from(ms) * 1000).div_ceil(u64::from(cycle_us.max(1)))
}

fn startup_steps(c: &CanOpenConfig, n: &NodeConfig, mode: OpMode) -> Vec<Step> {
    let w = |index, subindex, value, size| Step::Write {
        index,
        subindex,
        value,
        size,
    };
    let mut steps: Vec<Step> = pdo::mapping_writes(n.node_id, mode)
        .iter()
        .map(|&(i, s, v, z)| w(i, s, v, z))
        .collect();
    // Modes of operation: cyclic synchronous position (8) or velocity (9).
    steps.push(w(0x6060, 0, u32::from(mode.code()), 1));
    steps.push(w(0x60C2, 1, (c.cycle_us / 1000).max(1), 1)); // interpolation period...
    steps.push(w(0x60C2, 2, (-3i8) as u8 as u32, 1)); // ...in 10^-3 s
    steps.push(w(0x1006, 0, c.cycle_us, 4)); // communication cycle period, µs
    steps.push(w(0x1017, 0, u32::from(c.drive_heartbeat_ms), 2));
    let consumer_ms = if c.master_heartbeat_ms == 0 {
        0
    } else {
        c.drive_consumer_timeout_ms
    };
    steps.push(w(
        0x1016,
        1,
        (u32::from(c.master_node_id) << 16) | u32::from(consumer_ms),
        4,
    ));
    if let Some(window) = n.following_window_increments {
        steps.push(w(0x6065, 0, window, 4));
    }
    if mode == OpMode::Csp {
        steps.push(Step::ReadPosition);
    }
    steps
}

fn step_object(s: Step) -> (u16, u8) {
    match s {
        Step::Write {
            index, subindex, ..
        } => (index, subindex),
        Step::ReadPosition => (0x6064, 0),
        Step::CheckMode(_) => (0x6061, 0),
    }
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

/// Checks the settings the master cannot run with.
fn check_config(cfg: &CanOpenConfig) -> Result<(), String> {
    if cfg.nodes.is_empty() || cfg.nodes.len() > MAX_AXES {
        return Err(format!(
            "{} drives configured, 1..={MAX_AXES} are supported",
            cfg.nodes.len()
        ));
    }
    if !(1000..=10_000).contains(&cfg.cycle_us) || !cfg.cycle_us.is_multiple_of(1000) {
        return Err(format!(
            "cycle time {} µs: 1 to 10 ms in whole ms are supported",
            cfg.cycle_us
        ));
    }
    for (i, n) in cfg.nodes.iter().enumerate() {
        if !(1..=127).contains(&n.node_id) || n.node_id == cfg.master_node_id {
            return Err(format!(
                "node id {} of axis {i} is outside 1..127 or equals the master's",
                n.node_id
            ));
        }
        if cfg.nodes[..i].iter().any(|m| m.node_id == n.node_id) {
            return Err(format!("node id {} is used twice", n.node_id));
        }
        if !(n.increments_per_mm.is_finite() && n.increments_per_mm > 0.0) {
            return Err(format!("increments per mm of axis {i} must be positive"));
        }
        if !(n.max_velocity_mm_s.is_finite() && n.max_velocity_mm_s > 0.0) {
            return Err(format!("maximum speed of axis {i} must be positive"));
        }
    }
    let Some(sp) = &cfg.spindle else {
        return Ok(());
    };
    if !(1..=127).contains(&sp.node_id) || sp.node_id == cfg.master_node_id {
        return Err(format!(
            "node id {} of the spindle is outside 1..127 or equals the master's",
            sp.node_id
        ));
    }
    if cfg.nodes.iter().any(|m| m.node_id == sp.node_id) {
        return Err(format!(
            "node id {} of the spindle is used by an axis",
            sp.node_id
        ));
    }
    if !(sp.units_per_rpm.is_finite() && sp.units_per_rpm > 0.0) {
        return Err("velocity units per rpm of the spindle must be positive".into());
    }
    Ok(())
}

impl Node {
    fn new(c: &CanOpenConfig, cfg: NodeConfig, mode: OpMode) -> Node {
        let step = cfg.max_velocity_mm_s * cfg.increments_per_mm * f64::from(c.cycle_us) * 1e-6;
        Node {
            steps: startup_steps(c, &cfg, mode),
            max_step_increments: (step.floor() as i64).max(1),
            cfg,
            mode,
            phase: Phase::Idle,
            statusword: 0,
            position_increments: 0,
            tpdo_seen: false,
            tpdo_missing: 0,
            last_heartbeat: 0,
            nmt_state: nmt::state::PRE_OPERATIONAL,
            booted: false,
            controlword: 0,
            target_increments: 0,
            emcy_code: None,
            taken_over: false,
            homing: HomingState::Idle,
            home_since: 0,
            mode_changed: false,
        }
    }

    /// The target that holds the drive still: where it is (CSP), or speed 0 (CSV).
    fn hold_target(&self) -> i32 {
        match self.mode {
            OpMode::Csp => self.position_increments,
            OpMode::Csv => 0,
        }
    }

    /// Phases in which the node sends a TPDO every SYNC.
    fn expects_pdo(&self) -> bool {
        matches!(
            self.phase,
            Phase::Starting { .. }
                | Phase::Enabling { .. }
                | Phase::Operational
                | Phase::Homing(_)
                | Phase::Stopped
        )
    }

    /// Whether the node gets an RPDO this tick: it is known to be in NMT operational and the
    /// master talks to it (a drive-level fault keeps the power stage off over the RPDO).
    fn gets_rpdo(&self) -> bool {
        self.nmt_state == nmt::state::OPERATIONAL
            && match self.phase {
                Phase::Starting { .. }
                | Phase::Enabling { .. }
                | Phase::Operational
                | Phase::Homing(_)
                | Phase::Stopped => true,
                // A silent drive may still listen: controlword 0 switches it off.
                Phase::Faulted(r) => is_drive_level(r) || r == FaultReason::Timeout,
                Phase::ShuttingDown(off) => off != Off::Done,
                _ => false,
            }
    }

    fn is_off(&self) -> bool {
        matches!(self.phase, Phase::Idle | Phase::ShuttingDown(Off::Done))
    }
}

impl<P: CanPort> CanOpenMaster<P> {
    /// A master for `cfg.nodes` (one per axis, in axis order) on `port`; `name` is the
    /// interface name for logs. Nothing is sent before [`DriveBus::enable`].
    pub fn new(port: P, name: &str, cfg: CanOpenConfig) -> Result<Self, String> {
        check_config(&cfg)?;
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
        Ok(CanOpenMaster {
            port,
            name: name.to_owned(),
            axes: cfg.nodes.len(),
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

    fn node_index(&self, node_id: u8) -> Option<usize> {
        self.nodes.iter().position(|n| n.cfg.node_id == node_id)
    }

    /// The axis a fault of node `i` names: its index, or the spindle.
    fn axis_of(&self, i: usize) -> u8 {
        if i < self.axes {
            i as u8
        } else {
            crate::SPINDLE_AXIS
        }
    }

    fn fault(&mut self, i: usize, reason: FaultReason) {
        let n = &mut self.nodes[i];
        if !matches!(
            n.phase,
            Phase::Faulted(_) | Phase::Idle | Phase::ShuttingDown(_)
        ) {
            n.phase = Phase::Faulted(reason);
            if n.homing == HomingState::Running {
                n.homing = HomingState::Aborted;
            }
        }
    }

    fn send_step(&mut self, i: usize, step: usize) {
        let s = self.nodes[i].steps[step];
        self.send_sdo(i, s);
    }

    /// The SDO request of one step.
    fn send_sdo(&mut self, i: usize, s: Step) {
        let id = self.nodes[i].cfg.node_id;
        let f = match s {
            Step::Write {
                index,
                subindex,
                value,
                size,
            } => sdo::download(id, index, subindex, value, size),
            Step::ReadPosition | Step::CheckMode(_) => {
                let (index, subindex) = step_object(s);
                sdo::upload(id, index, subindex)
            }
        };
        self.send(&f);
    }

    fn on_frame(&mut self, f: &Frame) {
        let (code, node_id) = cob::split(f.id);
        let Some(i) = self.node_index(node_id) else {
            return;
        };
        match code {
            cob::TPDO1 => self.on_tpdo(i, f),
            cob::EMCY => {
                let Some(e) = Emcy::decode(f.payload()) else {
                    return;
                };
                if e.code == 0 || self.nodes[i].phase == Phase::Idle {
                    return;
                }
                self.nodes[i].emcy_code = Some(e.code);
                let reason = if e.code == emcy::FOLLOWING_ERROR {
                    FaultReason::FollowingError
                } else {
                    FaultReason::DriveFault { code: e.code }
                };
                self.fault(i, reason);
            }
            cob::HEARTBEAT => {
                if let Some(&state) = f.payload().first() {
                    self.on_heartbeat(i, state);
                }
            }
            cob::SDO_TX => {
                if let Some(r) = sdo::parse_response(f.payload()) {
                    self.on_sdo_response(i, r);
                }
            }
            _ => {}
        }
    }

    fn on_tpdo(&mut self, i: usize, f: &Frame) {
        match Tpdo::decode(f.payload()) {
            Some(t) => {
                let n = &mut self.nodes[i];
                n.statusword = t.statusword;
                n.position_increments = t.position_increments;
                n.tpdo_seen = true;
                // Only a node in NMT operational sends PDOs.
                n.nmt_state = nmt::state::OPERATIONAL;
            }
            // CAN frames are checked by CRC: a wrong length is a mapping mismatch, not noise.
            None if self.nodes[i].expects_pdo() => self.fault(
                i,
                FaultReason::PdoLength {
                    cob_id: f.id,
                    len: f.len,
                    expected: pdo::LEN as u8,
                },
            ),
            None => {}
        }
    }

    fn on_heartbeat(&mut self, i: usize, state: u8) {
        let tick = self.tick;
        let n = &mut self.nodes[i];
        n.last_heartbeat = tick;
        if state == nmt::state::BOOT_UP {
            n.booted = true;
            n.nmt_state = nmt::state::PRE_OPERATIONAL;
            if matches!(
                n.phase,
                Phase::Starting { .. }
                    | Phase::Enabling { .. }
                    | Phase::Operational
                    | Phase::Homing(_)
                    | Phase::Stopped
            ) {
                self.fault(i, FaultReason::NmtStateChanged { state });
            }
            return;
        }
        // A heartbeat sent before our NMT start may still arrive while starting.
        if !matches!(n.phase, Phase::Starting { .. }) {
            n.nmt_state = state;
        }
        if state != nmt::state::OPERATIONAL
            && matches!(
                n.phase,
                Phase::Enabling { .. } | Phase::Operational | Phase::Homing(_) | Phase::Stopped
            )
        {
            self.fault(i, FaultReason::NmtStateChanged { state });
        }
    }

    fn on_sdo_response(&mut self, i: usize, r: Response) {
        match self.nodes[i].phase {
            Phase::Configuring { step, .. } => {
                let expected = self.nodes[i].steps[step];
                if r.object() != step_object(expected) {
                    return; // a late answer to an earlier, retried request
                }
                match r {
                    Response::Abort { code, .. } => {
                        let (index, subindex) = r.object();
                        let reason = FaultReason::SdoAbort {
                            index,
                            subindex,
                            abort_code: code,
                        };
                        self.fault(i, reason);
                    }
                    Response::UploadOk { value, .. } => {
                        if expected == Step::ReadPosition {
                            self.nodes[i].position_increments = value as i32;
                        }
                        self.next_step(i, step);
                    }
                    Response::DownloadOk { .. } => self.next_step(i, step),
                }
            }
            // Done either way: a drive that refuses is switched off and told to stop all the
            // same.
            Phase::ShuttingDown(Off::ClearConsumer { .. }) if r.object() == (0x1016, 1) => {
                self.leave_bus(i)
            }
            Phase::Homing(Home::Sdo { leaving, step, .. }) => {
                self.on_homing_sdo(i, leaving, step, r)
            }
            _ => {}
        }
    }

    fn next_step(&mut self, i: usize, step: usize) {
        let tick = self.tick;
        if step + 1 < self.nodes[i].steps.len() {
            self.nodes[i].phase = Phase::Configuring {
                step: step + 1,
                sent_at: tick,
                retried: false,
            };
            self.send_step(i, step + 1);
        } else {
            self.nodes[i].phase = Phase::Configured;
        }
    }

    /// NMT start for every configured node once no node is still being configured: the
    /// drives get SYNC and PDOs only after all of them have their configuration.
    fn start_configured(&mut self) {
        if self.shutting_down
            || self.nodes.iter().any(|n| {
                matches!(
                    n.phase,
                    Phase::ResetPending { .. } | Phase::Booting { .. } | Phase::Configuring { .. }
                )
            })
        {
            return;
        }
        let tick = self.tick;
        for i in 0..self.nodes.len() {
            let n = &mut self.nodes[i];
            if n.phase != Phase::Configured {
                continue;
            }
            n.phase = Phase::Starting { since: tick };
            n.tpdo_seen = false;
            n.last_heartbeat = tick;
            n.nmt_state = nmt::state::OPERATIONAL;
            n.target_increments = n.hold_target();
            n.controlword = cw::DISABLE_VOLTAGE;
            let id = n.cfg.node_id;
            self.send(&nmt::command(nmt::Command::Start, id));
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

    fn ticks(&self, ms: u32) -> u64 {
        ticks(ms, self.cfg.cycle_us)
    }

    /// Watchdogs of a started node: a TPDO every SYNC, the heartbeat.
    fn watch(&mut self, i: usize) {
        let hb_ticks = self.ticks(self.cfg.heartbeat_timeout_ms);
        let missing_limit = self.cfg.tpdo_missing_ticks;
        let tick = self.tick;
        let n = &mut self.nodes[i];
        if !matches!(
            n.phase,
            Phase::Enabling { .. } | Phase::Operational | Phase::Homing(_) | Phase::Stopped
        ) {
            return;
        }
        if n.tpdo_seen {
            n.tpdo_missing = 0;
        } else {
            n.tpdo_missing += 1;
        }
        if n.tpdo_missing > missing_limit {
            self.fault(i, FaultReason::Timeout);
        } else if tick - n.last_heartbeat > hb_ticks {
            self.fault(i, FaultReason::HeartbeatLost);
        }
    }

    /// Advances node `i` by one tick; `target` is this tick's setpoint in drive units.
    fn update_node(&mut self, i: usize, target: i32) {
        self.watch(i);
        match self.nodes[i].phase {
            Phase::Idle | Phase::Configured | Phase::ShuttingDown(Off::Done) => {}
            Phase::ResetPending { command } => {
                let tick = self.tick;
                let n = &mut self.nodes[i];
                n.booted = false;
                n.emcy_code = None;
                n.nmt_state = nmt::state::PRE_OPERATIONAL;
                n.phase = Phase::Booting {
                    since: tick,
                    command,
                };
                let id = n.cfg.node_id;
                self.send(&nmt::command(command, id));
            }
            Phase::Booting { since, command } => self.boot(i, since, command),
            Phase::Configuring {
                step,
                sent_at,
                retried,
            } => self.configure(i, step, sent_at, retried),
            Phase::Starting { since } => self.start(i, since),
            Phase::Enabling { since } => self.enable_step(i, since),
            Phase::Operational => self.operate(i, target),
            Phase::Homing(h) => self.update_homing(i, h),
            Phase::Stopped => {
                // The safe state's controlword stays; the drive holds where it stands.
                let n = &mut self.nodes[i];
                n.target_increments = n.hold_target();
            }
            Phase::Faulted(_) => {}
            Phase::ShuttingDown(Off::PowerDown { since }) => self.power_down(i, since),
            Phase::ShuttingDown(Off::ClearConsumer { sent_at, retried }) => {
                self.clear_consumer(i, sent_at, retried)
            }
        }
        // A faulted node gets its power stage switched off in this tick's RPDO; its target
        // stays where the drive is.
        let n = &mut self.nodes[i];
        if matches!(n.phase, Phase::Faulted(_)) {
            n.controlword = cw::DISABLE_VOLTAGE;
            n.target_increments = n.hold_target();
            n.taken_over = false;
        }
        n.tpdo_seen = false;
    }

    fn boot(&mut self, i: usize, since: u64, command: nmt::Command) {
        let boot_ticks = self.ticks(self.cfg.boot_timeout_ms);
        let tick = self.tick;
        let n = &mut self.nodes[i];
        if n.booted {
            n.phase = Phase::Configuring {
                step: 0,
                sent_at: tick,
                retried: false,
            };
            self.send_step(i, 0);
        } else if tick - since > boot_ticks {
            self.fault(i, FaultReason::NoBootUp);
        } else if (tick - since).is_multiple_of(boot_ticks / 3 + 1) {
            // The reset may have been lost (a drive busy or not yet listening): ask again,
            // twice, before giving up.
            let id = n.cfg.node_id;
            self.send(&nmt::command(command, id));
        }
    }

    fn configure(&mut self, i: usize, step: usize, sent_at: u64, retried: bool) {
        if self.tick - sent_at <= self.ticks(self.cfg.sdo_timeout_ms) {
            return;
        }
        if retried {
            let (index, subindex) = step_object(self.nodes[i].steps[step]);
            self.fault(i, FaultReason::SdoTimeout { index, subindex });
        } else {
            self.nodes[i].phase = Phase::Configuring {
                step,
                sent_at: self.tick,
                retried: true,
            };
            self.send_step(i, step);
        }
    }

    fn start(&mut self, i: usize, since: u64) {
        let boot_ticks = self.ticks(self.cfg.boot_timeout_ms);
        let tick = self.tick;
        let n = &mut self.nodes[i];
        n.target_increments = n.hold_target();
        if n.tpdo_seen {
            n.tpdo_missing = 0;
            n.phase = Phase::Enabling { since: tick };
            self.enable_step(i, tick);
        } else if tick - since > boot_ticks {
            self.fault(i, FaultReason::Timeout);
        }
    }

    /// The CiA 402 enable sequence. It acts only on a statusword that arrived this tick: after
    /// a reset the last one known may be stale (the drive faulted or switched off since).
    fn enable_step(&mut self, i: usize, since: u64) {
        let enable_ticks = self.ticks(self.cfg.enable_timeout_ms);
        let tick = self.tick;
        let n = &mut self.nodes[i];
        // The target follows the actual position (a spindle: stands) until enabled.
        n.target_increments = n.hold_target();
        let state = PowerState::from_statusword(n.statusword);
        if tick - since > enable_ticks {
            let statusword = n.statusword;
            self.fault(i, FaultReason::EnableTimeout { statusword });
        } else if !n.tpdo_seen {
            // Keep the last controlword until the drive reports again.
        } else if state == PowerState::OperationEnabled {
            n.phase = Phase::Operational;
            n.controlword = cw::ENABLE_OPERATION_CMD;
            n.taken_over = n.mode == OpMode::Csv;
        } else {
            n.controlword = cia402::controlword_toward_enabled(state, n.controlword);
        }
    }

    fn operate(&mut self, i: usize, target: i32) {
        // The master's following-error check is a position check: not for a velocity node.
        let fe_limit = self
            .cfg
            .following_error_limit_mm
            .filter(|_| self.nodes[i].mode == OpMode::Csp)
            .map(|mm| mm * self.nodes[i].cfg.increments_per_mm);
        let n = &mut self.nodes[i];
        let s = n.statusword;
        let state = PowerState::from_statusword(s);
        let lag = f64::from(n.target_increments) - f64::from(n.position_increments);
        if s & sw::FOLLOWING_ERROR != 0 {
            self.fault(i, FaultReason::FollowingError);
        } else if matches!(state, PowerState::Fault | PowerState::FaultReactionActive) {
            let code = n.emcy_code.unwrap_or(0);
            self.fault(i, FaultReason::DriveFault { code });
        } else if state != PowerState::OperationEnabled {
            self.fault(i, FaultReason::DriveDisabled { statusword: s });
        } else if fe_limit.is_some_and(|l| lag.abs() > l) {
            self.fault(i, FaultReason::FollowingError);
        } else if n.taken_over {
            n.target_increments = target;
        } else if (i64::from(target) - i64::from(n.target_increments)).abs()
            <= n.max_step_increments
        {
            // The controller commands from where the drive is: from now on it leads.
            n.taken_over = true;
            n.target_increments = target;
        } else {
            // The controller has not yet taken its commanded position from this drive's
            // actual position (it does so once every drive is enabled): hold still.
            n.target_increments = n.hold_target();
        }
    }

    /// Shutdown: walk the power stage down (07h → 06h → 00h, or 02h → 00h) on fresh
    /// statuswords.
    fn power_down(&mut self, i: usize, since: u64) {
        let enable_ticks = self.ticks(self.cfg.enable_timeout_ms);
        let toward_off = match self.cfg.shutdown {
            ShutdownMode::Disable => cia402::controlword_toward_disabled,
            ShutdownMode::QuickStop => cia402::controlword_toward_disabled_by_quick_stop,
        };
        let tick = self.tick;
        let n = &mut self.nodes[i];
        let state = PowerState::from_statusword(n.statusword);
        let off = matches!(
            state,
            PowerState::SwitchOnDisabled
                | PowerState::NotReadyToSwitchOn
                | PowerState::Fault
                | PowerState::FaultReactionActive
        );
        if (n.tpdo_seen && off)
            || tick - since > enable_ticks
            || n.nmt_state != nmt::state::OPERATIONAL
        {
            n.controlword = cw::DISABLE_VOLTAGE;
            self.send_clear_consumer(i, false);
        } else if n.tpdo_seen {
            n.controlword = toward_off(state);
        }
    }

    fn send_clear_consumer(&mut self, i: usize, retried: bool) {
        self.nodes[i].phase = Phase::ShuttingDown(Off::ClearConsumer {
            sent_at: self.tick,
            retried,
        });
        let id = self.nodes[i].cfg.node_id;
        self.send(&sdo::download(id, 0x1016, 1, 0, 4));
    }

    fn clear_consumer(&mut self, i: usize, sent_at: u64, retried: bool) {
        if self.tick - sent_at <= self.ticks(self.cfg.sdo_timeout_ms) {
            return;
        }
        if retried {
            self.leave_bus(i);
        } else {
            self.send_clear_consumer(i, true);
        }
    }

    /// Last step of a node's shutdown: NMT pre-operational (PDOs stop, SDO stays possible).
    fn leave_bus(&mut self, i: usize) {
        let n = &mut self.nodes[i];
        n.phase = Phase::ShuttingDown(Off::Done);
        n.nmt_state = nmt::state::PRE_OPERATIONAL;
        let id = n.cfg.node_id;
        self.send(&nmt::command(nmt::Command::EnterPreOperational, id));
    }

    /// The spindle node, if configured.
    fn spindle(&self) -> Option<&Node> {
        self.nodes.get(self.axes)
    }

    fn state_of(phase: Phase) -> DriveState {
        match phase {
            Phase::Idle | Phase::ShuttingDown(_) | Phase::Stopped => DriveState::Disabled,
            // The drive homes on its own, enabled: the axis counts as operational.
            Phase::Operational | Phase::Homing(_) => DriveState::Operational,
            Phase::Faulted(_) => DriveState::Fault,
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

    /// SYNC (once a node is started), one RPDO per node in NMT operational, the heartbeat.
    fn send_cyclic(&mut self) {
        if self.nodes.iter().any(Node::gets_rpdo) {
            self.send(&pdo::sync());
        }
        for i in 0..self.nodes.len() {
            let n = &self.nodes[i];
            if n.gets_rpdo() {
                let f = Rpdo {
                    controlword: n.controlword,
                    target_increments: n.target_increments,
                }
                .encode(n.cfg.node_id);
                self.send(&f);
            }
        }
        let hb = self.ticks(u32::from(self.cfg.master_heartbeat_ms));
        if hb > 0 && self.tick.is_multiple_of(hb) {
            let id = self.cfg.master_node_id;
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
                position_mm: f64::from(n.position_increments) / n.cfg.increments_per_mm,
                state: Self::state_of(n.phase),
            };
        }
        let (spindle_rpm, spindle_state) = match self.spindle() {
            Some(n) if n.phase == Phase::Operational => (
                f64::from(n.position_increments) / n.cfg.increments_per_mm,
                DriveState::Operational,
            ),
            Some(n) => (0.0, Self::state_of(n.phase)),
            None => (0.0, DriveState::Disabled),
        };
        feedback.spindle_rpm = spindle_rpm;
        feedback.spindle_state = spindle_state;
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
            if let Phase::Faulted(reason) = n.phase {
                return Err(BusFault {
                    axis: Some(self.axis_of(i)),
                    node: Some(n.cfg.node_id),
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

/// A value in drive units, rounded and saturated to the 32-bit PDO field.
fn to_units(value: f64, units_per: f64) -> i32 {
    (value * units_per)
        .round()
        .clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
}

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
            self.update_node(i, target);
        }
        self.interrupt_homing_on_fault();
        self.start_configured();
        if self.enabled {
            self.send_cyclic();
        }
        if self.shutting_down && self.nodes.iter().all(Node::is_off) {
            // Every drive has left: SYNC and the master's heartbeat stop.
            self.enabled = false;
        }
        // A transmit queue that stays full (nobody acknowledges, bus jammed) is a bus fault.
        if self.tx_blocked_ticks == blocked_before {
            self.tx_blocked_ticks = 0;
        } else if self.tx_blocked_ticks > self.cfg.tpdo_missing_ticks {
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
    }

    fn reset(&mut self) {
        if self.shutting_down {
            return;
        }
        self.enabled = true;
        let whole_bus = self.bus_fault.take().is_some();
        self.error_score = 0;
        self.tx_blocked_ticks = 0;
        let tick = self.tick;
        let hb_ticks = self.ticks(self.cfg.heartbeat_timeout_ms);
        let restart = Phase::ResetPending {
            command: nmt::Command::ResetCommunication,
        };
        for n in &mut self.nodes {
            // Still in NMT operational by its own latest word: a fault reset over the RPDO
            // is enough. Otherwise (it left operational, or went quiet) the whole start-up.
            let talking =
                n.nmt_state == nmt::state::OPERATIONAL && tick - n.last_heartbeat <= hb_ticks;
            match n.phase {
                // A reference run that did not return to CSP: restart, so the configuration
                // sets the mode again.
                Phase::Faulted(_) | Phase::Stopped if n.mode_changed => n.phase = restart,
                Phase::Faulted(r) if is_drive_level(r) && !whole_bus && talking => {
                    n.emcy_code = None;
                    n.tpdo_missing = 0;
                    n.phase = Phase::Enabling { since: tick };
                }
                Phase::Stopped if !whole_bus => {
                    n.tpdo_missing = 0;
                    n.phase = Phase::Enabling { since: tick };
                }
                Phase::Faulted(_) | Phase::Stopped => n.phase = restart,
                Phase::Idle => {
                    n.phase = Phase::ResetPending {
                        command: nmt::Command::ResetNode,
                    }
                }
                _ if whole_bus => n.phase = restart,
                _ => {}
            }
        }
    }

    fn enable_timeout_ticks(&self) -> u32 {
        // The slowest path a node may take before it is operational or faulted by its own
        // timeouts: boot-up, every SDO with its retry, NMT start to the first TPDO, enable.
        let c = &self.cfg;
        let steps = self.nodes.iter().map(|n| n.steps.len()).max().unwrap_or(0) as u64;
        let boot = self.ticks(c.boot_timeout_ms) + 1;
        let sdo = 2 * (self.ticks(c.sdo_timeout_ms) + 1);
        let total = 2 * boot + steps * sdo + self.ticks(c.enable_timeout_ms) + 2;
        u32::try_from(total).unwrap_or(u32::MAX)
    }

    fn shutdown(&mut self) {
        if self.shutting_down {
            return;
        }
        self.shutting_down = true;
        let tick = self.tick;
        for i in 0..self.nodes.len() {
            let n = &mut self.nodes[i];
            match n.phase {
                Phase::Idle
                | Phase::ResetPending { .. }
                | Phase::Booting { .. }
                | Phase::Faulted(FaultReason::NoBootUp) => {
                    n.phase = Phase::ShuttingDown(Off::Done);
                }
                Phase::Starting { .. }
                | Phase::Enabling { .. }
                | Phase::Operational
                | Phase::Homing(_)
                | Phase::Stopped => {
                    n.phase = Phase::ShuttingDown(Off::PowerDown { since: tick });
                }
                Phase::Faulted(r) if is_drive_level(r) => {
                    n.phase = Phase::ShuttingDown(Off::PowerDown { since: tick });
                }
                // Configured but not started, or communication lost: no power stage to walk
                // down, but the heartbeat watch may be set.
                Phase::Configuring { .. } | Phase::Configured | Phase::Faulted(_) => {
                    self.send_clear_consumer(i, false);
                }
                Phase::ShuttingDown(_) => {}
            }
        }
    }

    fn is_shut_down(&self) -> bool {
        self.shutting_down && !self.enabled
    }

    fn safe_state(&mut self) {
        self.enter_safe_state();
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
            self.start_homing_node(axis);
        }
    }

    fn stop_homing(&mut self, axis: usize) {
        if axis < self.axes {
            self.stop_homing_node(axis);
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
mod tests {
    use std::collections::VecDeque;

    use super::*;

    /// A port fed by the test: `rx` is what the master will receive, `tx` what it sent.
    #[derive(Default)]
    struct FakePort {
        rx: VecDeque<RxEvent>,
        tx: Vec<Frame>,
    }

    impl CanPort for FakePort {
        fn send(&mut self, frame: &Frame) -> Result<(), PortError> {
            self.tx.push(*frame);
            Ok(())
        }
        fn try_recv(&mut self) -> Result<Option<RxEvent>, PortError> {
            Ok(self.rx.pop_front())
        }
    }

    fn master(nodes: &[u8]) -> CanOpenMaster<FakePort> {
        let cfg = CanOpenConfig::new(
            nodes
                .iter()
                .map(|&node_id| NodeConfig {
                    node_id,
                    increments_per_mm: 1000.0,
                    following_window_increments: Some(5000),
                    ..NodeConfig::new(node_id, 1000.0)
                })
                .collect(),
        );
        CanOpenMaster::new(FakePort::default(), "fake", cfg).unwrap()
    }

    fn step(m: &mut CanOpenMaster<FakePort>) -> (Vec<Frame>, Result<(), BusFault>) {
        let mut fb = CycleFeedback::default();
        let cmd = CycleCommand::default();
        let r = m.cycle(&cmd, &mut fb);
        (std::mem::take(&mut m.port.tx), r)
    }

    fn rx(m: &mut CanOpenMaster<FakePort>, f: Frame) {
        m.port.rx.push_back(RxEvent::Frame(f));
    }

    /// The drive `node` reports continuous overcurrent (EMCY 2310h).
    fn overcurrent(m: &mut CanOpenMaster<FakePort>, node: u8) {
        let emcy = Emcy {
            code: 0x2310,
            register: 1,
            vendor: [0; 5],
        };
        rx(m, emcy.encode(node));
    }

    /// Answers every SDO request of the last tick as a cooperative drive would.
    fn answer_sdos(m: &mut CanOpenMaster<FakePort>, sent: &[Frame]) -> usize {
        let mut n = 0;
        for f in sent.iter().filter(|f| f.id & 0x780 == cob::SDO_RX) {
            let node = (f.id & 0x7F) as u8;
            let answer = match sdo::parse_request(f.payload()).unwrap() {
                sdo::Request::Download {
                    index, subindex, ..
                } => sdo::download_ok(node, index, subindex),
                sdo::Request::Upload { index, subindex } => {
                    sdo::upload_ok(node, index, subindex, 2500, 4)
                }
            };
            rx(m, answer);
            n += 1;
        }
        n
    }

    /// Drives node 3 through boot-up and configuration; returns the SDO writes seen.
    fn bring_up(m: &mut CanOpenMaster<FakePort>) -> Vec<(u16, u8, u32)> {
        m.enable();
        let (sent, r) = step(m);
        assert!(r.is_ok());
        assert!(sent.contains(&nmt::command(nmt::Command::ResetNode, 3)));
        rx(m, nmt::heartbeat(3, nmt::state::BOOT_UP));
        let mut writes = Vec::new();
        for _ in 0..100 {
            let (sent, r) = step(m);
            assert!(r.is_ok(), "{r:?}");
            for f in &sent {
                if let Ok(sdo::Request::Download {
                    index,
                    subindex,
                    value,
                    ..
                }) = sdo::parse_request(f.payload())
                    && f.id == 0x603
                {
                    writes.push((index, subindex, value));
                }
            }
            if sent.contains(&nmt::command(nmt::Command::Start, 3)) {
                return writes;
            }
            answer_sdos(m, &sent);
        }
        panic!("no NMT start");
    }

    fn tpdo(m: &mut CanOpenMaster<FakePort>, state: PowerState, extra: u16, pos: i32) {
        rx(
            m,
            Tpdo {
                statusword: state.statusword_bits() | extra,
                position_increments: pos,
            }
            .encode(3),
        );
        rx(m, nmt::heartbeat(3, nmt::state::OPERATIONAL));
    }

    fn rpdo_of(sent: &[Frame]) -> Rpdo {
        let f = sent.iter().find(|f| f.id == 0x203).expect("an RPDO");
        Rpdo::decode(f.payload()).unwrap()
    }

    #[test]
    fn configures_the_drive_for_csp() {
        let mut m = master(&[3]);
        let writes = bring_up(&mut m);
        for w in [
            (0x6060, 0, 8),
            (0x60C2, 1, 4),
            (0x60C2, 2, 0xFD),
            (0x1006, 0, 4000),
            (0x1017, 0, 100),
            (0x1016, 1, (127 << 16) | 500),
            (0x6065, 0, 5000),
            (0x1600, 1, 0x6040_0010),
            (0x1A00, 2, 0x6064_0020),
            (0x1800, 1, 0x183),
        ] {
            assert!(writes.contains(&w), "missing write {w:X?}");
        }
        // The 0x6064 upload (2500 increments) is the first target: nothing jumps.
        let (sent, _) = step(&mut m);
        assert_eq!(sent[0], pdo::sync());
        assert_eq!(
            rpdo_of(&sent),
            Rpdo {
                controlword: 0,
                target_increments: 2500
            }
        );
    }

    #[test]
    fn enables_through_the_state_machine_and_follows_setpoints() {
        let mut m = master(&[3]);
        bring_up(&mut m);
        let mut state = PowerState::SwitchOnDisabled;
        let mut last_cw = 0;
        let mut cws = Vec::new();
        for _ in 0..10 {
            tpdo(&mut m, state, 0, 2500);
            let (sent, r) = step(&mut m);
            assert!(r.is_ok());
            let c = rpdo_of(&sent).controlword;
            cws.push(c);
            state = cia402::apply_controlword(state, last_cw, c);
            last_cw = c;
        }
        assert_eq!(state, PowerState::OperationEnabled, "controlwords {cws:X?}");
        assert!(cws.starts_with(&[0x06, 0x07, 0x0F]), "{cws:X?}");
        // Operational: setpoints in mm become increments.
        let mut fb = CycleFeedback::default();
        let mut cmd = CycleCommand::default();
        cmd.positions_mm[0] = 2.75;
        tpdo(&mut m, state, 0, 2600);
        m.cycle(&cmd, &mut fb).unwrap();
        assert_eq!(fb.axes[0].state, DriveState::Operational);
        assert!((fb.axes[0].position_mm - 2.6).abs() < 1e-9);
        assert_eq!(rpdo_of(&m.port.tx).target_increments, 2750);
    }

    fn operational(m: &mut CanOpenMaster<FakePort>) {
        bring_up(m);
        for _ in 0..3 {
            tpdo(m, PowerState::OperationEnabled, 0, 2500);
            let (_, r) = step(m);
            assert!(r.is_ok());
        }
        assert_eq!(m.nodes[0].phase, Phase::Operational);
    }

    #[test]
    fn missing_tpdo_faults_after_the_configured_ticks_only() {
        let mut m = master(&[3]);
        operational(&mut m);
        for _ in 0..25 {
            rx(&mut m, nmt::heartbeat(3, nmt::state::OPERATIONAL));
            assert!(step(&mut m).1.is_ok());
        }
        let e = step(&mut m).1.unwrap_err();
        assert_eq!(
            e,
            BusFault {
                axis: Some(0),
                node: Some(3),
                reason: FaultReason::Timeout
            }
        );
        // Faulted drive gets its power stage switched off; the fault persists until reset.
        let (sent, r) = step(&mut m);
        assert!(r.is_err());
        assert_eq!(rpdo_of(&sent).controlword, 0);
    }

    #[test]
    fn lost_heartbeat_faults() {
        let mut m = master(&[3]);
        operational(&mut m);
        let mut fault = None;
        for i in 0..200 {
            rx(
                &mut m,
                Tpdo {
                    statusword: 0x0237,
                    position_increments: 2500,
                }
                .encode(3),
            );
            if let Err(e) = step(&mut m).1 {
                fault = Some((i, e.reason));
                break;
            }
        }
        let (i, reason) = fault.expect("heartbeat loss must fault");
        assert_eq!(reason, FaultReason::HeartbeatLost);
        assert!((120..=130).contains(&i), "after {i} ticks");
    }

    #[test]
    fn emcy_and_statusword_faults_then_reset_resumes() {
        let mut m = master(&[3]);
        operational(&mut m);
        overcurrent(&mut m, 3);
        tpdo(&mut m, PowerState::Fault, 0, 2500);
        let e = step(&mut m).1.unwrap_err();
        assert_eq!(e.reason, FaultReason::DriveFault { code: 0x2310 });
        assert!(e.to_string().contains("overcurrent"), "{e}");
        // Reset: fault reset edge over the RPDO, no NMT restart.
        m.reset();
        tpdo(&mut m, PowerState::Fault, 0, 2500);
        let (sent, r) = step(&mut m);
        assert!(r.is_ok());
        assert_eq!(rpdo_of(&sent).controlword, cw::FAULT_RESET);
        assert!(!sent.iter().any(|f| f.id == cob::NMT));
        tpdo(&mut m, PowerState::SwitchOnDisabled, 0, 2500);
        tpdo(&mut m, PowerState::ReadyToSwitchOn, 0, 2500);
        step(&mut m).1.unwrap();
        step(&mut m).1.unwrap();
        tpdo(&mut m, PowerState::OperationEnabled, 0, 2500);
        step(&mut m).1.unwrap();
        assert_eq!(m.nodes[0].phase, Phase::Operational);

        // Following error bit 13 names the following error.
        tpdo(&mut m, PowerState::Fault, sw::FOLLOWING_ERROR, 2500);
        assert_eq!(
            step(&mut m).1.unwrap_err().reason,
            FaultReason::FollowingError
        );
    }

    /// Issue #23, seen 3: after a reset the last statusword known (Operation Enabled, from
    /// before the fault) is stale; the master waits for the drive's next TPDO and walks the
    /// sequence from the state that reports.
    #[test]
    fn reset_waits_for_a_fresh_statusword() {
        let mut m = master(&[3]);
        operational(&mut m);
        overcurrent(&mut m, 3);
        rx(&mut m, nmt::heartbeat(3, nmt::state::OPERATIONAL));
        assert!(step(&mut m).1.is_err());
        m.reset();
        for _ in 0..5 {
            rx(&mut m, nmt::heartbeat(3, nmt::state::OPERATIONAL));
            let (sent, r) = step(&mut m);
            assert!(r.is_ok());
            assert_eq!(rpdo_of(&sent).controlword, cw::DISABLE_VOLTAGE);
        }
        tpdo(&mut m, PowerState::SwitchOnDisabled, 0, 2500);
        let (sent, _) = step(&mut m);
        assert_eq!(rpdo_of(&sent).controlword, cw::SHUTDOWN);
    }

    /// A TPDO of the wrong length is a mapping fault, named with its COB-ID and lengths; the
    /// reset restarts the node (reset communication, configuration).
    #[test]
    fn short_tpdo_is_a_pdo_length_fault() {
        let mut m = master(&[3]);
        operational(&mut m);
        rx(&mut m, Frame::new(0x183, &[0x37, 0x02, 0xC4]));
        let e = step(&mut m).1.unwrap_err();
        assert_eq!(
            e.reason,
            FaultReason::PdoLength {
                cob_id: 0x183,
                len: 3,
                expected: 6
            }
        );
        m.reset();
        let (sent, _) = step(&mut m);
        assert!(sent.contains(&nmt::command(nmt::Command::ResetCommunication, 3)));
        assert!(
            !sent.iter().any(|f| f.id == 0x203),
            "no RPDO while restarting"
        );
    }

    /// The enable deadline the bus reports covers every per-node timeout on the way.
    #[test]
    fn enable_deadline_covers_the_node_timeouts() {
        let m = master(&[3]);
        let per_node = ticks(3000, 4000) * 2 + 2000 / 4;
        assert!(u64::from(m.enable_timeout_ticks()) > per_node);
    }

    #[test]
    fn bus_off_and_bad_frames() {
        let mut m = master(&[3]);
        operational(&mut m);
        // Garbage must not panic: short EMCY, empty heartbeat, unknown nodes.
        for f in [
            Frame::new(0x83, &[1, 2]),
            Frame::new(0x703, &[]),
            Frame::new(0x583, &[0xFF; 8]),
            Frame::new(0x185, &[0; 6]),
        ] {
            rx(&mut m, f);
        }
        tpdo(&mut m, PowerState::OperationEnabled, 0, 2500);
        assert!(step(&mut m).1.is_ok());
        m.port.rx.push_back(RxEvent::Error {
            class: err_class::BUS_OFF,
            data: [0; 8],
        });
        let e = step(&mut m).1.unwrap_err();
        assert_eq!(
            e,
            BusFault {
                axis: None,
                node: None,
                reason: FaultReason::BusOff
            }
        );
        // Reset after bus-off restarts every node (reset communication, configuration).
        m.reset();
        let (sent, _) = step(&mut m);
        assert!(sent.contains(&nmt::command(nmt::Command::ResetCommunication, 3)));
    }

    #[test]
    fn error_frames_fault_only_beyond_the_limit() {
        let mut m = master(&[3]);
        operational(&mut m);
        let burst = |m: &mut CanOpenMaster<FakePort>, n: usize| {
            for _ in 0..n {
                m.port.rx.push_back(RxEvent::Error {
                    class: err_class::PROTOCOL,
                    data: [0; 8],
                });
            }
        };
        // 20 error frames are tolerated, and forgiven one per 10 ticks.
        burst(&mut m, 20);
        tpdo(&mut m, PowerState::OperationEnabled, 0, 2500);
        assert!(step(&mut m).1.is_ok());
        for _ in 0..20 {
            tpdo(&mut m, PowerState::OperationEnabled, 0, 2500);
            assert!(step(&mut m).1.is_ok());
        }
        burst(&mut m, 2);
        tpdo(&mut m, PowerState::OperationEnabled, 0, 2500);
        assert!(step(&mut m).1.is_ok(), "two were forgiven meanwhile");
        burst(&mut m, 10);
        let e = step(&mut m).1.unwrap_err();
        assert_eq!((e.axis, e.reason), (None, FaultReason::ErrorFrames));
    }

    #[test]
    fn sdo_abort_and_silence_are_reported_with_the_object() {
        let mut m = master(&[3]);
        m.enable();
        let _ = step(&mut m);
        rx(&mut m, nmt::heartbeat(3, 0));
        let (sent, _) = step(&mut m);
        let first = sent.iter().find(|f| f.id == 0x603).unwrap();
        let sdo::Request::Download {
            index, subindex, ..
        } = sdo::parse_request(first.payload()).unwrap()
        else {
            panic!()
        };
        rx(
            &mut m,
            sdo::abort(3, index, subindex, sdo::abort::CANNOT_MAP),
        );
        let e = step(&mut m).1.unwrap_err();
        assert_eq!(
            e.reason,
            FaultReason::SdoAbort {
                index,
                subindex,
                abort_code: sdo::abort::CANNOT_MAP
            }
        );
        assert!(e.to_string().contains("cannot be mapped"), "{e}");

        let mut m = master(&[3]);
        m.enable();
        let mut r = Ok(());
        let mut resets = 0;
        for _ in 0..1000 {
            let (sent, res) = step(&mut m);
            resets += sent
                .iter()
                .filter(|f| **f == nmt::command(nmt::Command::ResetNode, 3))
                .count();
            r = res;
            if r.is_err() {
                break;
            }
        }
        assert_eq!(r.unwrap_err().reason, FaultReason::NoBootUp);
        assert_eq!(resets, 3, "the reset is sent three times before giving up");
    }

    /// Axis node 3 and spindle node 9 (10 velocity units per rpm).
    fn master_with_spindle() -> CanOpenMaster<FakePort> {
        let mut cfg = CanOpenConfig::new(vec![NodeConfig {
            node_id: 3,
            increments_per_mm: 1000.0,
            following_window_increments: Some(5000),
            ..NodeConfig::new(3, 1000.0)
        }]);
        cfg.spindle = Some(SpindleNodeConfig {
            node_id: 9,
            units_per_rpm: 10.0,
        });
        CanOpenMaster::new(FakePort::default(), "fake", cfg).unwrap()
    }

    /// Plays both drives until they are operational; returns the SDO writes to node 9 and
    /// whether node 9 was asked for its position.
    fn spindle_bring_up(m: &mut CanOpenMaster<FakePort>) -> (Vec<(u16, u8, u32)>, bool) {
        m.enable();
        let _ = step(m);
        rx(m, nmt::heartbeat(3, nmt::state::BOOT_UP));
        rx(m, nmt::heartbeat(9, nmt::state::BOOT_UP));
        let mut writes = Vec::new();
        let mut uploads = false;
        let mut states = [PowerState::SwitchOnDisabled; 2];
        let mut last_cw = [0u16; 2];
        let mut started = [false; 2];
        for _ in 0..200 {
            for (k, id) in [3u8, 9].into_iter().enumerate() {
                if started[k] {
                    rx(
                        m,
                        Tpdo {
                            statusword: states[k].statusword_bits(),
                            position_increments: if id == 3 { 2500 } else { 0 },
                        }
                        .encode(id),
                    );
                    rx(m, nmt::heartbeat(id, nmt::state::OPERATIONAL));
                }
            }
            let (sent, r) = step(m);
            assert!(r.is_ok(), "{r:?}");
            for f in &sent {
                if f.id == 0x609 {
                    match sdo::parse_request(f.payload()) {
                        Ok(sdo::Request::Download {
                            index,
                            subindex,
                            value,
                            ..
                        }) => writes.push((index, subindex, value)),
                        Ok(sdo::Request::Upload { .. }) => uploads = true,
                        Err(_) => {}
                    }
                }
                for (k, id) in [3u8, 9].into_iter().enumerate() {
                    if *f == nmt::command(nmt::Command::Start, id) {
                        started[k] = true;
                    }
                    if f.id == 0x200 + u16::from(id) {
                        let c = Rpdo::decode(f.payload()).unwrap().controlword;
                        states[k] = cia402::apply_controlword(states[k], last_cw[k], c);
                        last_cw[k] = c;
                    }
                }
            }
            answer_sdos(m, &sent);
            if m.nodes.iter().all(|n| n.phase == Phase::Operational) {
                return (writes, uploads);
            }
        }
        panic!(
            "not operational: {:?}",
            m.nodes.iter().map(|n| n.phase).collect::<Vec<_>>()
        );
    }

    #[test]
    fn spindle_node_runs_in_csv_and_carries_the_speed_both_ways() {
        let mut m = master_with_spindle();
        assert_eq!(m.axes(), 1, "the spindle is not an axis");
        assert!(m.has_spindle());
        let (writes, uploads) = spindle_bring_up(&mut m);
        for w in [
            (0x6060, 0, 9),
            (0x1600, 1, 0x6040_0010),
            (0x1600, 2, 0x60FF_0020),
            (0x1A00, 2, 0x606C_0020),
            (0x1400, 1, 0x209),
            (0x1800, 1, 0x189),
            (0x1006, 0, 4000),
        ] {
            assert!(writes.contains(&w), "missing spindle write {w:X?}");
        }
        assert!(!writes.iter().any(|w| w.0 == 0x6065), "no position window");
        assert!(!uploads, "a velocity drive has no position to start from");

        // M3 S1200: 12000 units in the spindle's RPDO; M4 is negative.
        let mut fb = CycleFeedback::default();
        let mut cmd = CycleCommand::default();
        cmd.positions_mm[0] = 2.5;
        for (rpm, units) in [(1200.0, 12_000), (-300.04, -3000), (f64::NAN, 0)] {
            cmd.spindle_rpm = rpm;
            tpdo(&mut m, PowerState::OperationEnabled, 0, 2500);
            rx(
                &mut m,
                Tpdo {
                    statusword: PowerState::OperationEnabled.statusword_bits(),
                    position_increments: 11_990,
                }
                .encode(9),
            );
            rx(&mut m, nmt::heartbeat(9, nmt::state::OPERATIONAL));
            m.cycle(&cmd, &mut fb).unwrap();
            let f = m
                .port
                .tx
                .iter()
                .find(|f| f.id == 0x209)
                .expect("spindle RPDO");
            let r = Rpdo::decode(f.payload()).unwrap();
            assert_eq!(r.controlword, cw::ENABLE_OPERATION_CMD);
            assert_eq!(r.target_increments, units, "{rpm} rpm");
            assert_eq!(rpdo_of(&m.port.tx).target_increments, 2500);
            m.port.tx.clear();
        }
        // 0x606C back: 11990 units = 1199 rpm.
        assert!((fb.spindle_rpm - 1199.0).abs() < 1e-9);
        assert_eq!(fb.spindle_state, DriveState::Operational);
        assert_eq!(fb.axes[0].state, DriveState::Operational);
    }

    #[test]
    fn spindle_faults_name_the_spindle_and_reset_like_an_axis() {
        let mut m = master_with_spindle();
        spindle_bring_up(&mut m);
        overcurrent(&mut m, 9);
        tpdo(&mut m, PowerState::OperationEnabled, 0, 2500);
        let e = step(&mut m).1.unwrap_err();
        assert_eq!(
            e,
            BusFault {
                axis: Some(crate::SPINDLE_AXIS),
                node: Some(9),
                reason: FaultReason::DriveFault { code: 0x2310 }
            }
        );
        assert!(e.to_string().contains("spindle, node 9"), "{e}");
        // The faulted spindle is switched off with speed 0.
        let mut fb = CycleFeedback::default();
        let cmd = CycleCommand {
            spindle_rpm: 1000.0,
            ..CycleCommand::default()
        };
        let _ = m.cycle(&cmd, &mut fb);
        let f = m.port.tx.iter().find(|f| f.id == 0x209).unwrap();
        assert_eq!(
            Rpdo::decode(f.payload()).unwrap(),
            Rpdo {
                controlword: cw::DISABLE_VOLTAGE,
                target_increments: 0
            }
        );
        assert_eq!(fb.spindle_state, DriveState::Fault);
        assert_eq!(fb.spindle_rpm, 0.0);
        // Reset: fault reset over the spindle's RPDO.
        m.port.tx.clear();
        m.reset();
        rx(
            &mut m,
            Tpdo {
                statusword: PowerState::Fault.statusword_bits(),
                position_increments: 0,
            }
            .encode(9),
        );
        let (sent, _) = step(&mut m);
        let f = sent.iter().find(|f| f.id == 0x209).unwrap();
        assert_eq!(
            Rpdo::decode(f.payload()).unwrap().controlword,
            cw::FAULT_RESET
        );

        // A silent spindle times out like an axis.
        let mut m = master_with_spindle();
        spindle_bring_up(&mut m);
        let mut fault = None;
        for _ in 0..40 {
            tpdo(&mut m, PowerState::OperationEnabled, 0, 2500);
            if let Err(e) = step(&mut m).1 {
                fault = Some(e);
                break;
            }
        }
        let e = fault.expect("silent spindle must fault");
        assert_eq!(
            (e.axis, e.node, e.reason),
            (Some(crate::SPINDLE_AXIS), Some(9), FaultReason::Timeout)
        );
    }

    #[test]
    fn spindle_node_ids_are_checked() {
        let cfg = |id: u8, units: f64| {
            let mut c = CanOpenConfig::new(vec![NodeConfig {
                node_id: 3,
                increments_per_mm: 1000.0,
                following_window_increments: None,
                ..NodeConfig::new(3, 1000.0)
            }]);
            c.spindle = Some(SpindleNodeConfig {
                node_id: id,
                units_per_rpm: units,
            });
            CanOpenMaster::new(FakePort::default(), "fake", c).err()
        };
        assert!(cfg(3, 1.0).unwrap().contains("used by an axis"));
        assert!(cfg(127, 1.0).unwrap().contains("equals the master"));
        assert!(cfg(0, 1.0).is_some());
        assert!(cfg(9, 0.0).unwrap().contains("units per rpm"));
        assert!(cfg(9, 1.0).is_none());
        // Without a spindle node the bus says so.
        assert!(!master(&[3]).has_spindle());
    }
}
