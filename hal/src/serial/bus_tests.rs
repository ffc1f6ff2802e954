//! Tests of the serial bus against an in-memory line, the test playing the drive unit.

use super::*;
use crate::cia402::{self, PowerState};
use crate::io::{IoBits, IoMap, IoPoint};
use crate::serial::message::{AxisReply, IoStatus};
use std::sync::{Arc, Mutex};

/// Both directions of an in-memory line, and whether it hung up.
#[derive(Default)]
struct Line {
    to_drive: Vec<u8>,
    to_master: Vec<u8>,
    hung_up: bool,
}

/// The master's end of the in-memory line.
#[derive(Clone, Default)]
struct MemPort(Arc<Mutex<Line>>);

impl SerialPort for MemPort {
    fn try_read(&mut self, buf: &mut [u8]) -> Result<usize, LinkDown> {
        let mut line = self.0.lock().unwrap();
        if line.hung_up {
            return Err(LinkDown);
        }
        let n = line.to_master.len().min(buf.len());
        buf[..n].copy_from_slice(&line.to_master[..n]);
        line.to_master.drain(..n);
        Ok(n)
    }

    fn write(&mut self, frame: &[u8]) -> Result<(), LinkDown> {
        let mut line = self.0.lock().unwrap();
        if line.hung_up {
            return Err(LinkDown);
        }
        line.to_drive.extend_from_slice(frame);
        Ok(())
    }

    fn close(&mut self) {}

    fn reopen(&mut self) -> Result<(), SerialError> {
        if self.0.lock().unwrap().hung_up {
            return Err(SerialError::Open {
                path: "mem".into(),
                reason: "unplugged".into(),
            });
        }
        Ok(())
    }
}

/// The test plays the drive at the other end of the line: it answers requests by hand.
struct Unit {
    line: MemPort,
    decoder: Decoder,
}

impl Unit {
    /// Reads the last request sent and answers what `reply` makes of it (nothing on
    /// `None`).
    fn answer_with(&mut self, reply: impl FnOnce(&Request) -> Option<Reply>) -> Option<Request> {
        let bytes = std::mem::take(&mut self.line.0.lock().unwrap().to_drive);
        let mut got = None;
        self.decoder.feed(&bytes, |r| {
            if let Ok(p) = r {
                got = Request::decode(p);
            }
        });
        let req = got?;
        if let Some(y) = reply(&req) {
            let mut p = [0u8; frame::MAX_PAYLOAD];
            let n = y.encode(&mut p);
            let mut f = [0u8; frame::MAX_FRAME];
            let len = frame::encode(&p[..n], &mut f);
            self.line
                .0
                .lock()
                .unwrap()
                .to_master
                .extend_from_slice(&f[..len]);
        }
        Some(req)
    }

    /// Answers the last request for one axis with `statusword` at `position`.
    fn answer(&mut self, statusword: u16, position: i32) -> Option<Request> {
        self.answer_with(|req| {
            let mut y = v1_reply(req, position);
            y.axis[0].statusword = statusword;
            Some(y)
        })
    }

    fn hang_up(&self, hung_up: bool) {
        self.line.0.lock().unwrap().hung_up = hung_up;
    }
}

/// A version 1 reply of one enabled axis at `position`.
fn v1_reply(req: &Request, position: i32) -> Reply {
    let mut y = Reply {
        seq: req.seq,
        axes: 1,
        axis: [AxisReply::default(); MAX_AXES],
        spindle: None,
        home: None,
        io: None,
    };
    y.axis[0] = AxisReply {
        statusword: PowerState::OperationEnabled.statusword_bits(),
        position_increments: position,
        error_code: 0,
    };
    y
}

/// A version 3 reply of one enabled axis at `position`.
fn v3_reply(req: &Request, position: i32, home: HomeStatus) -> Option<Reply> {
    Some(Reply {
        home: Some(home),
        ..v1_reply(req, position)
    })
}

fn setup() -> (SerialBus<MemPort>, Unit) {
    setup_with(false)
}

fn setup_with(homing: bool) -> (SerialBus<MemPort>, Unit) {
    setup_io(homing, IoMap::default())
}

fn setup_io(homing: bool, io: IoMap) -> (SerialBus<MemPort>, Unit) {
    let line = MemPort::default();
    let cfg = SerialConfig {
        homing,
        io,
        ..SerialConfig::new("mem", vec![SerialAxis::new(4, 100.0)])
    };
    let bus = SerialBus::new(line.clone(), cfg).unwrap();
    let drive = Unit {
        line,
        decoder: Decoder::default(),
    };
    (bus, drive)
}

#[test]
fn a_bad_configuration_is_refused_with_its_code() {
    let axis = |increments_per_mm| SerialAxis::new(1, increments_per_mm);
    let open = |axes: Vec<SerialAxis>| {
        SerialBus::new(MemPort::default(), SerialConfig::new("mem", axes))
            .err()
            .map(|e| e.code())
    };
    assert_eq!(open(vec![]), Some("serial_axis_count"));
    assert_eq!(open(vec![axis(1.0), axis(0.0)]), Some("serial_axis_scale"));
    let stopped = SerialAxis {
        max_velocity_mm_s: 0.0,
        ..axis(1.0)
    };
    assert_eq!(open(vec![axis(1.0), stopped]), Some("serial_axis_speed"));
    assert_eq!(open(vec![axis(1.0)]), None);
    let cfg = SerialConfig {
        spindle: Some(SerialSpindle {
            node_id: 2,
            units_per_rpm: f64::NAN,
        }),
        ..SerialConfig::new("mem", vec![axis(1.0)])
    };
    let e = SerialBus::new(MemPort::default(), cfg).err().unwrap();
    assert_eq!(e.code(), "serial_spindle_scale");
}

#[test]
fn enables_follows_and_times_out_on_silence() {
    let (mut bus, mut drive) = setup();
    bus.enable();
    let mut fb = CycleFeedback::default();
    let mut cmd = CycleCommand::default();
    cmd.positions_mm[0] = 1.5;
    let mut state = PowerState::SwitchOnDisabled;
    let mut last_cw = 0;
    for _ in 0..12 {
        bus.cycle(&cmd, &mut fb).unwrap();
        let req = drive.answer(state.statusword_bits(), 100).unwrap();
        let c = req.axis[0].controlword;
        state = cia402::apply_controlword(state, last_cw, c);
        last_cw = c;
    }
    assert_eq!(state, PowerState::OperationEnabled);
    bus.cycle(&cmd, &mut fb).unwrap();
    assert_eq!(fb.axes[0].state, DriveState::Operational);
    assert!((fb.axes[0].position_mm - 1.0).abs() < 1e-9);
    let req = drive.answer(state.statusword_bits(), 150).unwrap();
    assert_eq!(req.axis[0].target_increments, 150);

    // Silence: exactly reply_timeout_ticks ticks pass without a fault, then Timeout.
    let mut ticks = 0;
    let e = loop {
        ticks += 1;
        if let Err(e) = bus.cycle(&cmd, &mut fb) {
            break e;
        }
    };
    assert_eq!(ticks, 27, "the first tick still reads the last reply");
    assert_eq!(e.reason, FaultReason::Timeout);
    assert_eq!((e.axis, e.node), (Some(0), Some(4)));
}

#[test]
fn hang_up_is_link_down_and_reset_keeps_it_until_the_port_returns() {
    let (mut bus, mut drive) = setup();
    bus.enable();
    drive.hang_up(true);
    let mut fb = CycleFeedback::default();
    let cmd = CycleCommand::default();
    let e = bus.cycle(&cmd, &mut fb).unwrap_err();
    assert_eq!(e.reason, FaultReason::LinkDown);
    assert_eq!(fb.axes[0].state, DriveState::Fault);
    // Still unplugged: the reset cannot reopen the port, the fault stays.
    bus.reset();
    let e = bus.cycle(&cmd, &mut fb).unwrap_err();
    assert_eq!(e.reason, FaultReason::LinkDown);
    assert!(
        drive.answer(0, 0).is_none(),
        "nothing is sent on a closed port"
    );
    // Plugged in again: the reset reopens it and the drive is enabled again.
    drive.hang_up(false);
    bus.reset();
    bus.cycle(&cmd, &mut fb).unwrap();
    assert_eq!(fb.axes[0].state, DriveState::Enabling);
    drive.answer(PowerState::SwitchOnDisabled.statusword_bits(), 0);
    bus.cycle(&cmd, &mut fb).unwrap();
    let req = drive.answer(0, 0).unwrap();
    assert_eq!(req.axis[0].controlword, cw::SHUTDOWN);
}

/// Version 3: the switch input reaches `home_switch`; the reference command shifts the
/// reported position at once (replies still in the old reference are shifted by the
/// controller) and is repeated until acknowledged; a refusal faults the axis.
#[test]
fn reference_command_is_repeated_until_acknowledged_and_a_refusal_faults_the_axis() {
    let (mut bus, mut drive) = setup_with(true);
    bus.enable();
    let mut fb = CycleFeedback::default();
    let mut cmd = CycleCommand::default();
    cmd.positions_mm[0] = 1.0;
    let pressed = HomeStatus {
        switches: 1,
        ..HomeStatus::default()
    };
    for _ in 0..3 {
        bus.cycle(&cmd, &mut fb).unwrap();
        let req = drive.answer_with(|r| v3_reply(r, 100, pressed)).unwrap();
        assert_eq!(req.version(), 3);
    }
    bus.cycle(&cmd, &mut fb).unwrap();
    assert_eq!(fb.axes[0].state, DriveState::Operational);
    assert!(bus.home_switch(0) && !bus.home_switch(1));
    // The switch was met at 1 mm; it becomes -2 mm: the drive shifts by -300 increments.
    bus.set_home(0, 1.0, -2.0);
    cmd.positions_mm[0] = -2.0;
    // The drive has not seen the command yet (its reply is in the old reference).
    let req = drive.answer_with(|r| v3_reply(r, 100, pressed)).unwrap();
    assert_eq!(req.home.unwrap().action, HomeAction::None);
    bus.cycle(&cmd, &mut fb).unwrap();
    assert!((fb.axes[0].position_mm + 2.0).abs() < 1e-9, "{fb:?}");
    // Its reply is lost: the command comes again with the same id.
    let first = drive.answer_with(|_| None).unwrap().home.unwrap();
    bus.cycle(&cmd, &mut fb).unwrap();
    assert!((fb.axes[0].position_mm + 2.0).abs() < 1e-9, "{fb:?}");
    let acked = HomeStatus {
        id: first.id,
        ..pressed
    };
    let again = drive.answer_with(|r| v3_reply(r, -200, acked)).unwrap();
    assert_eq!(again.home, Some(first));
    assert_eq!(
        (
            first.action,
            first.shift_increments,
            again.axis[0].target_increments
        ),
        (HomeAction::SetReference, -300, -200)
    );
    bus.cycle(&cmd, &mut fb).unwrap();
    assert!((fb.axes[0].position_mm + 2.0).abs() < 1e-9, "{fb:?}");
    let idle = drive.answer_with(|r| v3_reply(r, -200, acked)).unwrap();
    assert_eq!(idle.home.unwrap().action, HomeAction::None);

    // The next command is refused: a fault naming the axis.
    bus.cycle(&cmd, &mut fb).unwrap();
    bus.set_home(0, -2.0, 0.0);
    drive.answer_with(|r| v3_reply(r, -200, acked));
    bus.cycle(&cmd, &mut fb).unwrap();
    let refused = HomeStatus {
        id: first.id.wrapping_add(1),
        result: HomeResult::Refused,
        ..pressed
    };
    drive.answer_with(|r| v3_reply(r, 0, refused));
    let e = bus.cycle(&cmd, &mut fb).unwrap_err();
    assert_eq!(
        (e.reason, e.axis, e.node),
        (FaultReason::HomingRefused, Some(0), Some(4))
    );
}

#[test]
fn an_unacknowledged_reference_command_times_out() {
    let (mut bus, mut drive) = setup_with(true);
    bus.enable();
    let mut fb = CycleFeedback::default();
    let cmd = CycleCommand::default();
    for _ in 0..4 {
        bus.cycle(&cmd, &mut fb).unwrap();
        drive.answer_with(|r| v3_reply(r, 0, HomeStatus::default()));
    }
    bus.set_home(0, 0.0, 1.0);
    let mut ticks = 0;
    let e = loop {
        ticks += 1;
        match bus.cycle(&cmd, &mut fb) {
            Ok(()) => drive.answer_with(|r| v3_reply(r, 0, HomeStatus::default())),
            Err(e) => break e,
        };
    };
    assert_eq!(ticks, HOME_ACK_TIMEOUT_TICKS + 1);
    assert_eq!(
        (e.reason, e.axis, e.node),
        (FaultReason::HomingTimeout, Some(0), Some(4))
    );
}

/// A unit of an older version answers only the probes: refused at start-up, clearly.
#[test]
fn an_old_unit_is_refused_when_homing_needs_version_3() {
    let (mut bus, mut drive) = setup_with(true);
    bus.enable();
    let mut fb = CycleFeedback::default();
    let cmd = CycleCommand::default();
    let mut probes = 0;
    let e = loop {
        if let Err(e) = bus.cycle(&cmd, &mut fb) {
            break e;
        }
        let req = drive
            .answer_with(|r| {
                let mut y = v3_reply(r, 0, HomeStatus::default())?;
                y.home = None;
                (r.version() == 1).then_some(y)
            })
            .unwrap();
        if req.version() == 1 {
            probes += 1;
            assert_eq!(req.axis[0].controlword, cw::DISABLE_VOLTAGE);
        }
    };
    assert_eq!(probes, PROBE_ANSWERS);
    assert_eq!(
        e.reason,
        FaultReason::ProtocolVersion {
            drive: 1,
            needed: 3
        }
    );
    assert!(e.to_string().contains("version 1, homing needs version 3"));
}

/// The drive unit's CiA 402 power stage of axis 0, standing at `position`: it answers
/// each request with its state, then takes the request's controlword.
struct Stage {
    state: PowerState,
    last_cw: u16,
    position: i32,
}

impl Stage {
    fn new(position: i32) -> Stage {
        Stage {
            state: PowerState::SwitchOnDisabled,
            last_cw: 0,
            position,
        }
    }

    /// One tick of the bus and the unit's answer to its request.
    fn exchange(
        &mut self,
        bus: &mut SerialBus<MemPort>,
        unit: &mut Unit,
        cmd: &CycleCommand,
    ) -> (Result<(), BusFault>, CycleFeedback, AxisRequest) {
        let mut fb = CycleFeedback::default();
        let r = bus.cycle(cmd, &mut fb);
        let req = unit
            .answer(self.state.statusword_bits(), self.position)
            .unwrap();
        let c = req.axis[0].controlword;
        self.state = cia402::apply_controlword(self.state, self.last_cw, c);
        self.last_cw = c;
        (r, fb, req.axis[0])
    }

    /// Ticks until the drive is enabled (and the bus saw it).
    fn enable(&mut self, bus: &mut SerialBus<MemPort>, unit: &mut Unit, cmd: &CycleCommand) {
        for _ in 0..12 {
            self.exchange(bus, unit, cmd).0.unwrap();
        }
        assert_eq!(self.state, PowerState::OperationEnabled);
    }
}

/// The controller still commands 0 mm while the drive stands at 3 mm (it takes its
/// commanded position from the drives once all are enabled): the target holds, no jump.
#[test]
fn an_enabled_drive_holds_until_the_command_comes_within_one_tick() {
    let (mut bus, mut unit) = setup();
    bus.enable();
    let mut stage = Stage::new(300);
    let mut cmd = CycleCommand::default();
    stage.enable(&mut bus, &mut unit, &cmd);
    let (r, fb, req) = stage.exchange(&mut bus, &mut unit, &cmd);
    r.unwrap();
    assert_eq!(fb.axes[0].state, DriveState::Operational);
    assert_eq!(req.target_increments, 300);
    // Within one tick at 200 mm/s (80 increments): taken over, then followed.
    for (mm, increments) in [(3.5, 350), (4.2, 420), (0.0, 0)] {
        cmd.positions_mm[0] = mm;
        let (_, _, req) = stage.exchange(&mut bus, &mut unit, &cmd);
        assert_eq!(req.target_increments, increments);
    }
}

/// After a fault stop the drive quick-stops and holds; a reset enables it again; the
/// shutdown walks it down 07h → 06h → 00h and nothing enables it after that.
#[test]
fn safe_state_holds_and_shutdown_walks_the_drive_down() {
    let (mut bus, mut unit) = setup();
    bus.enable();
    let mut stage = Stage::new(120);
    let cmd = CycleCommand::default();
    stage.enable(&mut bus, &mut unit, &cmd);
    bus.safe_state();
    let (r, fb, req) = stage.exchange(&mut bus, &mut unit, &cmd);
    r.unwrap();
    assert_eq!(req.controlword, cw::QUICK_STOP_CMD);
    assert_eq!(req.target_increments, 120);
    assert_eq!(fb.axes[0].state, DriveState::Disabled);
    assert_eq!(stage.state, PowerState::QuickStopActive);
    bus.reset();
    stage.enable(&mut bus, &mut unit, &cmd);

    bus.shutdown();
    let mut sent = Vec::new();
    while !bus.is_shut_down() {
        assert!(sent.len() < 10, "no end: {sent:X?}");
        sent.push(stage.exchange(&mut bus, &mut unit, &cmd).1.axes[0].state);
    }
    assert_eq!(stage.state, PowerState::SwitchOnDisabled);
    assert!(sent.iter().all(|s| *s != DriveState::Operational));
    bus.reset();
    bus.enable();
    let (_, fb, req) = stage.exchange(&mut bus, &mut unit, &cmd);
    assert_eq!(req.controlword, cw::DISABLE_VOLTAGE);
    assert_eq!(fb.axes[0].state, DriveState::Disabled);
}

#[test]
fn shutdown_walk_sends_disable_operation_then_shutdown_then_disable_voltage() {
    let (mut bus, mut unit) = setup();
    bus.enable();
    let mut stage = Stage::new(0);
    let cmd = CycleCommand::default();
    stage.enable(&mut bus, &mut unit, &cmd);
    bus.shutdown();
    let mut words = Vec::new();
    while !bus.is_shut_down() {
        assert!(words.len() < 10, "no end: {words:X?}");
        words.push(stage.exchange(&mut bus, &mut unit, &cmd).2.controlword);
    }
    words.dedup();
    // The first request after `shutdown` still answers the enabled statusword read
    // before it: the walk starts there.
    assert_eq!(
        words,
        [cw::SWITCH_ON_CMD, cw::SHUTDOWN, cw::DISABLE_VOLTAGE],
        "{words:X?}"
    );
}

#[test]
fn a_link_down_ends_the_shutdown_walk_at_once() {
    let (mut bus, mut unit) = setup();
    bus.enable();
    let mut stage = Stage::new(0);
    stage.enable(&mut bus, &mut unit, &CycleCommand::default());
    bus.shutdown();
    unit.hang_up(true);
    let mut fb = CycleFeedback::default();
    let _ = bus.cycle(&CycleCommand::default(), &mut fb);
    assert!(bus.is_shut_down());
}

/// Inputs 0 and 2 on the unit's bits 5 and 63 (input 1 is another bus's); outputs 1 and 2
/// on its bits 0 and 40 (output 0 another bus's), output 2 on when the link is lost.
fn io_map() -> IoMap {
    IoMap {
        inputs: vec![
            IoPoint::Serial { bit: 5 },
            IoPoint::Sim,
            IoPoint::Serial { bit: 63 },
        ],
        outputs: vec![
            IoPoint::Module { node: 9, bit: 0 },
            IoPoint::Serial { bit: 0 },
            IoPoint::Serial { bit: 40 },
        ],
        safe_outputs: IoBits(0b100),
    }
}

/// A version 4 reply of one enabled axis with input word `inputs`, holding the safe word
/// when `held`.
fn v4_reply(req: &Request, inputs: u64, held: bool) -> Option<Reply> {
    Some(Reply {
        io: Some(IoStatus {
            inputs,
            safe_held: held,
        }),
        ..v1_reply(req, 0)
    })
}

/// Version 4: the output word carries the configured outputs in the unit's bits, the safe
/// word goes out until a reply confirms it, and the reply's input word fills the inputs.
#[test]
fn io_words_map_both_ways_and_the_safe_word_goes_out_until_confirmed() {
    let (mut bus, mut unit) = setup_io(false, io_map());
    bus.enable();
    let mut fb = CycleFeedback {
        inputs: IoBits(0b010),
        ..CycleFeedback::default()
    };
    let cmd = CycleCommand {
        outputs: IoBits(0b111),
        ..CycleCommand::default()
    };
    bus.cycle(&cmd, &mut fb).unwrap();
    assert_eq!(
        fb.inputs,
        IoBits::NONE,
        "nothing received yet, other buses' bits are 0"
    );
    // The first reply does not yet hold the safe word: it goes out again.
    let req = unit.answer_with(|r| v4_reply(r, 1 << 5 | 1 << 63 | 1 << 6, false));
    let io = req.unwrap().io.unwrap();
    assert_eq!(io.outputs, 1 | 1 << 40);
    assert_eq!(io.safe_outputs, Some(1 << 40));
    bus.cycle(&cmd, &mut fb).unwrap();
    assert_eq!(fb.inputs, IoBits(0b101));
    let req = unit.answer_with(|r| v4_reply(r, 1 << 63, true)).unwrap();
    assert_eq!(req.version(), 4);
    assert_eq!(req.io.unwrap().safe_outputs, Some(1 << 40));
    bus.cycle(&cmd, &mut fb).unwrap();
    assert_eq!(fb.inputs, IoBits(0b100));
    let req = unit.answer_with(|r| v4_reply(r, 0, true)).unwrap();
    assert_eq!(req.io.unwrap().safe_outputs, None, "confirmed");
    // The unit restarted and lost it: sent again.
    bus.cycle(&cmd, &mut fb).unwrap();
    unit.answer_with(|r| v4_reply(r, 0, false));
    bus.cycle(&cmd, &mut fb).unwrap();
    let req = unit.answer_with(|r| v4_reply(r, 0, true)).unwrap();
    assert_eq!(req.io.unwrap().safe_outputs, Some(1 << 40));
}

/// An I/O map without serial points leaves the link in version 1, exactly as before.
#[test]
fn io_on_other_buses_keeps_the_link_on_version_1() {
    let others = IoMap {
        inputs: vec![IoPoint::Sim],
        outputs: vec![IoPoint::Module { node: 2, bit: 1 }],
        safe_outputs: IoBits(1),
    };
    let (mut bus, mut unit) = setup_io(false, others);
    bus.enable();
    let mut fb = CycleFeedback::default();
    let cmd = CycleCommand {
        outputs: IoBits(1),
        ..CycleCommand::default()
    };
    for _ in 0..3 {
        bus.cycle(&cmd, &mut fb).unwrap();
        let req = unit.answer(PowerState::SwitchOnDisabled.statusword_bits(), 0);
        assert_eq!(req.unwrap().version(), 1);
    }
}

/// A unit of version 3 (it answers versions 1 to 3, never 4) is refused, named as version 3
/// when homing lets the probes ask version 3, as version 1 otherwise.
#[test]
fn an_old_unit_is_refused_when_io_needs_version_4() {
    for (homing, named) in [(true, 3), (false, 1)] {
        let (mut bus, mut unit) = setup_io(homing, io_map());
        bus.enable();
        let mut fb = CycleFeedback::default();
        let cmd = CycleCommand::default();
        let mut versions = Vec::new();
        let e = loop {
            if let Err(e) = bus.cycle(&cmd, &mut fb) {
                break e;
            }
            let req = unit
                .answer_with(|r| {
                    let home = r.home.map(|_| HomeStatus::default());
                    (r.version() < 4).then_some(Reply {
                        home,
                        ..v1_reply(r, 0)
                    })
                })
                .unwrap();
            if req.version() < 4 {
                versions.push(req.version());
                assert_eq!(req.axis[0].controlword, cw::DISABLE_VOLTAGE);
            }
            assert!(versions.len() < 10, "no refusal: {versions:?}");
        };
        assert_eq!(
            (e.reason, e.reason.code()),
            (
                FaultReason::ProtocolVersion {
                    drive: named,
                    needed: 4
                },
                "protocol_version"
            ),
            "{versions:?}"
        );
    }
}

#[test]
fn an_io_bit_beyond_the_word_is_refused_with_its_code() {
    let mut io = io_map();
    io.inputs.push(IoPoint::Serial { bit: 64 });
    let cfg = SerialConfig {
        io,
        ..SerialConfig::new("mem", vec![SerialAxis::new(1, 1.0)])
    };
    let e = SerialBus::new(MemPort::default(), cfg).err().unwrap();
    assert_eq!(e.code(), "serial_io_bit");
}
