use super::*;
use crate::cia402::{apply_controlword, sw};

const TIMEOUT: u64 = 10;

fn position_drive() -> Drive {
    Drive::new(DriveSettings::new(Setpoint::Position, 5.0, TIMEOUT))
}

/// A drive-side CiA 402 power stage answering the master's controlwords, one per tick.
struct Stage {
    state: PowerState,
    last_cw: u16,
}

impl Stage {
    fn new(state: PowerState) -> Stage {
        Stage { state, last_cw: 0 }
    }

    /// The drive takes the controlword the master sent and reports its new statusword.
    fn answer(&mut self, d: &mut Drive, actual: i32) {
        let c = d.controlword();
        self.state = apply_controlword(self.state, self.last_cw, c);
        self.last_cw = c;
        d.on_status(self.state.statusword_bits(), actual);
    }
}

/// Ticks the drive from `tick` with a statusword every tick until it is enabled.
fn enable(d: &mut Drive, stage: &mut Stage, mut tick: u64) -> u64 {
    d.begin_enable(tick);
    while d.phase() != DrivePhase::Enabled {
        tick += 1;
        assert!(tick < 100, "not enabled: {:?}", d.phase());
        stage.answer(d, 1000);
        d.tick(tick, true, 0);
    }
    tick
}

#[test]
fn enables_on_fresh_statuswords_and_waits_on_stale_ones() {
    let mut d = position_drive();
    let mut stage = Stage::new(PowerState::SwitchOnDisabled);
    d.on_status(stage.state.statusword_bits(), 1000);
    d.begin_enable(0);
    d.tick(1, true, 0);
    assert_eq!(d.controlword(), cw::SHUTDOWN);
    // No statusword this tick: the controlword stays, nothing is decided on the old word.
    d.tick(2, false, 0);
    assert_eq!(d.controlword(), cw::SHUTDOWN);
    assert_eq!(d.phase(), DrivePhase::Enabling { since: 0 });
    let mut tick = 2;
    while d.phase() != DrivePhase::Enabled {
        tick += 1;
        stage.answer(&mut d, 1000);
        d.tick(tick, true, 0);
    }
    assert_eq!(stage.state, PowerState::OperationEnabled);
    assert_eq!(d.controlword(), cw::ENABLE_OPERATION_CMD);
    // While enabling the target held at the actual position.
    assert_eq!(d.target_increments(), 1000);
}

/// The one enable-timeout rule of every bus: judged every tick, statusword or not; a fresh
/// Operation Enabled in the tick the timeout passes wins.
#[test]
fn enable_timeout_is_judged_every_tick_and_a_fresh_enabled_wins() {
    let enabled = PowerState::OperationEnabled.statusword_bits();
    let off = PowerState::SwitchOnDisabled.statusword_bits();
    let mut silent = position_drive();
    silent.on_status(off, 0);
    silent.begin_enable(0);
    silent.tick(TIMEOUT, false, 0);
    assert_eq!(silent.phase(), DrivePhase::Enabling { since: 0 });
    silent.tick(TIMEOUT + 1, false, 0);
    assert_eq!(
        silent.phase(),
        DrivePhase::Faulted(FaultReason::EnableTimeout { statusword: off })
    );
    assert_eq!(silent.controlword(), cw::DISABLE_VOLTAGE);

    let mut late = position_drive();
    late.begin_enable(0);
    late.on_status(enabled, 0);
    late.tick(TIMEOUT + 1, true, 0);
    assert_eq!(late.phase(), DrivePhase::Enabled);

    let mut stuck = position_drive();
    stuck.begin_enable(0);
    stuck.on_status(off, 0);
    stuck.tick(TIMEOUT + 1, true, 0);
    assert_eq!(
        stuck.fault_reason(),
        Some(FaultReason::EnableTimeout { statusword: off })
    );
}

#[test]
fn an_enabled_position_drive_holds_until_the_command_comes_within_one_tick() {
    let mut d = position_drive();
    let mut stage = Stage::new(PowerState::SwitchOnDisabled);
    let mut tick = enable(&mut d, &mut stage, 0);
    // The controller still commands 0 while the drive stands at 1000: hold, no jump.
    for target in [0, 994] {
        tick += 1;
        d.on_status(stage.state.statusword_bits(), 1000);
        d.tick(tick, true, target);
        assert_eq!(d.target_increments(), 1000);
    }
    // Within one tick's travel (5): taken over, and from then on followed.
    for target in [1004, 1009, 1020] {
        tick += 1;
        d.tick(tick, true, target);
        assert_eq!(d.target_increments(), target);
    }
    // A reference run by the drive holds it: afterwards it is taken over anew.
    d.hold(cw::ENABLE_OPERATION_CMD);
    d.tick(tick + 1, true, 0);
    assert_eq!(d.target_increments(), 1000);

    let mut spindle = Drive::new(DriveSettings::new(Setpoint::Velocity, 1.0, TIMEOUT));
    let mut stage = Stage::new(PowerState::SwitchOnDisabled);
    let tick = enable(&mut spindle, &mut stage, 0);
    spindle.tick(tick + 1, true, 3000);
    assert_eq!(spindle.target_increments(), 3000);
}

#[test]
fn faults_by_statusword_and_following_error_keep_the_first_cause() {
    let mut d = Drive::new(DriveSettings {
        following_error_increments: Some(50.0),
        ..DriveSettings::new(Setpoint::Position, 5.0, TIMEOUT)
    });
    let mut stage = Stage::new(PowerState::SwitchOnDisabled);
    let tick = enable(&mut d, &mut stage, 0);
    d.tick(tick + 1, true, 1000);
    // The drive lags 100 increments behind its target: the master's check stops it.
    d.on_status(stage.state.statusword_bits(), 900);
    d.tick(tick + 2, true, 1000);
    assert_eq!(d.fault_reason(), Some(FaultReason::FollowingError));
    assert_eq!(d.controlword(), cw::DISABLE_VOLTAGE);
    assert_eq!(d.target_increments(), 900);
    // A later drive fault does not replace the cause.
    d.fault(FaultReason::DriveFault { code: 0x2310 });
    assert_eq!(d.fault_reason(), Some(FaultReason::FollowingError));

    let mut e = position_drive();
    let mut stage = Stage::new(PowerState::SwitchOnDisabled);
    let tick = enable(&mut e, &mut stage, 0);
    e.set_error_code(0x7500);
    e.on_status(PowerState::Fault.statusword_bits(), 1000);
    e.tick(tick + 1, true, 1000);
    assert_eq!(
        e.fault_reason(),
        Some(FaultReason::DriveFault { code: 0x7500 })
    );
    let mut f = position_drive();
    f.begin_enable(0);
    f.on_status(
        PowerState::OperationEnabled.statusword_bits() | sw::FOLLOWING_ERROR,
        1000,
    );
    f.tick(1, true, 1000);
    f.tick(2, true, 1000);
    assert_eq!(f.fault_reason(), Some(FaultReason::FollowingError));
}

#[test]
fn power_down_walks_down_one_step_per_statusword() {
    for (mode, walk) in [
        (
            ShutdownMode::Disable,
            &[cw::SWITCH_ON_CMD, cw::SHUTDOWN, cw::DISABLE_VOLTAGE][..],
        ),
        (
            ShutdownMode::QuickStop,
            &[cw::QUICK_STOP_CMD, cw::DISABLE_VOLTAGE][..],
        ),
    ] {
        let mut d = Drive::new(DriveSettings {
            shutdown: mode,
            ..DriveSettings::new(Setpoint::Position, 5.0, TIMEOUT)
        });
        let mut stage = Stage::new(PowerState::SwitchOnDisabled);
        let mut tick = enable(&mut d, &mut stage, 0);
        d.tick(tick + 1, true, 1002);
        tick += 1;
        d.begin_power_down(tick);
        let mut sent = Vec::new();
        while d.phase() != DrivePhase::Off {
            tick += 1;
            d.tick(tick, true, 0);
            // The target stays where it was while the drive is walked down.
            assert_eq!(d.target_increments(), 1002);
            if d.phase() != DrivePhase::Off {
                sent.push(d.controlword());
                stage.answer(&mut d, 1000);
            }
        }
        sent.push(d.controlword());
        sent.dedup();
        assert_eq!(sent, walk, "{mode:?}");
        assert_eq!(stage.state, PowerState::SwitchOnDisabled);
    }
}

#[test]
fn power_down_ends_at_the_timeout_without_answers() {
    let mut d = position_drive();
    let mut stage = Stage::new(PowerState::SwitchOnDisabled);
    let tick = enable(&mut d, &mut stage, 0);
    d.begin_power_down(tick);
    d.tick(tick + TIMEOUT, false, 0);
    assert_eq!(d.phase(), DrivePhase::PoweringDown { since: tick });
    d.tick(tick + TIMEOUT + 1, false, 0);
    assert_eq!(d.phase(), DrivePhase::Off);
    assert_eq!(d.controlword(), cw::DISABLE_VOLTAGE);
}

#[test]
fn a_stopped_drive_holds_and_enables_again_from_quick_stop() {
    let mut d = position_drive();
    let mut stage = Stage::new(PowerState::SwitchOnDisabled);
    let tick = enable(&mut d, &mut stage, 0);
    d.stop(FaultReaction::QuickStop.controlword().unwrap());
    stage.answer(&mut d, 1010);
    assert_eq!(stage.state, PowerState::QuickStopActive);
    d.tick(tick + 1, true, 0);
    assert_eq!(d.phase(), DrivePhase::Stopped);
    assert_eq!(d.target_increments(), 1010);
    assert_eq!(d.controlword(), cw::QUICK_STOP_CMD);
    enable(&mut d, &mut stage, tick + 1);
    assert_eq!(stage.state, PowerState::OperationEnabled);
    assert_eq!(FaultReaction::Hold.controlword(), None);
}
