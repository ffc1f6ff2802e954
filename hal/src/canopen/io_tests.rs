//! Tests of the master's digital I/O against the fake port: CiA 401 modules (configuration,
//! inputs, outputs, faults naming the node) and the drives' own 0x60FD / 0x60FE:1.

use super::*;
use crate::io::{IoBits, IoMap, IoPoint};

const MODULE: u8 = 10;

/// Axis node 3 and module 10: inputs module bits 0 and 9, drive 3 bit 2 (home switch);
/// outputs module bits 2 and 3 (output 1 safe on), drive 3 output bit 0.
fn io_master(with_drive_io: bool) -> CanOpenMaster<FakePort> {
    let mut cfg = CanOpenConfig::new(vec![NodeConfig::new(id(3), 1000.0)]);
    let m = |bit| IoPoint::Module { node: MODULE, bit };
    cfg.io = IoMap {
        inputs: vec![m(0), m(9), IoPoint::Sim],
        outputs: vec![m(2), m(3)],
        safe_outputs: IoBits(0b10),
    };
    if with_drive_io {
        cfg.io.inputs.push(IoPoint::Drive { axis: 0, bit: 2 });
        cfg.io.outputs.push(IoPoint::Drive { axis: 0, bit: 0 });
    }
    CanOpenMaster::new(FakePort::default(), "fake", cfg).unwrap()
}

/// What the test's devices last said and were told.
#[derive(Default)]
struct Devices {
    /// SDO writes per node: (node, index, subindex, value).
    writes: Vec<(u8, u16, u8, u32)>,
    started: Vec<u8>,
    drive_state: Option<PowerState>,
    last_cw: u16,
    /// Inputs the module sends (its two groups) and the drive's 0x60FD.
    module_inputs: [u8; 2],
    drive_inputs: u32,
}

impl Devices {
    /// One tick: the devices answer what the master sent in the last one.
    fn tick(&mut self, m: &mut CanOpenMaster<FakePort>) -> (Vec<Frame>, Result<(), BusFault>) {
        if self.started.contains(&3) {
            let state = self.drive_state.unwrap_or(PowerState::SwitchOnDisabled);
            tpdo(m, state, 0, 2500);
            if m.nodes[0].io.inputs {
                rx(m, cia401::encode_u32(0x283, self.drive_inputs));
            }
        }
        if self.started.contains(&MODULE) {
            rx(
                m,
                Frame::new(0x180 + u16::from(MODULE), &self.module_inputs),
            );
            rx(m, nmt::heartbeat(MODULE, nmt::state::OPERATIONAL));
        }
        let (sent, r) = step(m);
        for f in &sent {
            self.record(f);
        }
        answer_sdos(m, &sent);
        (sent, r)
    }

    fn record(&mut self, f: &Frame) {
        if let Ok(sdo::Request::Download {
            index,
            subindex,
            value,
            ..
        }) = sdo::parse_request(f.payload())
            && f.id & 0x780 == cob::SDO_RX
        {
            self.writes
                .push(((f.id & 0x7F) as u8, index, subindex, value));
        }
        if f.id == cob::NMT && f.data[0] == nmt::Command::Start as u8 {
            self.started.push(f.data[1]);
        }
        if f.id == 0x203 {
            let c = Rpdo::decode(f.payload()).unwrap().controlword;
            let s = self.drive_state.unwrap_or(PowerState::SwitchOnDisabled);
            self.drive_state = Some(cia402::apply_controlword(s, self.last_cw, c));
            self.last_cw = c;
        }
    }

    /// From enable to the drive enabled and the module running.
    fn bring_up(&mut self, m: &mut CanOpenMaster<FakePort>) {
        m.enable();
        let _ = self.tick(m);
        rx(m, nmt::heartbeat(3, nmt::state::BOOT_UP));
        rx(m, nmt::heartbeat(MODULE, nmt::state::BOOT_UP));
        for _ in 0..300 {
            let (_, r) = self.tick(m);
            assert!(r.is_ok(), "{r:?}");
            if enabled(&m.nodes[0]) && m.modules[0].phase == Phase::Running {
                return;
            }
        }
        panic!("not up: {:?} {:?}", m.nodes[0].phase, m.modules[0].phase);
    }

    /// The last value written to `index:subindex` of `node`.
    fn wrote(&self, node: u8, index: u16, subindex: u8) -> Option<u32> {
        self.writes
            .iter()
            .rev()
            .find(|w| (w.0, w.1, w.2) == (node, index, subindex))
            .map(|w| w.3)
    }
}

#[test]
fn a_module_is_booted_and_configured_with_its_error_values() {
    let mut m = io_master(false);
    let mut d = Devices::default();
    d.bring_up(&mut m);
    let w = |index, sub| d.wrote(MODULE, index, sub);
    // Inputs up to bit 9: two groups of 0x6000 in a synchronous TPDO1.
    assert_eq!(w(0x1A00, 1), Some(0x6000_0108));
    assert_eq!(w(0x1A00, 2), Some(0x6000_0208));
    assert_eq!(w(0x1800, 2), Some(1));
    // Outputs up to bit 3: one group of 0x6200 in an event-driven RPDO1.
    assert_eq!(w(0x1600, 1), Some(0x6200_0108));
    assert_eq!(w(0x1600, 2), None);
    assert_eq!(w(0x1400, 2), Some(0xFF));
    // Error mode and values: output 1 (module bit 3) is safe on.
    assert_eq!(w(0x6206, 1), Some(0xFF));
    assert_eq!(w(0x6207, 1), Some(0b1000));
    assert_eq!(w(0x1016, 1), Some((127 << 16) | 500));
    assert_eq!(w(0x1017, 0), Some(100));
    assert!(d.started.contains(&MODULE) && d.started.contains(&3));
    // The drive without I/O points keeps its PDO1 layout alone.
    assert!(
        !d.writes
            .iter()
            .any(|w| w.0 == 3 && (w.1 & 0xFF00) == 0x1A00 && w.1 != 0x1A00)
    );
}

#[test]
fn module_inputs_and_outputs_travel_every_cycle() {
    let mut m = io_master(false);
    let mut d = Devices::default();
    d.bring_up(&mut m);
    d.module_inputs = [0x01, 0x02];
    let _ = d.tick(&mut m);
    let mut fb = CycleFeedback::default();
    let cmd = CycleCommand {
        outputs: IoBits(0b01),
        ..CycleCommand::default()
    };
    m.cycle(&cmd, &mut fb).unwrap();
    // Input 0 is module bit 0, input 1 module bit 9 (group 2 bit 1); input 2 is not ours.
    assert_eq!(fb.inputs, IoBits(0b011));
    // Output 0 is module bit 2: its RPDO carries one group.
    let f = m
        .port
        .tx
        .iter()
        .find(|f| f.id == 0x20A)
        .expect("module RPDO");
    assert_eq!(f.payload(), [0b100]);
}

#[test]
fn a_module_fault_names_its_node_and_no_axis() {
    let mut m = io_master(false);
    let mut d = Devices::default();
    d.bring_up(&mut m);
    // The module's heartbeat stops; its TPDO continues.
    d.started.retain(|&n| n != MODULE);
    let mut fault = None;
    for _ in 0..200 {
        rx(&mut m, Frame::new(0x18A, &[0, 0]));
        if let Err(e) = d.tick(&mut m).1 {
            fault = Some(e);
            break;
        }
    }
    let e = fault.expect("heartbeat loss of the module");
    assert_eq!(
        e,
        BusFault {
            axis: None,
            node: Some(MODULE),
            reason: FaultReason::HeartbeatLost
        }
    );
    assert!(e.to_string().ends_with("node 10"), "{e}");
    // A reset restarts it.
    m.reset();
    let (sent, _) = d.tick(&mut m);
    assert!(sent.contains(&nmt::command(nmt::Command::ResetCommunication, MODULE)));
}

#[test]
fn a_drive_with_io_points_maps_0x60fd_and_0x60fe() {
    let mut m = io_master(true);
    let mut d = Devices::default();
    d.bring_up(&mut m);
    assert_eq!(d.wrote(3, 0x1A01, 1), Some(0x60FD_0020));
    assert_eq!(d.wrote(3, 0x1801, 1), Some(0x283));
    assert_eq!(d.wrote(3, 0x1601, 1), Some(0x60FE_0120));
    assert_eq!(d.wrote(3, 0x1401, 1), Some(0x303));
    d.drive_inputs = 0b100;
    let _ = d.tick(&mut m);
    let mut fb = CycleFeedback::default();
    let cmd = CycleCommand {
        outputs: IoBits(0b100),
        ..CycleCommand::default()
    };
    m.cycle(&cmd, &mut fb).unwrap();
    assert!(
        fb.inputs.get(3),
        "input 3 is the drive's bit 2: {:?}",
        fb.inputs
    );
    let f = m.port.tx.iter().find(|f| f.id == 0x303).expect("RPDO2");
    assert_eq!(cia401::decode_u32(f.payload()), Some(1));
    // A TPDO2 of the wrong length is a mapping fault of the drive.
    rx(&mut m, Frame::new(0x283, &[1, 2]));
    let e = d.tick(&mut m).1.unwrap_err();
    assert_eq!(
        (e.axis, e.reason),
        (
            Some(0),
            FaultReason::PdoLength {
                cob_id: 0x283,
                len: 2,
                expected: 4
            }
        )
    );
}

#[test]
fn io_points_are_checked() {
    let build = |points: Vec<IoPoint>| {
        let mut cfg = CanOpenConfig::new(vec![NodeConfig::new(id(3), 1000.0)]);
        cfg.io.inputs = points;
        CanOpenMaster::new(FakePort::default(), "fake", cfg)
            .err()
            .map(|e| e.code())
    };
    let module = |node, bit| IoPoint::Module { node, bit };
    assert_eq!(build(vec![module(3, 0)]), Some("can_module_node_used"));
    assert_eq!(build(vec![module(127, 0)]), Some("can_module_node_used"));
    assert_eq!(build(vec![module(0, 0)]), Some("can_node_id_range"));
    assert_eq!(build(vec![module(9, 64)]), Some("can_module_bit_range"));
    let drive = |axis, bit| IoPoint::Drive { axis, bit };
    assert_eq!(build(vec![drive(1, 0)]), Some("can_io_drive_missing"));
    assert_eq!(
        build(vec![drive(crate::SPINDLE_AXIS, 0)]),
        Some("can_io_drive_missing")
    );
    assert_eq!(build(vec![drive(0, 32)]), Some("can_io_drive_bit_range"));
    assert_eq!(build(vec![drive(0, 31), module(9, 63), IoPoint::Sim]), None);
}
