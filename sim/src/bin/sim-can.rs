//! `sim-can --iface vcan0 --node 1 [--node 2 ...] [--io-module 10 ...]`: simulated CiA 402
//! drives and CiA 401 I/O modules on a SocketCAN interface, one process for one or several
//! nodes. Each drive node is a position drive (CSP) or, when the master sets it up in velocity
//! mode (CSV), a spindle drive that ramps at `--ramp-rpm-s` with `--units-per-rpm`. Each
//! `--io-module` is a module with `--io-groups` (8) groups of 8 inputs and of 8 outputs.
//! Fault injection, inputs and outputs through stdin (see `sim::control`). Prints
//! `sim-can ready` once listening.

use std::io::Write;
use std::time::{Duration, Instant};

use hal::canopen::{CanPort, RxEvent, SocketCanPort};
use sim::can_node::CanNode;
use sim::cia401_module::Cia401Module;
use sim::control::{self, Command, SimArgs};

/// The simulated nodes of the process.
struct Nodes {
    drives: Vec<CanNode>,
    modules: Vec<Cia401Module>,
}

fn main() {
    let args = match SimArgs::parse(std::env::args().skip(1)) {
        Ok(a) if !(a.nodes.is_empty() && a.io_modules.is_empty()) => a,
        Ok(_) => fail("give at least one --node or --io-module"),
        Err(e) => fail(&e.to_string()),
    };
    let mut port = SocketCanPort::open(&args.iface).unwrap_or_else(|e| fail(&e.to_string()));
    let mut nodes = Nodes {
        drives: args
            .nodes
            .iter()
            .map(|&id| CanNode::new(id, args.drive()))
            .collect(),
        modules: args
            .io_modules
            .iter()
            .map(|&id| Cia401Module::new(id, args.io_groups))
            .collect(),
    };
    let commands = control::stdin_commands();
    let start = Instant::now();
    let mut out = Vec::new();
    println!(
        "sim-can ready on {} nodes {:?} modules {:?}",
        args.iface, args.nodes, args.io_modules
    );
    let _ = std::io::stdout().flush();
    loop {
        let now_ms = start.elapsed().as_millis() as u64;
        while let Ok(c) = commands.try_recv() {
            if c == Command::Quit {
                return;
            }
            nodes.command(c, &mut out);
            let _ = std::io::stdout().flush();
            eprintln!("sim-can: {c:?}");
        }
        // Wait briefly for a frame, then take everything already queued.
        let mut next = port.recv_timeout(Duration::from_millis(2));
        loop {
            match next {
                Ok(Some(RxEvent::Frame(f))) => nodes.handle(&f, now_ms, &mut out),
                Ok(Some(RxEvent::Error { .. })) => {}
                Ok(None) => break,
                Err(e) => fail(&format!("CAN interface {} failed: {e:?}", args.iface)),
            }
            next = port.try_recv();
        }
        nodes.poll(now_ms, &mut out);
        for f in out.drain(..) {
            // A full queue drops the frame, as a node on a jammed bus would.
            let _ = port.send(&f);
        }
    }
}

impl Nodes {
    fn handle(&mut self, f: &hal::canopen::Frame, now_ms: u64, out: &mut Vec<hal::canopen::Frame>) {
        for n in &mut self.drives {
            n.handle(f, now_ms, out);
        }
        for m in &mut self.modules {
            m.handle(f, now_ms, out);
        }
    }

    fn poll(&mut self, now_ms: u64, out: &mut Vec<hal::canopen::Frame>) {
        for n in &mut self.drives {
            n.poll(now_ms, out);
        }
        for m in &mut self.modules {
            m.poll(now_ms, out);
        }
    }

    /// A line of stdin: fault injection to the nodes it names (all without a node), inputs
    /// set, states and outputs printed.
    fn command(&mut self, c: Command, out: &mut Vec<hal::canopen::Frame>) {
        let pick = |id: u8, which: Option<u8>| which.is_none_or(|w| w == id);
        for n in &mut self.drives {
            match c {
                Command::Heartbeat(on, w) if pick(n.id, w) => n.inject.drop_heartbeat = !on,
                Command::Silent(on, w) if pick(n.id, w) => n.inject.silent = on,
                Command::Corrupt(on, w) if pick(n.id, w) => n.inject.corrupt_pdo = on,
                Command::Fault(code, w) if pick(n.id, w) => n.force_fault(code, out),
                Command::State => println!("{}", n.state_line()),
                Command::Input { node, bit, on } if node == n.id && bit < 32 => {
                    let mask = 1u32 << bit;
                    n.io.inputs = if on {
                        n.io.inputs | mask
                    } else {
                        n.io.inputs & !mask
                    };
                }
                Command::Outputs(node) if node == n.id => {
                    println!("outputs node {node} {:016X}", n.io.outputs);
                }
                _ => {}
            }
        }
        for m in &mut self.modules {
            match c {
                Command::Heartbeat(on, w) if pick(m.id, w) => m.inject.drop_heartbeat = !on,
                Command::Silent(on, w) if pick(m.id, w) => m.inject.silent = on,
                Command::Corrupt(on, w) if pick(m.id, w) => m.inject.corrupt_pdo = on,
                Command::State => println!("{}", m.state_line()),
                Command::Input { node, bit, on } if node == m.id => m.io.set_input(bit, on),
                Command::Outputs(node) if node == m.id => {
                    println!("outputs node {node} {:016X}", m.io.outputs());
                }
                _ => {}
            }
        }
    }
}

fn fail(msg: &str) -> ! {
    eprintln!("sim-can: {msg}");
    std::process::exit(2)
}
