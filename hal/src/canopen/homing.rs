//! The drive's own reference run (CiA 402 homing mode 6), started by the controller, and the
//! safe state after a fault stop: steps of a [`Node`]. A child of `master`.
//!
//! A reference run of one node, every step on the tick without blocking (SDO requests go out
//! and their answers are taken when they arrive, with the start-up's timeout and retry):
//! 1. the target holds at the actual position; SDO writes 0x6098 method, 0x607C home offset,
//!    0x6099:1/2 speeds, 0x609A acceleration, 0x6060 = 6, then 0x6061 is read until it
//!    shows 6;
//! 2. controlword bit 4 starts the run; statusword bit 13 (homing error) is a fault naming
//!    the node, bits 12 + 10 (homing attained, target reached) end it;
//! 3. 0x6060 = 8, 0x6061 read until 8, then the node follows setpoints again from the new
//!    position actual: its target holds there until the commanded position (re-based on the
//!    homed position by the controller) takes over within one tick's travel.
//!
//! The whole run is bounded by `homing_timeout`.

use super::*;

/// The drive's homing settings, written before each reference run (drive units).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HomingParams {
    /// 0x6098 homing method (CiA 402), e.g. 19/21: home switch without index pulse, 37:
    /// the current position.
    pub method: i8,
    /// 0x607C home offset, increments: the position actual value at the home position.
    pub offset_increments: i32,
    /// 0x6099:1 speed during the search for the switch, increments/s.
    pub search_speed: u32,
    /// 0x6099:2 speed during the search for zero (leaving the switch), increments/s.
    pub zero_speed: u32,
    /// 0x609A homing acceleration, increments/s².
    pub accel: u32,
}

/// Where a node's reference run is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Home {
    /// SDO steps: entering homing mode (`leaving: None`), or returning to CSP ending the run
    /// with the given state.
    Sdo {
        leaving: Option<HomingState>,
        step: usize,
        sent_at: u64,
        retried: bool,
    },
    /// Controlword bit 4 set since `since`: waiting for statusword bits 12 + 10.
    Running { since: u64 },
    /// Bit 4 cleared (stop asked, or a fault elsewhere): waiting for the drive to stand.
    Halting { since: u64 },
}

/// The SDO steps that return to CSP.
const LEAVE: [Step; 2] = [
    Step::Write {
        index: 0x6060,
        subindex: 0,
        value: 8,
        size: 1,
    },
    Step::CheckMode(8),
];

fn enter_step(p: &HomingParams, step: usize) -> Option<Step> {
    let w = |index, subindex, value, size| Step::Write {
        index,
        subindex,
        value,
        size,
    };
    Some(match step {
        0 => w(0x6098, 0, u32::from(p.method as u8), 1),
        1 => w(0x607C, 0, p.offset_increments as u32, 4),
        2 => w(0x6099, 1, p.search_speed, 4),
        3 => w(0x6099, 2, p.zero_speed, 4),
        4 => w(0x609A, 0, p.accel, 4),
        5 => w(0x6060, 0, 6, 1),
        6 => Step::CheckMode(6),
        _ => return None,
    })
}

/// Ticks between sending a controlword and reading the drive's answer to it: the RPDO is
/// latched at the next SYNC, and the TPDO of that SYNC arrives in the tick after.
const ANSWER_TICKS: u64 = 2;

impl Node {
    /// Step `step` of the entering (`leaving: None`) or returning SDO plan.
    fn homing_step_of(&self, leaving: Option<HomingState>, step: usize) -> Option<Step> {
        match leaving {
            None => self.cfg.homing.as_ref().and_then(|p| enter_step(p, step)),
            Some(_) => LEAVE.get(step).copied(),
        }
    }

    /// Starts the reference run of a node whose drive is enabled; any other reports it
    /// aborted.
    pub(super) fn start_homing(&mut self, now: u64, out: &mut Outbox) {
        let enabled = self.phase == Phase::Running && self.drive.phase() == DrivePhase::Enabled;
        if !enabled || self.cfg.homing.is_none() {
            self.homing = HomingState::Aborted;
            return;
        }
        self.homing = HomingState::Running;
        self.home_since = now;
        self.mode_changed = true;
        self.drive.hold(cw::ENABLE_OPERATION_CMD);
        self.send_homing_step(now, None, 0, false, out);
    }

    /// Interrupts the reference run: the drive stops, then returns to CSP.
    pub(super) fn stop_homing(&mut self, now: u64, out: &mut Outbox) {
        match self.phase {
            Phase::Homing(Home::Running { .. }) => {
                self.phase = Phase::Homing(Home::Halting { since: now });
            }
            Phase::Homing(Home::Sdo { leaving: None, .. }) => {
                self.send_homing_step(now, Some(HomingState::Aborted), 0, false, out);
            }
            _ => {}
        }
    }

    fn send_homing_step(
        &mut self,
        now: u64,
        leaving: Option<HomingState>,
        step: usize,
        retried: bool,
        out: &mut Outbox,
    ) {
        let Some(s) = self.homing_step_of(leaving, step) else {
            return;
        };
        self.phase = Phase::Homing(Home::Sdo {
            leaving,
            step,
            sent_at: now,
            retried,
        });
        out.push(self.sdo_request(s));
    }

    /// An SDO answer while entering or leaving homing mode.
    pub(super) fn on_homing_sdo(
        &mut self,
        now: u64,
        leaving: Option<HomingState>,
        step: usize,
        r: Response,
        out: &mut Outbox,
    ) {
        let Some(expected) = self.homing_step_of(leaving, step) else {
            return;
        };
        match self.sdo_answer(expected, r) {
            // The drive has not switched its mode yet: ask again.
            Some(SdoAnswer::Uploaded(value)) if matches!(expected, Step::CheckMode(m) if value as u8 != m) =>
            {
                self.send_homing_step(now, leaving, step, false, out);
            }
            Some(_) if self.homing_step_of(leaving, step + 1).is_some() => {
                self.send_homing_step(now, leaving, step + 1, false, out);
            }
            Some(_) => self.homing_plan_done(now, leaving),
            None => {}
        }
    }

    fn homing_plan_done(&mut self, now: u64, leaving: Option<HomingState>) {
        match leaving {
            None => self.phase = Phase::Homing(Home::Running { since: now }),
            Some(outcome) => {
                // Back in CSP, enabled: hold at the new position actual until the commanded
                // position (re-based on it) takes over.
                self.phase = Phase::Running;
                self.homing = outcome;
                self.mode_changed = false;
                self.drive.hold(cw::ENABLE_OPERATION_CMD);
            }
        }
    }

    /// One tick of a reference run: the target holds at the actual position; the drive
    /// must stay enabled; bounded by the homing timeout.
    pub(super) fn update_homing(&mut self, now: u64, h: Home, t: &Timing, out: &mut Outbox) {
        let s = self.drive.statusword();
        match PowerState::from_statusword(s) {
            PowerState::OperationEnabled => {}
            PowerState::Fault | PowerState::FaultReactionActive => {
                let code = self.drive.error_code();
                return self.fault(FaultReason::DriveFault { code });
            }
            _ => return self.fault(FaultReason::DriveDisabled { statusword: s }),
        }
        if now - self.home_since > t.homing {
            return self.fault(FaultReason::HomingTimeout);
        }
        match h {
            Home::Sdo { sent_at, .. } => {
                self.drive.hold(cw::ENABLE_OPERATION_CMD);
                if now - sent_at > t.sdo {
                    self.homing_sdo_timed_out(now, h, out);
                }
            }
            Home::Running { since } => {
                self.drive.hold(cw::ENABLE_OPERATION_CMD | cw::HOMING_START);
                if self.answers(now, since) {
                    self.on_homing_statusword(now, s, out);
                }
            }
            Home::Halting { since } => {
                self.drive.hold(cw::ENABLE_OPERATION_CMD);
                if self.answers(now, since) && s & sw::TARGET_REACHED != 0 {
                    self.send_homing_step(now, Some(HomingState::Aborted), 0, false, out);
                }
            }
        }
    }

    /// A statusword arrived this tick that answers the controlword sent at `since`.
    fn answers(&self, now: u64, since: u64) -> bool {
        self.tpdo_seen && now >= since + ANSWER_TICKS
    }

    /// The run's answer: a homing error, or homing attained with the drive standing.
    fn on_homing_statusword(&mut self, now: u64, s: u16, out: &mut Outbox) {
        const DONE: u16 = sw::HOMING_ATTAINED | sw::TARGET_REACHED;
        if s & sw::HOMING_ERROR != 0 {
            self.fault(FaultReason::HomingError { statusword: s });
        } else if s & DONE == DONE {
            self.send_homing_step(now, Some(HomingState::Done), 0, false, out);
        }
    }

    /// The homing SDO request `sdo` was not answered in time: once more, then a fault naming
    /// it.
    fn homing_sdo_timed_out(&mut self, now: u64, sdo: Home, out: &mut Outbox) {
        let Home::Sdo {
            leaving,
            step,
            retried,
            ..
        } = sdo
        else {
            return;
        };
        if !retried {
            return self.send_homing_step(now, leaving, step, true, out);
        }
        if let Some(st) = self.homing_step_of(leaving, step) {
            let (index, subindex) = step_object(st);
            self.fault(FaultReason::SdoTimeout { index, subindex });
        }
    }

    /// After a fault stop with the healthy axes at rest: a drive still enabled (or on its
    /// way) goes to the safe state `controlword`, its target holding where it stands.
    pub(super) fn enter_safe_state(&mut self, controlword: u16) {
        let stops = match self.phase {
            Phase::Starting { .. } | Phase::Homing(_) => true,
            // Stopped already, or by a fault of its own: in its safe state.
            Phase::Running => matches!(
                self.drive.phase(),
                DrivePhase::Enabling { .. } | DrivePhase::Enabled
            ),
            _ => false,
        };
        if stops {
            if self.homing == HomingState::Running {
                self.homing = HomingState::Aborted;
            }
            self.phase = Phase::Running;
            self.drive.stop(controlword);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn enter_plan_writes_the_homing_objects_then_mode_6() {
        let p = HomingParams {
            method: -3,
            offset_increments: -20,
            search_speed: 1000,
            zero_speed: 100,
            accel: 5000,
        };
        let objects: Vec<(u16, u8)> = (0..7)
            .map(|k| step_object(enter_step(&p, k).unwrap()))
            .collect();
        assert_eq!(
            objects,
            [
                (0x6098, 0),
                (0x607C, 0),
                (0x6099, 1),
                (0x6099, 2),
                (0x609A, 0),
                (0x6060, 0),
                (0x6061, 0)
            ]
        );
        assert_eq!(enter_step(&p, 7), None);
        assert!(matches!(
            enter_step(&p, 0),
            Some(Step::Write {
                value: 0xFD,
                size: 1,
                ..
            })
        ));
        assert!(matches!(
            enter_step(&p, 1),
            Some(Step::Write {
                value: 0xFFFF_FFEC,
                size: 4,
                ..
            })
        ));
    }
}
