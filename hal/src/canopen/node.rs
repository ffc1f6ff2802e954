//! One node of the master, as a state machine driven by its caller (no port): where it is on
//! the bus ([`Phase`]), what the master knows of it ([`Node`]), and its advance by one tick
//! ([`Node::tick`]) through start-up, running and shutdown. The frames a step sends (NMT
//! commands, SDO requests) go into an [`Outbox`] the master empties onto the bus; the cyclic
//! SYNC and RPDO are the master's. Once started, the drive's power stage is run by the CiA 402
//! phase machine every bus shares ([`Drive`]). What the node makes of received frames is in
//! `receive.rs`, its reference run in `homing.rs`. A child of `master`.

use super::*;
use crate::cia402::{DriveSettings, Setpoint};

/// The orderly shutdown of one node, in this order.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Off {
    /// The drive's power stage walked down by its statusword (07h → 06h → 00h, or 02h → 00h).
    PowerDown,
    /// SDO write 0x1016:1 = 0: the drive stops watching the master's heartbeat, so the
    /// master may go silent without the drive faulting.
    ClearConsumer { sent_at: u64, retried: bool },
    /// NMT pre-operational sent: nothing more goes to this node.
    Done,
}

/// Where a node is on the bus. The order of the variants is the order of a start-up; a reset
/// re-enters at `ResetPending` (communication lost, or the node stopped) or restarts the
/// drive's enable sequence while `Running` (a fault of the drive itself).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Phase {
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
    /// NMT operational: the drive's CiA 402 machine has the power stage (enabling, enabled,
    /// in the safe state, or stopped by a fault of the drive).
    Running,
    /// The drive's own reference run (homing mode 6), then back to CSP.
    Homing(Home),
    /// Stopped by a fault of the communication, the configuration or a reference run: a reset
    /// restarts the node.
    Faulted(FaultReason),
    ShuttingDown(Off),
}

impl Phase {
    /// NMT start sent and not yet stopped by a fault or the shutdown: the node runs its PDOs
    /// and its power stage may be on.
    pub(super) fn is_started(self) -> bool {
        matches!(
            self,
            Phase::Starting { .. } | Phase::Running | Phase::Homing(_)
        )
    }
}

/// The bus-wide timeouts in ticks (rounded up, so a late tick never causes a false alarm).
#[derive(Clone, Copy, Debug)]
pub(super) struct Timing {
    pub(super) boot: u64,
    pub(super) sdo: u64,
    pub(super) heartbeat: u64,
    pub(super) tpdo: u64,
    pub(super) homing: u64,
}

impl Timing {
    pub(super) fn new(c: &CanOpenConfig) -> Timing {
        let t = |d| ticks(d, c.cycle);
        Timing {
            boot: t(c.boot_timeout),
            sdo: t(c.sdo_timeout),
            heartbeat: t(c.heartbeat_timeout),
            tpdo: t(c.tpdo_timeout),
            homing: t(c.homing_timeout),
        }
    }
}

/// The frames one step of a node sends, in order. Fixed size, so the tick never allocates: a
/// step sends at most two (the master empties it after every step).
pub(super) struct Outbox {
    frames: [Frame; 4],
    len: usize,
}

impl Outbox {
    pub(super) fn new() -> Outbox {
        Outbox {
            frames: [Frame::new(0, &[]); 4],
            len: 0,
        }
    }

    pub(super) fn push(&mut self, f: Frame) {
        debug_assert!(
            self.len < self.frames.len(),
            "a node step sends at most two frames"
        );
        if let Some(slot) = self.frames.get_mut(self.len) {
            *slot = f;
            self.len += 1;
        }
    }

    /// The frames in order (a copy: the caller may send while stepping on); the outbox is
    /// empty afterwards.
    pub(super) fn take(&mut self) -> impl Iterator<Item = Frame> + use<> {
        let n = std::mem::take(&mut self.len);
        self.frames.into_iter().take(n)
    }
}

pub(super) struct Node {
    /// For the spindle node `increments_per_mm` holds its velocity units per rpm.
    pub(super) cfg: NodeConfig,
    pub(super) steps: Vec<Step>,
    pub(super) phase: Phase,
    /// The power stage: statusword, actual value, controlword and target.
    pub(super) drive: Drive,
    /// A TPDO arrived in this tick (its statusword is fresh).
    pub(super) tpdo_seen: bool,
    pub(super) tpdo_missing: u32,
    pub(super) last_heartbeat: u64,
    /// The NMT state as last known: from the node's heartbeat or TPDO, or what the master
    /// commanded. RPDOs go only to nodes known operational.
    pub(super) nmt_state: u8,
    pub(super) booted: bool,
    /// The drive's reference run, as reported to the controller.
    pub(super) homing: HomingState,
    /// Tick the reference run started (its timeout counts from there).
    pub(super) home_since: u64,
    /// The mode of operation may not be CSP (a reference run did not return): a reset
    /// restarts the node so its configuration writes 0x6060 = 8 again.
    pub(super) mode_changed: bool,
    /// The drive's own digital I/O the map uses (0x60FD in TPDO2, 0x60FE:1 in RPDO2).
    pub(super) io: io_plan::DriveIo,
    /// The newest 0x60FD the drive sent.
    pub(super) digital_inputs: u32,
}

impl Node {
    pub(super) fn new(c: &CanOpenConfig, cfg: NodeConfig, mode: OpMode) -> Node {
        let step = cfg.max_velocity_mm_s * cfg.increments_per_mm * c.cycle.as_secs_f64();
        let setpoint = match mode {
            OpMode::Csp => Setpoint::Position,
            OpMode::Csv => Setpoint::Velocity,
        };
        let settings = DriveSettings {
            // The master's following-error check is a position check.
            following_error_increments: c
                .following_error_limit_mm
                .map(|mm| mm * cfg.increments_per_mm),
            shutdown: c.shutdown,
            ..DriveSettings::new(setpoint, step, ticks(c.enable_timeout, c.cycle))
        };
        Node {
            steps: startup_steps(c, &cfg, mode),
            drive: Drive::new(settings),
            cfg,
            phase: Phase::Idle,
            tpdo_seen: false,
            tpdo_missing: 0,
            last_heartbeat: 0,
            nmt_state: nmt::state::PRE_OPERATIONAL,
            booted: false,
            homing: HomingState::Idle,
            home_since: 0,
            mode_changed: false,
            io: io_plan::DriveIo::default(),
            digital_inputs: 0,
        }
    }

    /// The drive carries digital I/O of the map: its start-up maps 0x60FD / 0x60FE:1 too.
    pub(super) fn set_io(&mut self, io: io_plan::DriveIo) {
        let steps = std::mem::take(&mut self.steps);
        self.steps = startup::with_drive_io(steps, self.id(), io.inputs, io.outputs);
        self.io = io;
    }

    pub(super) fn id(&self) -> u8 {
        self.cfg.node_id.get()
    }

    /// The fault that stops this node: its own, or its running drive's.
    pub(super) fn fault_reason(&self) -> Option<FaultReason> {
        match self.phase {
            Phase::Faulted(r) => Some(r),
            Phase::Running => self.drive.fault_reason(),
            _ => None,
        }
    }

    /// Phases in which the node sends a TPDO every SYNC.
    pub(super) fn expects_pdo(&self) -> bool {
        self.phase.is_started()
    }

    /// Whether the node gets an RPDO this tick: it is known to be in NMT operational and the
    /// master talks to it (a drive-level fault keeps the power stage off over the RPDO).
    pub(super) fn gets_rpdo(&self) -> bool {
        self.nmt_state == nmt::state::OPERATIONAL
            && match self.phase {
                Phase::Starting { .. } | Phase::Running | Phase::Homing(_) => true,
                // A silent drive may still listen: controlword 0 switches it off.
                Phase::Faulted(r) => is_drive_level(r) || r == FaultReason::Timeout,
                Phase::ShuttingDown(off) => off != Off::Done,
                _ => false,
            }
    }

    pub(super) fn is_off(&self) -> bool {
        matches!(self.phase, Phase::Idle | Phase::ShuttingDown(Off::Done))
    }

    /// Stops the node for `reason`. A fault of the drive itself while it runs stays with its
    /// CiA 402 machine (a fault reset over the RPDO may clear it); any other stops the node
    /// (a reset restarts it). The first fault stays: later ones follow from it.
    pub(super) fn fault(&mut self, reason: FaultReason) {
        if self.fault_reason().is_some()
            || matches!(self.phase, Phase::Idle | Phase::ShuttingDown(_))
        {
            return;
        }
        let drive_runs = matches!(self.phase, Phase::Starting { .. } | Phase::Running);
        self.phase = if is_drive_level(reason) && drive_runs {
            Phase::Running
        } else {
            Phase::Faulted(reason)
        };
        self.drive.fault(reason);
        if self.homing == HomingState::Running {
            self.homing = HomingState::Aborted;
        }
    }

    /// One tick at `now`: the watchdogs, then the step of the node's phase. `target` is this
    /// tick's setpoint in drive units.
    pub(super) fn tick(&mut self, now: u64, target: i32, t: &Timing, out: &mut Outbox) {
        self.watch(now, t);
        match self.phase {
            Phase::Idle | Phase::Configured | Phase::ShuttingDown(Off::Done) => {}
            Phase::ResetPending { command } => self.send_reset(now, command, out),
            Phase::Booting { since, command } => self.boot(now, since, command, t, out),
            Phase::Configuring {
                step,
                sent_at,
                retried,
            } => self.configure(now, step, sent_at, retried, t, out),
            Phase::Starting { since } => self.start(now, since, target, t),
            // A node stopped by a fault keeps its power stage off (over the RPDO, where it
            // still listens), its target where the drive is.
            Phase::Running | Phase::Faulted(_) => self.drive.tick(now, self.tpdo_seen, target),
            Phase::Homing(h) => self.update_homing(now, h, t, out),
            Phase::ShuttingDown(Off::PowerDown) => self.power_down(now, out),
            Phase::ShuttingDown(Off::ClearConsumer { sent_at, retried }) => {
                if now - sent_at > t.sdo {
                    self.clear_consumer(now, retried, out);
                }
            }
        }
        self.tpdo_seen = false;
    }

    /// Watchdogs of a running node: a TPDO every SYNC, the heartbeat.
    fn watch(&mut self, now: u64, t: &Timing) {
        if !matches!(self.phase, Phase::Running | Phase::Homing(_)) {
            return;
        }
        if self.tpdo_seen {
            self.tpdo_missing = 0;
        } else {
            self.tpdo_missing += 1;
        }
        if u64::from(self.tpdo_missing) > t.tpdo {
            self.fault(FaultReason::Timeout);
        } else if now - self.last_heartbeat > t.heartbeat {
            self.fault(FaultReason::HeartbeatLost);
        }
    }

    /// The NMT reset goes out; the node boots afresh, its power stage off.
    fn send_reset(&mut self, now: u64, command: nmt::Command, out: &mut Outbox) {
        self.booted = false;
        self.nmt_state = nmt::state::PRE_OPERATIONAL;
        self.drive.switch_off();
        self.phase = Phase::Booting {
            since: now,
            command,
        };
        out.push(nmt::command(command, self.id()));
    }

    fn boot(&mut self, now: u64, since: u64, command: nmt::Command, t: &Timing, out: &mut Outbox) {
        if self.booted {
            self.send_step(now, 0, false, out);
        } else if now - since > t.boot {
            self.fault(FaultReason::NoBootUp);
        } else if (now - since).is_multiple_of(t.boot / 3 + 1) {
            // The reset may have been lost (a drive busy or not yet listening): ask again,
            // twice, before giving up.
            out.push(nmt::command(command, self.id()));
        }
    }

    fn configure(
        &mut self,
        now: u64,
        step: usize,
        sent_at: u64,
        retried: bool,
        t: &Timing,
        out: &mut Outbox,
    ) {
        if now - sent_at <= t.sdo {
            return;
        }
        if retried {
            let (index, subindex) = step_object(self.steps[step]);
            self.fault(FaultReason::SdoTimeout { index, subindex });
        } else {
            self.send_step(now, step, true, out);
        }
    }

    /// Sends start-up step `step` (configuring from now).
    pub(super) fn send_step(&mut self, now: u64, step: usize, retried: bool, out: &mut Outbox) {
        self.phase = Phase::Configuring {
            step,
            sent_at: now,
            retried,
        };
        out.push(self.sdo_request(self.steps[step]));
    }

    /// The SDO request of one step.
    pub(super) fn sdo_request(&self, s: Step) -> Frame {
        let id = self.id();
        match s {
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
        }
    }

    /// NMT start of a configured node: from now on it gets SYNC and its RPDO.
    pub(super) fn nmt_start(&mut self, now: u64, out: &mut Outbox) {
        self.phase = Phase::Starting { since: now };
        self.tpdo_seen = false;
        self.last_heartbeat = now;
        self.nmt_state = nmt::state::OPERATIONAL;
        self.drive.switch_off();
        out.push(nmt::command(nmt::Command::Start, self.id()));
    }

    /// Waiting for the first TPDO after NMT start; with it the enable sequence begins.
    fn start(&mut self, now: u64, since: u64, target: i32, t: &Timing) {
        if self.tpdo_seen {
            self.tpdo_missing = 0;
            self.phase = Phase::Running;
            self.drive.begin_enable(now);
        } else if now - since > t.boot {
            return self.fault(FaultReason::Timeout);
        }
        self.drive.tick(now, self.tpdo_seen, target);
    }

    /// A reset: a fault of the drive itself, or the safe state, is cleared over the RPDO while
    /// the node still talks (CiA 402 fault reset, enable again); anything else restarts the
    /// node. `whole_bus`: the bus itself had failed, every node restarts.
    pub(super) fn reset(&mut self, now: u64, whole_bus: bool, t: &Timing) {
        // Still in NMT operational by its own latest word: a fault reset over the RPDO is
        // enough. Otherwise (it left operational, or went quiet) the whole start-up.
        let talking =
            self.nmt_state == nmt::state::OPERATIONAL && now - self.last_heartbeat <= t.heartbeat;
        let restart = Phase::ResetPending {
            command: nmt::Command::ResetCommunication,
        };
        self.phase = match self.phase {
            Phase::Idle => Phase::ResetPending {
                command: nmt::Command::ResetNode,
            },
            Phase::Faulted(_) => restart,
            // A reference run that did not return to CSP: restart, so the configuration
            // sets the mode again.
            Phase::Running if whole_bus || self.mode_changed => restart,
            Phase::Running => match self.drive.phase() {
                DrivePhase::Faulted(_) if !talking => restart,
                DrivePhase::Faulted(_) | DrivePhase::Stopped => {
                    self.tpdo_missing = 0;
                    self.drive.begin_enable(now);
                    Phase::Running
                }
                _ => Phase::Running,
            },
            _ if whole_bus => restart,
            other => other,
        };
        if self.phase == restart {
            self.drive.switch_off();
        }
    }

    /// The start of the node's orderly shutdown, by where it is.
    pub(super) fn shut_down(&mut self, now: u64, out: &mut Outbox) {
        match self.phase {
            Phase::Idle
            | Phase::ResetPending { .. }
            | Phase::Booting { .. }
            | Phase::Faulted(FaultReason::NoBootUp) => {
                self.phase = Phase::ShuttingDown(Off::Done);
            }
            Phase::Starting { .. } | Phase::Running | Phase::Homing(_) => {
                self.phase = Phase::ShuttingDown(Off::PowerDown);
                self.drive.begin_power_down(now);
            }
            Phase::Faulted(r) if is_drive_level(r) => {
                self.phase = Phase::ShuttingDown(Off::PowerDown);
                self.drive.begin_power_down(now);
            }
            // Configured but not started, or communication lost: no power stage to walk
            // down, but the heartbeat watch may be set.
            Phase::Configuring { .. } | Phase::Configured | Phase::Faulted(_) => {
                self.send_clear_consumer(now, false, out);
            }
            Phase::ShuttingDown(_) => {}
        }
    }

    /// Shutdown: the drive's power stage walks down on fresh statuswords (at once if the
    /// node left NMT operational: it no longer takes the RPDO); then the heartbeat watch is
    /// cleared.
    fn power_down(&mut self, now: u64, out: &mut Outbox) {
        if self.nmt_state == nmt::state::OPERATIONAL {
            let target = self.drive.target_increments();
            self.drive.tick(now, self.tpdo_seen, target);
        } else {
            self.drive.switch_off();
        }
        if self.drive.phase() == DrivePhase::Off {
            self.send_clear_consumer(now, false, out);
        }
    }

    fn send_clear_consumer(&mut self, now: u64, retried: bool, out: &mut Outbox) {
        self.phase = Phase::ShuttingDown(Off::ClearConsumer {
            sent_at: now,
            retried,
        });
        out.push(sdo::download(self.id(), 0x1016, 1, 0, 4));
    }

    /// The clearing of the heartbeat watch was not answered in time: once more, then leave.
    fn clear_consumer(&mut self, now: u64, retried: bool, out: &mut Outbox) {
        if retried {
            self.leave_bus(out);
        } else {
            self.send_clear_consumer(now, true, out);
        }
    }

    /// Last step of a node's shutdown: NMT pre-operational (PDOs stop, SDO stays possible).
    pub(super) fn leave_bus(&mut self, out: &mut Outbox) {
        self.phase = Phase::ShuttingDown(Off::Done);
        self.nmt_state = nmt::state::PRE_OPERATIONAL;
        out.push(nmt::command(nmt::Command::EnterPreOperational, self.id()));
    }
}
