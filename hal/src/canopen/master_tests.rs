//! Tests of the CANopen master against a fake port fed by the test.

use std::collections::VecDeque;

use super::*;
use crate::cia402;
use std::time::Duration;

/// Node `n` runs with its drive enabled.
fn enabled(n: &Node) -> bool {
    n.phase == Phase::Running && n.drive.phase() == DrivePhase::Enabled
}

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

/// The node id `n` (valid in every test).
fn id(n: u8) -> NodeId {
    NodeId::new(n).unwrap()
}

fn master(nodes: &[u8]) -> CanOpenMaster<FakePort> {
    let cfg = CanOpenConfig::new(
        nodes
            .iter()
            .map(|&n| NodeConfig {
                following_window_increments: Some(5000),
                ..NodeConfig::new(id(n), 1000.0)
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
    assert!(enabled(&m.nodes[0]));
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
    assert!(enabled(&m.nodes[0]));

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
    let per_node = ticks(Duration::from_millis(3000), Duration::from_millis(4)) * 2 + 2000 / 4;
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
        following_window_increments: Some(5000),
        ..NodeConfig::new(id(3), 1000.0)
    }]);
    cfg.spindle = Some(SpindleNodeConfig {
        node_id: id(9),
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
        if m.nodes.iter().all(enabled) {
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
    let cfg = |node: u8, units: f64| {
        let mut c = CanOpenConfig::new(vec![NodeConfig::new(id(3), 1000.0)]);
        c.spindle = Some(SpindleNodeConfig {
            node_id: id(node),
            units_per_rpm: units,
        });
        CanOpenMaster::new(FakePort::default(), "fake", c)
            .err()
            .map(|e| e.code())
    };
    assert_eq!(cfg(3, 1.0), Some("can_spindle_node_used"));
    assert_eq!(cfg(127, 1.0), Some("can_spindle_node_is_master"));
    assert_eq!(cfg(9, 0.0), Some("can_spindle_scale"));
    assert_eq!(cfg(9, 1.0), None);
    assert_eq!(NodeId::new(0).unwrap_err().code(), "can_node_id_range");
    assert_eq!(
        NodeId::try_from(128).unwrap_err().code(),
        "can_node_id_range"
    );
    assert_eq!(NodeId::try_from(127).map(NodeId::get), Ok(127));
    // Without a spindle node the bus says so.
    assert!(!master(&[3]).has_spindle());
}

/// A node is a state machine driven by its caller, without a port: each step leaves the
/// frames it sends in the outbox. From reset to NMT start, answered by hand.
#[test]
fn a_node_steps_from_reset_to_start_through_its_outbox() {
    let cfg = CanOpenConfig::new(vec![NodeConfig::new(id(5), 1000.0)]);
    let t = Timing::new(&cfg);
    let mut n = Node::new(&cfg, cfg.nodes[0].clone(), OpMode::Csp);
    let mut out = Outbox::new();
    n.phase = Phase::ResetPending {
        command: nmt::Command::ResetNode,
    };
    n.tick(1, 0, &t, &mut out);
    let sent: Vec<Frame> = out.take().collect();
    assert_eq!(sent, [nmt::command(nmt::Command::ResetNode, 5)]);
    // Boot-up, then one SDO request per tick or answer, each answered.
    n.on_heartbeat(2, nmt::state::BOOT_UP);
    n.tick(2, 0, &t, &mut out);
    let mut requests = 0;
    while n.phase != Phase::Configured {
        let sent: Vec<Frame> = out.take().collect();
        assert_eq!(sent.len(), 1, "{:?}", n.phase);
        requests += 1;
        let answer = match sdo::parse_request(sent[0].payload()).unwrap() {
            sdo::Request::Download {
                index, subindex, ..
            } => sdo::download_ok(5, index, subindex),
            sdo::Request::Upload { index, subindex } => sdo::upload_ok(5, index, subindex, 777, 4),
        };
        let r = sdo::parse_response(answer.payload()).unwrap();
        n.on_sdo_response(3, r, &mut out);
    }
    assert_eq!(requests, n.steps.len());
    assert_eq!(n.drive.actual_increments(), 777);
    n.nmt_start(4, &mut out);
    let sent: Vec<Frame> = out.take().collect();
    assert_eq!(sent, [nmt::command(nmt::Command::Start, 5)]);
    assert_eq!(n.drive.target_increments(), 777);
}

#[path = "io_tests.rs"]
mod io;
