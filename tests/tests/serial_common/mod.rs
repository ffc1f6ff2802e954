//! The daemon's serial bus on a pseudo-terminal whose other end is served, in the same thread
//! between ticks, by the simulated drive unit (`sim::serial_drive`). No second thread and no
//! wall clock: each tick the unit answers the request of the tick before, as a real unit
//! does. For tests that run the daemon in the single-threaded harness over serial.

// Each test binary that includes this module uses part of it.
#![allow(dead_code)]

use std::io::{Read, Write};
use std::sync::{Arc, Mutex};

use hal::serial::frame::Decoder;
use hal::serial::message::Request;
use hal::{BusFault, CycleCommand, CycleFeedback, DriveBus};
use serialport::{SerialPort, TTYPort};
use sim::serial_drive::SerialDriveUnit;

/// The drive unit's end of the line, and what it was sent.
pub struct UnitSide {
    pub unit: SerialDriveUnit,
    master: TTYPort,
    /// The controller side, kept open to see when a reply has reached it.
    slave: TTYPort,
    pub now_ms: u64,
    out: Vec<u8>,
    decoder: Decoder,
    /// Every request the unit received, in order.
    pub requests: Vec<Request>,
}

impl UnitSide {
    /// A pty pair with `unit` on its master side; the controller opens the returned path.
    pub fn open(unit: SerialDriveUnit) -> (Arc<Mutex<UnitSide>>, String) {
        let (master, slave) = TTYPort::pair().unwrap();
        let path = slave.name().unwrap();
        let side = UnitSide {
            unit,
            master,
            slave,
            now_ms: 0,
            out: Vec::new(),
            decoder: Decoder::default(),
            requests: Vec::new(),
        };
        (Arc::new(Mutex::new(side)), path)
    }

    /// 4 ms pass; the unit reads what the controller sent and answers it.
    pub fn serve(&mut self) {
        self.now_ms += 4;
        let n = self.master.bytes_to_read().unwrap() as usize;
        let mut bytes = vec![0u8; n];
        self.master.read_exact(&mut bytes).unwrap();
        let requests = &mut self.requests;
        self.decoder.feed(&bytes, |r| {
            if let Some(req) = r.ok().and_then(Request::decode) {
                requests.push(req);
            }
        });
        self.out.clear();
        self.unit.poll(self.now_ms);
        self.unit.on_bytes(&bytes, self.now_ms, &mut self.out);
        self.master.write_all(&self.out).unwrap();
        self.master.flush().unwrap();
        // The pty hands bytes over asynchronously: wait (a bounded number of yields, not a
        // time) until the controller's side holds the whole answer, as a wire would.
        wait_for(|| self.slave.bytes_to_read().unwrap() as usize >= self.out.len());
    }

    /// `ms` pass with nobody talking to the unit (its watchdog runs).
    pub fn idle(&mut self, ms: u64) {
        self.now_ms += ms;
        self.unit.poll(self.now_ms);
    }
}

/// A serial bus (the one the daemon builds) and the unit it talks to, as one [`DriveBus`].
pub struct Line {
    pub bus: Box<dyn DriveBus>,
    pub side: Arc<Mutex<UnitSide>>,
}

impl DriveBus for Line {
    daemon::delegate_drive_bus!(bus: name, axes, has_spindle, enable, reset, enable_timeout_ticks,
        shutdown, is_shut_down, safe_state, supports_homing, home_switch, set_home);

    fn cycle(&mut self, cmd: &CycleCommand, fb: &mut CycleFeedback) -> Result<(), BusFault> {
        let mut side = self.side.lock().unwrap();
        side.serve();
        let r = self.bus.cycle(cmd, fb);
        // The bus sends a request every tick: let it arrive before the next tick.
        wait_for(|| side.master.bytes_to_read().unwrap() > 0);
        r
    }
}

/// Yields until `ready` (bounded: a pty that never delivers fails the test).
pub fn wait_for(mut ready: impl FnMut() -> bool) {
    for _ in 0..10_000_000 {
        if ready() {
            return;
        }
        std::thread::yield_now();
    }
    panic!("the pty never delivered");
}
