//! One node of the master: where it is on the bus ([`Phase`]), what the master knows of it
//! ([`Node`]), and its advance by one tick through start-up, running, and shutdown. Once
//! started, its drive's power stage is run by the CiA 402 phase machine every bus shares
//! ([`Drive`]). A child of `master`.

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
        }
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
}

impl<P: CanPort> CanOpenMaster<P> {
    /// Watchdogs of a started node: a TPDO every SYNC, the heartbeat.
    pub(super) fn watch(&mut self, i: usize) {
        let hb_ticks = self.ticks(self.cfg.heartbeat_timeout);
        let missing_limit = self.ticks(self.cfg.tpdo_timeout);
        let tick = self.tick;
        let n = &mut self.nodes[i];
        if !matches!(n.phase, Phase::Running | Phase::Homing(_)) {
            return;
        }
        if n.tpdo_seen {
            n.tpdo_missing = 0;
        } else {
            n.tpdo_missing += 1;
        }
        if u64::from(n.tpdo_missing) > missing_limit {
            self.fault(i, FaultReason::Timeout);
        } else if tick - n.last_heartbeat > hb_ticks {
            self.fault(i, FaultReason::HeartbeatLost);
        }
    }

    /// Advances node `i` by one tick; `target` is this tick's setpoint in drive units.
    pub(super) fn update_node(&mut self, i: usize, target: i32) {
        self.watch(i);
        let tick = self.tick;
        match self.nodes[i].phase {
            Phase::Idle | Phase::Configured | Phase::ShuttingDown(Off::Done) => {}
            Phase::ResetPending { command } => self.send_reset(i, command),
            Phase::Booting { since, command } => self.boot(i, since, command),
            Phase::Configuring {
                step,
                sent_at,
                retried,
            } => self.configure(i, step, sent_at, retried),
            Phase::Starting { since } => self.start(i, since, target),
            // A node stopped by a fault keeps its power stage off (over the RPDO, where it
            // still listens), its target where the drive is.
            Phase::Running | Phase::Faulted(_) => {
                let n = &mut self.nodes[i];
                n.drive.tick(tick, n.tpdo_seen, target);
            }
            Phase::Homing(h) => self.update_homing(i, h),
            Phase::ShuttingDown(Off::PowerDown) => self.power_down(i),
            Phase::ShuttingDown(Off::ClearConsumer { sent_at, retried }) => {
                self.clear_consumer(i, sent_at, retried)
            }
        }
        self.nodes[i].tpdo_seen = false;
    }

    /// The NMT reset of node `i` goes out; it boots afresh, its power stage off.
    fn send_reset(&mut self, i: usize, command: nmt::Command) {
        let tick = self.tick;
        let n = &mut self.nodes[i];
        n.booted = false;
        n.nmt_state = nmt::state::PRE_OPERATIONAL;
        n.drive.switch_off();
        n.phase = Phase::Booting {
            since: tick,
            command,
        };
        let id = n.cfg.node_id.get();
        self.send(&nmt::command(command, id));
    }

    pub(super) fn boot(&mut self, i: usize, since: u64, command: nmt::Command) {
        let boot_ticks = self.ticks(self.cfg.boot_timeout);
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
            let id = n.cfg.node_id.get();
            self.send(&nmt::command(command, id));
        }
    }

    pub(super) fn configure(&mut self, i: usize, step: usize, sent_at: u64, retried: bool) {
        if self.tick - sent_at <= self.ticks(self.cfg.sdo_timeout) {
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

    /// Waiting for the first TPDO after NMT start; with it the enable sequence begins.
    pub(super) fn start(&mut self, i: usize, since: u64, target: i32) {
        let boot_ticks = self.ticks(self.cfg.boot_timeout);
        let tick = self.tick;
        let n = &mut self.nodes[i];
        if n.tpdo_seen {
            n.tpdo_missing = 0;
            n.phase = Phase::Running;
            n.drive.begin_enable(tick);
        } else if tick - since > boot_ticks {
            return self.fault(i, FaultReason::Timeout);
        }
        let n = &mut self.nodes[i];
        n.drive.tick(tick, n.tpdo_seen, target);
    }

    /// A reset of node `i`: a fault of the drive itself, or the safe state, is cleared over
    /// the RPDO while the node still talks (CiA 402 fault reset, enable again); anything else
    /// restarts the node. `whole_bus`: the bus itself had failed, every node restarts.
    pub(super) fn reset_node(&mut self, i: usize, whole_bus: bool) {
        let tick = self.tick;
        let hb_ticks = self.ticks(self.cfg.heartbeat_timeout);
        let n = &mut self.nodes[i];
        // Still in NMT operational by its own latest word: a fault reset over the RPDO is
        // enough. Otherwise (it left operational, or went quiet) the whole start-up.
        let talking = n.nmt_state == nmt::state::OPERATIONAL && tick - n.last_heartbeat <= hb_ticks;
        let restart = Phase::ResetPending {
            command: nmt::Command::ResetCommunication,
        };
        let drive = n.drive.phase();
        n.phase = match n.phase {
            Phase::Idle => Phase::ResetPending {
                command: nmt::Command::ResetNode,
            },
            Phase::Faulted(_) => restart,
            // A reference run that did not return to CSP: restart, so the configuration
            // sets the mode again.
            Phase::Running if whole_bus || n.mode_changed => restart,
            Phase::Running => match drive {
                DrivePhase::Faulted(_) if !talking => restart,
                DrivePhase::Faulted(_) | DrivePhase::Stopped => {
                    n.tpdo_missing = 0;
                    n.drive.begin_enable(tick);
                    Phase::Running
                }
                _ => Phase::Running,
            },
            _ if whole_bus => restart,
            other => other,
        };
        if n.phase == restart {
            n.drive.switch_off();
        }
    }

    /// The start of node `i`'s orderly shutdown, by where it is.
    pub(super) fn shut_down_node(&mut self, i: usize) {
        let tick = self.tick;
        let n = &mut self.nodes[i];
        match n.phase {
            Phase::Idle
            | Phase::ResetPending { .. }
            | Phase::Booting { .. }
            | Phase::Faulted(FaultReason::NoBootUp) => {
                n.phase = Phase::ShuttingDown(Off::Done);
            }
            Phase::Starting { .. } | Phase::Running | Phase::Homing(_) => {
                n.phase = Phase::ShuttingDown(Off::PowerDown);
                n.drive.begin_power_down(tick);
            }
            Phase::Faulted(r) if is_drive_level(r) => {
                n.phase = Phase::ShuttingDown(Off::PowerDown);
                n.drive.begin_power_down(tick);
            }
            // Configured but not started, or communication lost: no power stage to walk
            // down, but the heartbeat watch may be set.
            Phase::Configuring { .. } | Phase::Configured | Phase::Faulted(_) => {
                self.send_clear_consumer(i, false);
            }
            Phase::ShuttingDown(_) => {}
        }
    }

    /// Shutdown: the drive's power stage walks down on fresh statuswords (at once if the
    /// node left NMT operational: it no longer takes the RPDO); then the heartbeat watch is
    /// cleared.
    pub(super) fn power_down(&mut self, i: usize) {
        let tick = self.tick;
        let n = &mut self.nodes[i];
        if n.nmt_state == nmt::state::OPERATIONAL {
            let target = n.drive.target_increments();
            n.drive.tick(tick, n.tpdo_seen, target);
        } else {
            n.drive.switch_off();
        }
        if n.drive.phase() == DrivePhase::Off {
            self.send_clear_consumer(i, false);
        }
    }

    pub(super) fn send_clear_consumer(&mut self, i: usize, retried: bool) {
        self.nodes[i].phase = Phase::ShuttingDown(Off::ClearConsumer {
            sent_at: self.tick,
            retried,
        });
        let id = self.nodes[i].cfg.node_id.get();
        self.send(&sdo::download(id, 0x1016, 1, 0, 4));
    }

    pub(super) fn clear_consumer(&mut self, i: usize, sent_at: u64, retried: bool) {
        if self.tick - sent_at <= self.ticks(self.cfg.sdo_timeout) {
            return;
        }
        if retried {
            self.leave_bus(i);
        } else {
            self.send_clear_consumer(i, true);
        }
    }

    /// Last step of a node's shutdown: NMT pre-operational (PDOs stop, SDO stays possible).
    pub(super) fn leave_bus(&mut self, i: usize) {
        let n = &mut self.nodes[i];
        n.phase = Phase::ShuttingDown(Off::Done);
        n.nmt_state = nmt::state::PRE_OPERATIONAL;
        let id = n.cfg.node_id.get();
        self.send(&nmt::command(nmt::Command::EnterPreOperational, id));
    }
}
