//! Simulated CANopen drives behind an in-memory port, for daemon tests on the CAN bus: the
//! master's port runs on the test's clock (one bus period passes when the master has read
//! every frame), and every frame either way is kept for the test to inspect.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};

use hal::canopen::{CanPort, Frame, PortError, RxEvent};
use sim::can_node::CanNode;

/// The simulated drives and what went over the bus; shared with the test.
#[derive(Default)]
pub struct Bus {
    pub nodes: Vec<CanNode>,
    pub now_ms: u64,
    pub to_master: VecDeque<Frame>,
    /// Every frame the master sent.
    pub sent: Vec<Frame>,
    /// Every frame the drives sent.
    pub received: Vec<Frame>,
    /// The bus period `[bus] cycle_ms` (0: the default 4 ms).
    pub cycle_ms: u64,
}

impl Bus {
    /// The drives see one bus period pass (4 ms by default; heartbeats, their watch on the
    /// master's).
    pub fn pass_4ms(&mut self) {
        self.now_ms += if self.cycle_ms == 0 { 4 } else { self.cycle_ms };
        let mut out = Vec::new();
        for n in &mut self.nodes {
            n.poll(self.now_ms, &mut out);
        }
        self.received.extend(&out);
        self.to_master.extend(out);
    }
}

/// The master's port: time passes once per tick, when the master has read everything.
pub struct Port(pub Arc<Mutex<Bus>>);

impl CanPort for Port {
    fn send(&mut self, f: &Frame) -> Result<(), PortError> {
        let mut b = self.0.lock().unwrap();
        b.sent.push(*f);
        let (now, mut out) = (b.now_ms, Vec::new());
        for n in &mut b.nodes {
            n.handle(f, now, &mut out);
        }
        b.received.extend(&out);
        b.to_master.extend(out);
        Ok(())
    }
    fn try_recv(&mut self) -> Result<Option<RxEvent>, PortError> {
        let mut b = self.0.lock().unwrap();
        match b.to_master.pop_front() {
            Some(f) => Ok(Some(RxEvent::Frame(f))),
            None => {
                b.pass_4ms();
                Ok(None)
            }
        }
    }
}
