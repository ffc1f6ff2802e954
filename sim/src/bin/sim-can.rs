//! `sim-can --iface vcan0 --node 1 [--node 2 ...]`: simulated CiA 402 drives on a SocketCAN
//! interface, one process for one or several nodes. Each node is a position drive (CSP) or,
//! when the master sets it up in velocity mode (CSV), a spindle drive that ramps at
//! `--ramp-rpm-s` with `--units-per-rpm`. Fault injection through stdin (see
//! `sim::control`). Prints `sim-can ready` once listening.

use std::io::Write;
use std::time::{Duration, Instant};

use hal::canopen::{CanPort, RxEvent, SocketCanPort};
use sim::can_node::CanNode;
use sim::control::{self, Command, SimArgs};

fn main() {
    let args = match SimArgs::parse(std::env::args().skip(1)) {
        Ok(a) if !a.nodes.is_empty() => a,
        Ok(_) => fail("give at least one --node"),
        Err(e) => fail(&e.to_string()),
    };
    let mut port = SocketCanPort::open(&args.iface).unwrap_or_else(|e| fail(&e.to_string()));
    let mut nodes: Vec<CanNode> = args
        .nodes
        .iter()
        .map(|&id| CanNode::new(id, args.drive()))
        .collect();
    let commands = control::stdin_commands();
    let start = Instant::now();
    let mut out = Vec::new();
    println!("sim-can ready on {} nodes {:?}", args.iface, args.nodes);
    let _ = std::io::stdout().flush();
    loop {
        let now_ms = start.elapsed().as_millis() as u64;
        while let Ok(c) = commands.try_recv() {
            let pick = |n: &CanNode, which: Option<u8>| which.is_none_or(|w| w == n.id);
            for n in &mut nodes {
                match c {
                    Command::Heartbeat(on, w) if pick(n, w) => n.inject.drop_heartbeat = !on,
                    Command::Silent(on, w) if pick(n, w) => n.inject.silent = on,
                    Command::Corrupt(on, w) if pick(n, w) => n.inject.corrupt_pdo = on,
                    Command::Fault(code, w) if pick(n, w) => n.force_fault(code, &mut out),
                    Command::State => println!("{}", n.state_line()),
                    Command::Quit => return,
                    _ => {}
                }
            }
            let _ = std::io::stdout().flush();
            eprintln!("sim-can: {c:?}");
        }
        // Wait briefly for a frame, then take everything already queued.
        let mut next = port.recv_timeout(Duration::from_millis(2));
        loop {
            match next {
                Ok(Some(RxEvent::Frame(f))) => {
                    for n in &mut nodes {
                        n.handle(&f, now_ms, &mut out);
                    }
                }
                Ok(Some(RxEvent::Error { .. })) => {}
                Ok(None) => break,
                Err(e) => fail(&format!("CAN interface {} failed: {e:?}", args.iface)),
            }
            next = port.try_recv();
        }
        for n in &mut nodes {
            n.poll(now_ms, &mut out);
        }
        for f in out.drain(..) {
            // A full queue drops the frame, as a drive on a jammed bus would.
            let _ = port.send(&f);
        }
    }
}

fn fail(msg: &str) -> ! {
    eprintln!("sim-can: {msg}");
    std::process::exit(2)
}
