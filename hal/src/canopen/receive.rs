//! What a node makes of the frames it sends the master: its TPDO (statusword, actual value),
//! its TPDO2 (digital inputs 0x60FD, when mapped),
//! EMCY, heartbeat and SDO answers. The master only dispatches by COB-ID. A child of `master`.

use super::*;

/// A drive's answer to a request of the master's SDO plan.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum SdoAnswer {
    Uploaded(u32),
    Downloaded,
}

impl Node {
    pub(super) fn on_tpdo(&mut self, f: &Frame) {
        match Tpdo::decode(f.payload()) {
            Some(t) => {
                self.drive.on_status(t.statusword, t.position_increments);
                self.tpdo_seen = true;
                // Only a node in NMT operational sends PDOs.
                self.nmt_state = nmt::state::OPERATIONAL;
            }
            // CAN frames are checked by CRC: a wrong length is a mapping mismatch, not noise.
            None if self.expects_pdo() => self.fault(FaultReason::PdoLength {
                cob_id: f.id,
                len: f.len,
                expected: pdo::LEN as u8,
            }),
            None => {}
        }
    }

    /// TPDO2 of a drive carrying inputs: 0x60FD, answering the same SYNC as its TPDO1.
    pub(super) fn on_tpdo2(&mut self, f: &Frame) {
        if !self.io.inputs {
            return;
        }
        match cia401::decode_u32(f.payload()) {
            Some(bits) => self.digital_inputs = bits,
            None if self.expects_pdo() => self.fault(FaultReason::PdoLength {
                cob_id: f.id,
                len: f.len,
                expected: 4,
            }),
            None => {}
        }
    }

    pub(super) fn on_emcy(&mut self, payload: &[u8]) {
        let Some(e) = Emcy::decode(payload) else {
            return;
        };
        if e.code == 0 || self.phase == Phase::Idle {
            return;
        }
        self.drive.set_error_code(e.code);
        self.fault(if e.code == emcy::FOLLOWING_ERROR {
            FaultReason::FollowingError
        } else {
            FaultReason::DriveFault { code: e.code }
        });
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
        if state != nmt::state::OPERATIONAL
            && matches!(self.phase, Phase::Running | Phase::Homing(_))
        {
            self.fault(FaultReason::NmtStateChanged { state });
        }
    }

    pub(super) fn on_sdo_response(&mut self, now: u64, r: Response, out: &mut Outbox) {
        match self.phase {
            Phase::Configuring { step, .. } => self.on_startup_sdo(now, step, r, out),
            // Done either way: a drive that refuses is switched off and told to stop all the
            // same.
            Phase::ShuttingDown(Off::ClearConsumer { .. }) if r.object() == (0x1016, 1) => {
                self.leave_bus(out)
            }
            Phase::Homing(Home::Sdo { leaving, step, .. }) => {
                self.on_homing_sdo(now, leaving, step, r, out)
            }
            _ => {}
        }
    }

    /// The answer to start-up step `step`: the next step, or configured after the last.
    fn on_startup_sdo(&mut self, now: u64, step: usize, r: Response, out: &mut Outbox) {
        let expected = self.steps[step];
        match self.sdo_answer(expected, r) {
            Some(SdoAnswer::Uploaded(value)) if expected == Step::ReadPosition => {
                self.drive.set_actual_increments(value as i32);
                self.next_step(now, step, out);
            }
            Some(_) => self.next_step(now, step, out),
            None => {}
        }
    }

    /// What answer `r` to the request of step `expected` says: `None` for a late answer to an
    /// earlier, retried request (ignored) or an abort (the node faults, naming the object).
    pub(super) fn sdo_answer(&mut self, expected: Step, r: Response) -> Option<SdoAnswer> {
        if r.object() != step_object(expected) {
            return None;
        }
        match r {
            Response::Abort { code, .. } => {
                let (index, subindex) = r.object();
                self.fault(FaultReason::SdoAbort {
                    index,
                    subindex,
                    abort_code: code,
                });
                None
            }
            Response::UploadOk { value, .. } => Some(SdoAnswer::Uploaded(value)),
            Response::DownloadOk { .. } => Some(SdoAnswer::Downloaded),
        }
    }

    fn next_step(&mut self, now: u64, step: usize, out: &mut Outbox) {
        if step + 1 < self.steps.len() {
            self.send_step(now, step + 1, false, out);
        } else {
            self.phase = Phase::Configured;
        }
    }
}
