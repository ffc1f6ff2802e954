//! One node of the master: where it is ([`Phase`]), what the master knows of it
//! ([`Node`]), and its advance by one tick through start-up, enable, operation and
//! shutdown. A child of `master`.

use super::*;
use crate::cia402::EnableStep;

/// The orderly shutdown of one node, in this order.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Off {
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

impl Phase {
    /// NMT start sent and not yet stopped by a fault or the shutdown: the node runs its PDOs
    /// and its power stage may be on.
    pub(super) fn is_started(self) -> bool {
        matches!(
            self,
            Phase::Starting { .. }
                | Phase::Enabling { .. }
                | Phase::Operational
                | Phase::Homing(_)
                | Phase::Stopped
        )
    }
}

pub(super) struct Node {
    /// For the spindle node `increments_per_mm` holds its velocity units per rpm.
    pub(super) cfg: NodeConfig,
    pub(super) mode: OpMode,
    pub(super) steps: Vec<Step>,
    pub(super) phase: Phase,
    pub(super) statusword: u16,
    /// The TPDO's value: actual position (CSP) or actual velocity (CSV), drive units.
    pub(super) position_increments: i32,
    /// A TPDO arrived in this tick (its statusword is fresh).
    pub(super) tpdo_seen: bool,
    pub(super) tpdo_missing: u32,
    pub(super) last_heartbeat: u64,
    /// The NMT state as last known: from the node's heartbeat or TPDO, or what the master
    /// commanded. RPDOs go only to nodes known operational.
    pub(super) nmt_state: u8,
    pub(super) booted: bool,
    pub(super) controlword: u16,
    pub(super) target_increments: i32,
    pub(super) emcy_code: Option<u16>,
    /// The commanded positions have been taken over: until then an enabled drive holds its
    /// own position, so the target never jumps (CSV nodes take the setpoint at once).
    pub(super) taken_over: bool,
    /// One tick's travel at the axis's highest speed, increments (at least 1).
    pub(super) max_step_increments: i64,
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
    pub(super) fn hold_target(&self) -> i32 {
        match self.mode {
            OpMode::Csp => self.position_increments,
            OpMode::Csv => 0,
        }
    }

    /// Phases in which the node sends a TPDO every SYNC.
    pub(super) fn expects_pdo(&self) -> bool {
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
    pub(super) fn gets_rpdo(&self) -> bool {
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
        if u64::from(n.tpdo_missing) > missing_limit {
            self.fault(i, FaultReason::Timeout);
        } else if tick - n.last_heartbeat > hb_ticks {
            self.fault(i, FaultReason::HeartbeatLost);
        }
    }

    /// Advances node `i` by one tick; `target` is this tick's setpoint in drive units.
    pub(super) fn update_node(&mut self, i: usize, target: i32) {
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
                let id = n.cfg.node_id.get();
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

    pub(super) fn start(&mut self, i: usize, since: u64) {
        let boot_ticks = self.ticks(self.cfg.boot_timeout);
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
    pub(super) fn enable_step(&mut self, i: usize, since: u64) {
        let enable_ticks = self.ticks(self.cfg.enable_timeout);
        let tick = self.tick;
        let n = &mut self.nodes[i];
        // The target follows the actual position (a spindle: stands) until enabled.
        n.target_increments = n.hold_target();
        if tick - since > enable_ticks {
            let statusword = n.statusword;
            self.fault(i, FaultReason::EnableTimeout { statusword });
        } else if !n.tpdo_seen {
            // Keep the last controlword until the drive reports again.
        } else {
            match cia402::enable_step(n.statusword, n.controlword) {
                EnableStep::Enabled => {
                    n.phase = Phase::Operational;
                    n.controlword = cw::ENABLE_OPERATION_CMD;
                    n.taken_over = n.mode == OpMode::Csv;
                }
                EnableStep::Toward(c) => n.controlword = c,
            }
        }
    }

    pub(super) fn operate(&mut self, i: usize, target: i32) {
        // The master's following-error check is a position check: not for a velocity node.
        let fe_limit = self
            .cfg
            .following_error_limit_mm
            .filter(|_| self.nodes[i].mode == OpMode::Csp)
            .map(|mm| mm * self.nodes[i].cfg.increments_per_mm);
        let n = &mut self.nodes[i];
        let lag = f64::from(n.target_increments) - f64::from(n.position_increments);
        if let Some(reason) = cia402::operating_fault(n.statusword, n.emcy_code.unwrap_or(0)) {
            self.fault(i, reason);
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
    pub(super) fn power_down(&mut self, i: usize, since: u64) {
        let enable_ticks = self.ticks(self.cfg.enable_timeout);
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
