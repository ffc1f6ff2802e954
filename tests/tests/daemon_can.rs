//! The daemon (its pipeline and RT core in the single-threaded harness, virtual time) with its CANopen master on an in-memory
//! bus of simulated CiA 402 drives (`sim::can_node`): the configuration the daemon builds from
//! `[bus] kind = "can"`, deterministic and without vcan. Issue #23: drives standing away from
//! 0 are enabled without a target jump; a drive that never boots is named by the bus before
//! the daemon's enabling window; a program runs and a shutdown (the SIGTERM path) leaves every
//! drive switched off, unwatched and without a fault.

use std::collections::VecDeque;
use std::path::Path;
use std::sync::{Arc, Mutex};

use daemon::runtime::buses::{BusConfig, can_config};
use daemon::runtime::clock::SimClock;
use daemon::runtime::config::Config;
use daemon::runtime::harness::{Harness, JobEnd};
use daemon::runtime::rt::MachineState;
use hal::FaultReason;
use hal::canopen::pdo::Rpdo;
use hal::canopen::{CanOpenMaster, CanPort, Frame, PortError, RxEvent, nmt};
use hal::cia402::PowerState;
use sim::SimDriveParams;
use sim::can_node::CanNode;
use sim::cia402_drive::Cia402Drive;

const INC_PER_MM: f64 = 10_000.0;

/// The simulated drives and what went over the bus; shared with the test.
#[derive(Default)]
struct Bus {
    nodes: Vec<CanNode>,
    now_ms: u64,
    to_master: VecDeque<Frame>,
    /// Every frame the master sent.
    sent: Vec<Frame>,
    /// Every frame the drives sent.
    received: Vec<Frame>,
    /// The bus period `[bus] cycle_ms` (0: the default 4 ms).
    cycle_ms: u64,
}

impl Bus {
    /// The drives see one bus period pass (4 ms by default; heartbeats, their watch on the
    /// master's).
    fn pass_4ms(&mut self) {
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
struct Port(Arc<Mutex<Bus>>);

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

/// A daemon with axes X, Y, Z on CAN nodes 1..3 whose drives stand at `start_mm`.
fn daemon(start_mm: [f64; 3], silent: Option<usize>, bus_keys: &str) -> (Harness, Arc<Mutex<Bus>>) {
    let mut toml = String::new();
    for (i, name) in ['X', 'Y', 'Z'].iter().enumerate() {
        toml.push_str(&format!(
            "[[axes]]\nname = '{name}'\nnode_id = {}\nincrements_per_mm = {INC_PER_MM}\n\n",
            i + 1
        ));
    }
    toml.push_str("[bus]\nkind = 'can'\ninterface = 'mem0'\nfollowing_window_mm = 5\n");
    toml.push_str(bus_keys);
    let mut cfg = Config::parse(&toml, Path::new("can.toml")).unwrap();
    let base = tests::test_config();
    cfg.storage = base.storage;
    cfg.rt = base.rt;
    let BusConfig::Can(can) = &cfg.bus else {
        panic!("{:?}", cfg.bus)
    };
    let master_cfg = can_config(can, &cfg.axes);
    let mut nodes: Vec<CanNode> = start_mm
        .iter()
        .enumerate()
        .map(|(i, &mm)| {
            let drive = Cia402Drive::new(SimDriveParams::default(), INC_PER_MM, mm);
            CanNode::new(i as u8 + 1, drive)
        })
        .collect();
    if let Some(k) = silent {
        nodes[k].inject.silent = true;
    }
    let bus = Arc::new(Mutex::new(Bus {
        nodes,
        cycle_ms: cfg.bus.cycle_ms() as u64,
        ..Bus::default()
    }));
    let master = CanOpenMaster::new(Port(bus.clone()), "mem0", master_cfg).unwrap();
    let h = Harness::new(cfg, Box::new(master), SimClock::exact()).unwrap();
    (h, bus)
}

fn rpdo_targets(sent: &[Frame], node: u8) -> Vec<i32> {
    sent.iter()
        .filter(|f| f.id == 0x200 + u16::from(node))
        .map(|f| Rpdo::decode(f.payload()).unwrap().target_increments)
        .collect()
}

#[test]
fn drives_away_from_zero_enable_without_a_jump_and_shut_down_switched_off() {
    let start = [25.0, -40.0, 7.5];
    let (mut h, bus) = daemon(start, None, "");
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    // The commanded position takes over the drives' on the tick after enabling ends.
    let s = h.step();
    for (i, &mm) in start.iter().enumerate() {
        assert!((s.commanded[i] - mm).abs() < 1e-3, "{:?}", s.commanded);
    }
    // One tick's travel at the axis limit: 12000 mm/min × 4 ms × 10000 increments/mm.
    let max_step = 200.0 * 0.004 * INC_PER_MM;
    {
        let b = bus.lock().unwrap();
        for node in 1..=3u8 {
            let t = rpdo_targets(&b.sent, node);
            assert_eq!(t[0], (start[usize::from(node) - 1] * INC_PER_MM) as i32);
            let step = t.windows(2).map(|w| (w[1] - w[0]).abs()).max().unwrap();
            assert!(f64::from(step) <= max_step, "node {node}: step {step}");
        }
    }

    // A program on the daemon's pipeline and RT core, then the SIGTERM path.
    let end = h
        .run_program("G90 G1 X27 Y-38 Z8 F3000\n", 100_000)
        .unwrap();
    assert_eq!(end, JobEnd::Finished);
    h.shut_down(100_000).unwrap();

    let mut b = bus.lock().unwrap();
    let sent = b.sent.len();
    // Long after the daemon ended, no drive has faulted for want of its heartbeat.
    for _ in 0..1000 {
        b.pass_4ms();
    }
    for (n, want) in b.nodes.iter().zip([27.0, -38.0, 8.0]) {
        assert_eq!(
            n.drive.state(),
            PowerState::SwitchOnDisabled,
            "node {}",
            n.id
        );
        assert_eq!(n.drive.error_code(), 0, "node {}", n.id);
        assert_eq!(n.consumer(), 0, "node {}", n.id);
        assert_eq!(n.nmt_state(), nmt::state::PRE_OPERATIONAL, "node {}", n.id);
        assert!((n.drive.position_mm() - want).abs() < 1e-3, "node {}", n.id);
    }
    assert!(
        !b.received
            .iter()
            .any(|f| f.id & 0x780 == 0x080 && f.id != 0x080 && f.data[..2] != [0, 0]),
        "no EMCY"
    );
    assert_eq!(b.sent.len(), sent);
}

/// A drive that never boots, with a boot timeout (3 × 12 s) longer than the daemon's former
/// fixed 10 s enabling window: the bus names it (axis Y, node 2, no boot-up) before the
/// daemon's window, which now derives from the bus's deadline, could end with an alarm that
/// names no drive.
#[test]
fn a_drive_that_never_boots_is_named_in_the_alarm() {
    let (mut h, _bus) = daemon([0.0; 3], Some(1), "boot_timeout_ms = 12000\n");
    let f = h
        .wait_state(MachineState::Fault, 100_000)
        .unwrap()
        .fault
        .unwrap();
    assert_eq!(
        (f.axis, f.node, f.reason),
        (Some(1), Some(2), FaultReason::NoBootUp)
    );
}

/// Values the master wrote to `index`:`sub` of `node` by expedited SDO download.
fn sdo_writes(sent: &[Frame], node: u8, index: u16, sub: u8) -> Vec<u32> {
    sent.iter()
        .filter(|f| f.id == 0x600 + u16::from(node) && f.data[0] & 0xE0 == 0x20)
        .filter(|f| u16::from_le_bytes([f.data[1], f.data[2]]) == index && f.data[3] == sub)
        .map(|f| u32::from_le_bytes([f.data[4], f.data[5], f.data[6], f.data[7]]))
        .collect()
}

/// `[bus] cycle_ms = 2`: the drives are told 0x60C2 = 2 × 10⁻³ s and 0x1006 = 2000 µs, one
/// SYNC goes out per 2 ms tick, the drives (away from 0) follow a program to its end with no
/// target step beyond one 2 ms period's travel at the axis limit, and shut down switched off.
#[test]
fn a_2ms_bus_cycle_reaches_the_drives_and_they_follow() {
    let start = [25.0, -40.0, 7.5];
    let (mut h, bus) = daemon(start, None, "cycle_ms = 2\n");
    h.wait_state(MachineState::Idle, 20_000).unwrap();
    assert_eq!(h.snapshot().cycle_ns, 2_000_000);
    let end = h
        .run_program("G90 G1 X27 Y-38 Z8 F3000\nG0 X20 Y-30 Z0\n", 200_000)
        .unwrap();
    assert_eq!(end, JobEnd::Finished);
    // The drives settle (1 s).
    for _ in 0..500 {
        h.step();
    }
    let s = h.snapshot();
    for (i, want) in [20.0, -30.0, 0.0].into_iter().enumerate() {
        assert!((s.actual[i] - want).abs() < 1e-3, "{:?}", s.actual);
    }
    {
        let b = bus.lock().unwrap();
        for node in 1..=3u8 {
            // 0x60C2: 2 × 10^-3 s (sub 1 the value, sub 2 the exponent -3); 0x1006 in µs.
            for (index, sub, want) in [
                (0x60C2, 1, 2),
                (0x60C2, 2, u32::from((-3i8) as u8)),
                (0x1006, 0, 2000),
            ] {
                let v = sdo_writes(&b.sent, node, index, sub);
                assert!(
                    !v.is_empty() && v.iter().all(|&x| x == want),
                    "node {node} {index:04X}:{sub}: {v:?}"
                );
            }
            // One 2 ms period's travel at the axis limit (12000 mm/min).
            let max_step = 200.0 * 0.002 * INC_PER_MM;
            let t = rpdo_targets(&b.sent, node);
            let step = t.windows(2).map(|w| (w[1] - w[0]).abs()).max().unwrap();
            assert!(f64::from(step) <= max_step, "node {node}: step {step}");
            assert!(step > 0);
        }
        // One SYNC per tick: the drives' time (2 ms per tick) and the SYNC count agree.
        let syncs = b.sent.iter().filter(|f| f.id == 0x080).count() as u64;
        assert!(
            syncs > 0 && syncs <= b.now_ms / 2,
            "{syncs} SYNCs in {} ms",
            b.now_ms
        );
    }
    h.shut_down(100_000).unwrap();
    let b = bus.lock().unwrap();
    for n in &b.nodes {
        assert_eq!(
            n.drive.state(),
            PowerState::SwitchOnDisabled,
            "node {}",
            n.id
        );
        assert_eq!(n.drive.error_code(), 0, "node {}", n.id);
    }
}
