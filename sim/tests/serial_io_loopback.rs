//! The serial master (`hal::serial::SerialBus`) against the simulated drive unit
//! (`sim::serial_drive`) on an in-memory line, deterministic: each tick the unit answers the
//! request of the tick before, 4 ms later, as a real unit does. Digital I/O of protocol
//! version 4: inputs into the feedback, outputs to the unit, the safe output word and the
//! unit's watchdog, an old unit refused, a link without serial I/O unchanged.

use std::sync::{Arc, Mutex};

use hal::io::{IoBits, IoMap, IoPoint};
use hal::serial::frame::Decoder;
use hal::serial::message::Request;
use hal::serial::{LinkDown, SerialAxis, SerialBus, SerialConfig, SerialError, SerialPort};
use hal::{BusFault, CycleCommand, CycleFeedback, DriveBus, DriveState, FaultReason};
use sim::SimDriveParams;
use sim::cia402_drive::Cia402Drive;
use sim::serial_drive::{IoWords, SerialDriveUnit, WATCHDOG_MS};

/// Both directions of the line.
#[derive(Default)]
struct Wire {
    to_unit: Vec<u8>,
    to_master: Vec<u8>,
}

/// The master's end of the line.
#[derive(Clone, Default)]
struct MemPort(Arc<Mutex<Wire>>);

impl SerialPort for MemPort {
    fn try_read(&mut self, buf: &mut [u8]) -> Result<usize, LinkDown> {
        let mut w = self.0.lock().unwrap();
        let n = w.to_master.len().min(buf.len());
        buf[..n].copy_from_slice(&w.to_master[..n]);
        w.to_master.drain(..n);
        Ok(n)
    }

    fn write(&mut self, frame: &[u8]) -> Result<(), LinkDown> {
        self.0.lock().unwrap().to_unit.extend_from_slice(frame);
        Ok(())
    }

    fn close(&mut self) {}

    fn reopen(&mut self) -> Result<(), SerialError> {
        Ok(())
    }
}

/// The bus, the unit, the line between them and the unit's clock.
struct Rig {
    bus: SerialBus<MemPort>,
    unit: SerialDriveUnit,
    line: MemPort,
    now_ms: u64,
    decoder: Decoder,
    /// The protocol version of every request the unit received.
    versions: Vec<u8>,
}

impl Rig {
    fn new(io: IoMap, homing: bool, unit_version: u8) -> Rig {
        let drive = Cia402Drive::new(SimDriveParams::default(), 1000.0, 0.0);
        let mut unit = SerialDriveUnit::new(vec![drive]);
        unit.max_version = unit_version;
        let line = MemPort::default();
        let cfg = SerialConfig {
            io,
            homing,
            ..SerialConfig::new("mem", vec![SerialAxis::new(1, 1000.0)])
        };
        let mut bus = SerialBus::new(line.clone(), cfg).unwrap();
        bus.enable();
        Rig {
            bus,
            unit,
            line,
            now_ms: 0,
            decoder: Decoder::default(),
            versions: Vec::new(),
        }
    }

    /// One tick of the bus, then the unit answers what it was sent.
    fn tick(&mut self, cmd: &CycleCommand) -> (Result<(), BusFault>, CycleFeedback) {
        let mut fb = CycleFeedback::default();
        let r = self.bus.cycle(cmd, &mut fb);
        self.now_ms += 4;
        let bytes = std::mem::take(&mut self.line.0.lock().unwrap().to_unit);
        let versions = &mut self.versions;
        self.decoder.feed(&bytes, |f| {
            if let Some(req) = f.ok().and_then(Request::decode) {
                versions.push(req.version());
            }
        });
        let mut out = Vec::new();
        self.unit.poll(self.now_ms);
        self.unit.on_bytes(&bytes, self.now_ms, &mut out);
        self.line
            .0
            .lock()
            .unwrap()
            .to_master
            .extend_from_slice(&out);
        (r, fb)
    }
}

/// Inputs 0 and 2 on the unit's bits 3 and 62 (input 1 is the simulated machine's); outputs
/// 0 and 1 on its bits 7 and 0, output 1 on when the link is lost.
fn io_map() -> IoMap {
    IoMap {
        inputs: vec![
            IoPoint::Serial { bit: 3 },
            IoPoint::Sim,
            IoPoint::Serial { bit: 62 },
        ],
        outputs: vec![IoPoint::Serial { bit: 7 }, IoPoint::Serial { bit: 0 }],
        safe_outputs: IoBits(0b10),
    }
}

fn outputs(bits: u64) -> CycleCommand {
    CycleCommand {
        outputs: IoBits(bits),
        ..CycleCommand::default()
    }
}

#[test]
fn inputs_arrive_outputs_reach_the_unit_and_the_drive_enables() {
    let mut rig = Rig::new(io_map(), false, 4);
    let io: IoWords = rig.unit.io.clone();
    io.set_inputs(1 << 3 | 1 << 62 | 1 << 10);
    let mut fb = CycleFeedback::default();
    for _ in 0..20 {
        let (r, f) = rig.tick(&outputs(0b01));
        r.unwrap();
        fb = f;
    }
    assert_eq!(fb.axes[0].state, DriveState::Operational);
    assert_eq!(fb.inputs, IoBits(0b101));
    assert_eq!(io.outputs(), 1 << 7);
    assert_eq!(
        io.safe_outputs(),
        1 << 0,
        "the safe word, in the unit's bits"
    );
    assert!(rig.versions.iter().all(|&v| v == 4), "{:?}", rig.versions);

    io.set_input(62, false);
    rig.tick(&outputs(0b10)).0.unwrap();
    let (r, fb) = rig.tick(&outputs(0b10));
    r.unwrap();
    assert_eq!(fb.inputs, IoBits(0b001));
    assert_eq!(io.outputs(), 1 << 0);
}

#[test]
fn the_units_watchdog_falls_to_the_safe_word_when_the_master_stops() {
    let mut rig = Rig::new(io_map(), false, 4);
    let io = rig.unit.io.clone();
    for _ in 0..20 {
        rig.tick(&outputs(0b01)).0.unwrap();
    }
    assert_eq!(io.outputs(), 1 << 7);
    // The master stops: nothing arrives any more.
    let last = rig.now_ms;
    rig.unit.poll(last + WATCHDOG_MS);
    assert_eq!(io.outputs(), 1 << 7, "within the watchdog time");
    rig.unit.poll(last + WATCHDOG_MS + 1);
    assert!(io.is_fallen());
    assert_eq!(io.outputs(), 1 << 0);
    assert_eq!(
        rig.unit.drives[0].error_code(),
        0x8130,
        "the drive faulted too"
    );
}

#[test]
fn a_unit_of_version_3_is_refused_when_io_is_configured() {
    for homing in [false, true] {
        let mut rig = Rig::new(io_map(), homing, 3);
        let io = rig.unit.io.clone();
        let e = (0..60)
            .find_map(|_| rig.tick(&outputs(0b11)).0.err())
            .expect("refused");
        let drive = if homing { 3 } else { 1 };
        assert_eq!(e.reason, FaultReason::ProtocolVersion { drive, needed: 4 });
        assert_eq!(e.reason.code(), "protocol_version");
        assert_eq!(io.outputs(), 0, "an old unit's outputs are never written");
        assert!(
            rig.unit.drives[0].statusword() & 0x000F != 0x0007,
            "nothing enabled"
        );
    }
}

#[test]
fn without_serial_io_the_link_speaks_version_1_and_an_old_unit_works() {
    let others = IoMap {
        inputs: vec![IoPoint::Sim],
        outputs: vec![IoPoint::Sim],
        safe_outputs: IoBits(1),
    };
    let mut rig = Rig::new(others, false, 1);
    let mut fb = CycleFeedback::default();
    for _ in 0..20 {
        let (r, f) = rig.tick(&outputs(1));
        r.unwrap();
        fb = f;
    }
    assert_eq!(fb.axes[0].state, DriveState::Operational);
    assert_eq!(fb.inputs, IoBits::NONE);
    assert!(rig.versions.iter().all(|&v| v == 1), "{:?}", rig.versions);
}
