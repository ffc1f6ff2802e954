//! One CiA 401 I/O module of the master, a state machine driven by it without a port, like a
//! drive node but without a power stage: NMT reset → boot-up → SDO configuration (PDO mapping
//! of its 8-bit groups, error mode and values of its outputs, heartbeats) → NMT start with
//! the drives → running (its TPDO and heartbeat watched with the drives' timeouts) →
//! shutdown (heartbeat watch cleared, NMT pre-operational). Its faults name its node and no
//! axis. A child of `master`.

use super::*;

pub(super) struct IoModule {
    pub(super) id: u8,
    pub(super) steps: Vec<Step>,
    pub(super) phase: Phase,
    /// 0x6000 groups in its TPDO1 (0: it sends none).
    input_groups: u8,
    /// 0x6200 groups in its RPDO1 (0: it gets none).
    output_groups: u8,
    /// The newest inputs received, module bit b (group b / 8 + 1, bit b % 8).
    pub(super) inputs: u64,
    tpdo_seen: bool,
    tpdo_missing: u32,
    last_heartbeat: u64,
    /// The NMT state as last known (heartbeat, TPDO, or what the master commanded).
    nmt_state: u8,
    booted: bool,
}

impl IoModule {
    pub(super) fn new(c: &CanOpenConfig, plan: cia401::ModulePlan) -> IoModule {
        IoModule {
            id: plan.node,
            steps: startup::module_steps(c, &plan),
            phase: Phase::Idle,
            input_groups: plan.input_groups,
            output_groups: plan.output_groups,
            inputs: 0,
            tpdo_seen: false,
            tpdo_missing: 0,
            last_heartbeat: 0,
            nmt_state: nmt::state::PRE_OPERATIONAL,
            booted: false,
        }
    }

    pub(super) fn fault_reason(&self) -> Option<FaultReason> {
        match self.phase {
            Phase::Faulted(r) => Some(r),
            _ => None,
        }
    }

    /// Stops the module for `reason`; the first fault stays (later ones follow from it).
    fn fault(&mut self, reason: FaultReason) {
        if self.fault_reason().is_none()
            && !matches!(self.phase, Phase::Idle | Phase::ShuttingDown(_))
        {
            self.phase = Phase::Faulted(reason);
        }
    }

    pub(super) fn is_off(&self) -> bool {
        matches!(self.phase, Phase::Idle | Phase::ShuttingDown(Off::Done))
    }

    /// Its TPDO answers SYNC: the master sends SYNC while it is started.
    pub(super) fn needs_sync(&self) -> bool {
        self.input_groups > 0 && self.phase.is_started()
    }

    /// Whether it gets its outputs this tick: known in NMT operational, and the master talks
    /// to it (after a fault too: the caller's outputs, safe ones by then, still reach it).
    pub(super) fn gets_rpdo(&self) -> bool {
        self.output_groups > 0
            && self.nmt_state == nmt::state::OPERATIONAL
            && matches!(
                self.phase,
                Phase::Starting { .. }
                    | Phase::Running
                    | Phase::Faulted(_)
                    | Phase::ShuttingDown(Off::ClearConsumer { .. })
            )
    }

    /// Its RPDO1 with module bits `bits`.
    pub(super) fn rpdo(&self, bits: u64) -> Frame {
        cia401::encode_groups(cob::RPDO1 + u16::from(self.id), bits, self.output_groups)
    }

    /// One tick at `now`: the watchdogs, then the step of its phase.
    pub(super) fn tick(&mut self, now: u64, t: &Timing, out: &mut Outbox) {
        self.watch(now, t);
        match self.phase {
            Phase::ResetPending { command } => {
                self.booted = false;
                self.nmt_state = nmt::state::PRE_OPERATIONAL;
                self.phase = Phase::Booting {
                    since: now,
                    command,
                };
                out.push(nmt::command(command, self.id));
            }
            Phase::Booting { since, command } => self.boot(now, since, command, t, out),
            Phase::Configuring {
                step,
                sent_at,
                retried,
            } if now - sent_at > t.sdo => {
                if retried {
                    let (index, subindex) = step_object(self.steps[step]);
                    self.fault(FaultReason::SdoTimeout { index, subindex });
                } else {
                    self.send_step(now, step, true, out);
                }
            }
            Phase::Starting { since } => self.start(now, since, t),
            Phase::ShuttingDown(Off::ClearConsumer { sent_at, retried })
                if now - sent_at > t.sdo =>
            {
                if retried {
                    self.leave_bus(out);
                } else {
                    self.send_clear_consumer(now, true, out);
                }
            }
            _ => {}
        }
        self.tpdo_seen = false;
    }

    /// Watchdogs of a running module: its TPDO every SYNC (if it has inputs), its heartbeat.
    fn watch(&mut self, now: u64, t: &Timing) {
        if self.phase != Phase::Running {
            return;
        }
        if self.tpdo_seen || self.input_groups == 0 {
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

    fn boot(&mut self, now: u64, since: u64, command: nmt::Command, t: &Timing, out: &mut Outbox) {
        if self.booted {
            self.send_step(now, 0, false, out);
        } else if now - since > t.boot {
            self.fault(FaultReason::NoBootUp);
        } else if (now - since).is_multiple_of(t.boot / 3 + 1) {
            // The reset may have been lost: ask again, twice, before giving up.
            out.push(nmt::command(command, self.id));
        }
    }

    fn send_step(&mut self, now: u64, step: usize, retried: bool, out: &mut Outbox) {
        self.phase = Phase::Configuring {
            step,
            sent_at: now,
            retried,
        };
        if let Step::Write {
            index,
            subindex,
            value,
            size,
        } = self.steps[step]
        {
            out.push(sdo::download(self.id, index, subindex, value, size));
        }
    }

    /// NMT start (with the drives): outputs go out from now on.
    pub(super) fn nmt_start(&mut self, now: u64, out: &mut Outbox) {
        self.phase = Phase::Starting { since: now };
        self.tpdo_seen = false;
        self.last_heartbeat = now;
        self.nmt_state = nmt::state::OPERATIONAL;
        out.push(nmt::command(nmt::Command::Start, self.id));
    }

    /// Waiting for the first TPDO after NMT start (none to wait for without inputs).
    fn start(&mut self, now: u64, since: u64, t: &Timing) {
        if self.tpdo_seen || self.input_groups == 0 {
            self.tpdo_missing = 0;
            self.phase = Phase::Running;
        } else if now - since > t.boot {
            self.fault(FaultReason::Timeout);
        }
    }

    /// A reset: a faulted module restarts (reset communication, configuration, start); a
    /// running one stays, unless the bus itself had failed.
    pub(super) fn reset(&mut self, whole_bus: bool) {
        let restart = Phase::ResetPending {
            command: nmt::Command::ResetCommunication,
        };
        self.phase = match self.phase {
            Phase::Idle => Phase::ResetPending {
                command: nmt::Command::ResetNode,
            },
            Phase::Faulted(_) => restart,
            Phase::ShuttingDown(_) => self.phase,
            _ if whole_bus => restart,
            other => other,
        };
    }

    /// The start of its orderly shutdown, once the drives are off: the heartbeat watch is
    /// cleared (the last outputs, the safe ones, stay), then NMT pre-operational.
    pub(super) fn shut_down(&mut self, now: u64, out: &mut Outbox) {
        match self.phase {
            Phase::Idle
            | Phase::ResetPending { .. }
            | Phase::Booting { .. }
            | Phase::Faulted(FaultReason::NoBootUp) => {
                self.phase = Phase::ShuttingDown(Off::Done);
            }
            Phase::ShuttingDown(_) => {}
            _ => self.send_clear_consumer(now, false, out),
        }
    }

    fn send_clear_consumer(&mut self, now: u64, retried: bool, out: &mut Outbox) {
        self.phase = Phase::ShuttingDown(Off::ClearConsumer {
            sent_at: now,
            retried,
        });
        out.push(sdo::download(self.id, 0x1016, 1, 0, 4));
    }

    fn leave_bus(&mut self, out: &mut Outbox) {
        self.phase = Phase::ShuttingDown(Off::Done);
        self.nmt_state = nmt::state::PRE_OPERATIONAL;
        out.push(nmt::command(nmt::Command::EnterPreOperational, self.id));
    }

    pub(super) fn on_tpdo(&mut self, f: &Frame) {
        if self.input_groups == 0 {
            return;
        }
        if f.len == self.input_groups {
            self.inputs = cia401::decode_groups(f.payload());
            self.tpdo_seen = true;
            self.nmt_state = nmt::state::OPERATIONAL;
        } else if self.phase.is_started() {
            self.fault(FaultReason::PdoLength {
                cob_id: f.id,
                len: f.len,
                expected: self.input_groups,
            });
        }
    }

    pub(super) fn on_emcy(&mut self, payload: &[u8]) {
        if let Some(e) = emcy::Emcy::decode(payload)
            && e.code != 0
        {
            self.fault(FaultReason::DriveFault { code: e.code });
        }
    }

    pub(super) fn on_heartbeat(&mut self, now: u64, state: u8) {
        self.last_heartbeat = now;
        if state == nmt::state::BOOT_UP {
            self.booted = true;
            self.nmt_state = nmt::state::PRE_OPERATIONAL;
            if self.phase.is_started() {
                self.fault(FaultReason::NmtStateChanged { state });
            }
            return;
        }
        // A heartbeat sent before our NMT start may still arrive while starting.
        if !matches!(self.phase, Phase::Starting { .. }) {
            self.nmt_state = state;
        }
        if state != nmt::state::OPERATIONAL && self.phase == Phase::Running {
            self.fault(FaultReason::NmtStateChanged { state });
        }
    }

    pub(super) fn on_sdo_response(&mut self, now: u64, r: Response, out: &mut Outbox) {
        match self.phase {
            Phase::Configuring { step, .. } if r.object() == step_object(self.steps[step]) => {
                if let Response::Abort { code, .. } = r {
                    let (index, subindex) = r.object();
                    self.fault(FaultReason::SdoAbort {
                        index,
                        subindex,
                        abort_code: code,
                    });
                } else if step + 1 < self.steps.len() {
                    self.send_step(now, step + 1, false, out);
                } else {
                    self.phase = Phase::Configured;
                }
            }
            Phase::ShuttingDown(Off::ClearConsumer { .. }) if r.object() == (0x1016, 1) => {
                self.leave_bus(out)
            }
            _ => {}
        }
    }
}
