//! `DriveBus::cycle` of the CAN master and of the serial bus must not allocate: the
//! real-time thread calls it. A counting allocator counts this thread's allocations during
//! operational ticks, including fault and reset paths.

use std::collections::VecDeque;
use std::time::Duration;

use hal::canopen::{
    CanOpenConfig, CanOpenMaster, CanPort, Frame, NodeConfig, NodeId, PortError, RxEvent,
};
use hal::serial::{SerialAxis, SerialBus, SerialConfig};
use hal::{CycleCommand, CycleFeedback, DriveBus, DriveState};
use sim::SimDriveParams;
use sim::can_node::CanNode;
use sim::cia401_module::Cia401Module;
use sim::cia402_drive::Cia402Drive;

#[global_allocator]
static ALLOC: alloc_count::Counting = alloc_count::Counting;

use alloc_count::allocations;

/// In-memory bus with every buffer allocated up front.
struct Net {
    nodes: Vec<CanNode>,
    modules: Vec<Cia401Module>,
    now_ms: u64,
    out: Vec<Frame>,
    to_master: VecDeque<Frame>,
}

impl CanPort for Net {
    fn send(&mut self, f: &Frame) -> Result<(), PortError> {
        for n in &mut self.nodes {
            n.handle(f, self.now_ms, &mut self.out);
        }
        for m in &mut self.modules {
            m.handle(f, self.now_ms, &mut self.out);
        }
        self.to_master.extend(self.out.drain(..));
        Ok(())
    }
    fn try_recv(&mut self) -> Result<Option<RxEvent>, PortError> {
        Ok(self.to_master.pop_front().map(RxEvent::Frame))
    }
}

#[test]
fn can_master_cycle_does_not_allocate() {
    let nodes = (1..=3)
        .map(|id| CanNode::new(id, Cia402Drive::new(SimDriveParams::default(), 1000.0, 0.0)))
        .collect();
    let net = Net {
        nodes,
        modules: Vec::new(),
        now_ms: 0,
        out: Vec::with_capacity(256),
        to_master: VecDeque::with_capacity(1024),
    };
    let cfg = CanOpenConfig::new(
        (1..=3)
            .map(|node_id| NodeConfig {
                node_id: NodeId::new(node_id).unwrap(),
                increments_per_mm: 1000.0,
                following_window_increments: Some(10_000),
                max_velocity_mm_s: 200.0,
                homing: None,
            })
            .collect(),
    );
    let mut m = CanOpenMaster::new(net, "mem", cfg).unwrap();
    let mut cmd = CycleCommand::default();
    let mut fb = CycleFeedback::default();
    let tick = |m: &mut CanOpenMaster<Net>, cmd: &CycleCommand, fb: &mut CycleFeedback| {
        let net = m.port_mut();
        net.now_ms += 4;
        for n in &mut net.nodes {
            n.poll(net.now_ms, &mut net.out);
        }
        net.to_master.extend(net.out.drain(..));
        m.cycle(cmd, fb)
    };
    let before = allocations();
    m.enable();
    for _ in 0..200 {
        tick(&mut m, &cmd, &mut fb).unwrap();
    }
    assert!(
        fb.axes[..3]
            .iter()
            .all(|a| a.state == DriveState::Operational)
    );
    for i in 0..500 {
        cmd.positions_mm[0] = f64::from(i) * 0.05;
        tick(&mut m, &cmd, &mut fb).unwrap();
    }
    // A fault and its reset (drive restart through NMT, SDO, enable) allocate nothing either.
    m.port_mut().nodes[1].inject.drop_heartbeat = true;
    let mut faulted = false;
    for _ in 0..300 {
        faulted |= tick(&mut m, &cmd, &mut fb).is_err();
    }
    assert!(faulted);
    m.port_mut().nodes[1].inject.drop_heartbeat = false;
    m.reset();
    for _ in 0..200 {
        let _ = tick(&mut m, &cmd, &mut fb);
    }
    assert!(
        fb.axes[..3]
            .iter()
            .all(|a| a.state == DriveState::Operational)
    );
    assert_eq!(
        allocations() - before,
        0,
        "allocations in cycle/enable/reset"
    );
}

/// One tick of the in-memory bus: the nodes and modules see 4 ms pass, the master cycles.
fn io_tick(
    m: &mut CanOpenMaster<Net>,
    cmd: &CycleCommand,
    fb: &mut CycleFeedback,
) -> Result<(), hal::BusFault> {
    let net = m.port_mut();
    net.now_ms += 4;
    for n in &mut net.nodes {
        n.poll(net.now_ms, &mut net.out);
    }
    for md in &mut net.modules {
        md.poll(net.now_ms, &mut net.out);
    }
    net.to_master.extend(net.out.drain(..));
    m.cycle(cmd, fb)
}

/// The digital I/O (a CiA 401 module, a drive's 0x60FD/0x60FE) adds no allocation to the
/// cycle, including a module's fault and its restart.
#[test]
fn can_master_cycle_with_io_does_not_allocate() {
    use hal::io::{IoBits, IoMap, IoPoint};
    let net = Net {
        nodes: vec![CanNode::new(
            1,
            Cia402Drive::new(SimDriveParams::default(), 1000.0, 0.0),
        )],
        modules: vec![Cia401Module::new(10, 2)],
        now_ms: 0,
        out: Vec::with_capacity(256),
        to_master: VecDeque::with_capacity(1024),
    };
    let mut cfg = CanOpenConfig::new(vec![NodeConfig::new(NodeId::new(1).unwrap(), 1000.0)]);
    let module = |bit| IoPoint::Module { node: 10, bit };
    cfg.io = IoMap {
        inputs: vec![module(0), module(9), IoPoint::Drive { axis: 0, bit: 2 }],
        outputs: vec![module(1), IoPoint::Drive { axis: 0, bit: 0 }],
        safe_outputs: IoBits::NONE,
    };
    let mut m = CanOpenMaster::new(net, "mem", cfg).unwrap();
    let mut cmd = CycleCommand::default();
    let mut fb = CycleFeedback::default();
    let before = allocations();
    m.enable();
    for i in 0..400u64 {
        cmd.outputs = IoBits(i / 7 % 4);
        m.port_mut().modules[0].io.set_input(9, i % 3 == 0);
        io_tick(&mut m, &cmd, &mut fb).unwrap();
    }
    assert_eq!(fb.axes[0].state, DriveState::Operational);
    m.port_mut().modules[0].inject.drop_heartbeat = true;
    let mut faulted = false;
    for _ in 0..300 {
        faulted |= io_tick(&mut m, &cmd, &mut fb).is_err();
    }
    assert!(faulted);
    m.port_mut().modules[0].inject.drop_heartbeat = false;
    m.reset();
    for _ in 0..200 {
        io_tick(&mut m, &cmd, &mut fb).unwrap();
    }
    assert_eq!(allocations() - before, 0, "allocations with I/O");
}

#[test]
fn serial_bus_cycle_does_not_allocate() {
    use serialport::{SerialPort, TTYPort};
    use sim::serial_drive::SerialDriveUnit;
    use std::io::{Read, Write};

    let (mut master, slave) = TTYPort::pair().unwrap();
    master.set_timeout(Duration::from_millis(1)).unwrap();
    let path = slave.name().unwrap();
    // The drive unit answers on another thread (its allocations are not counted).
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let stop_drive = stop.clone();
    let drive = std::thread::spawn(move || {
        let _keep = slave;
        let drives = (0..2)
            .map(|_| Cia402Drive::new(SimDriveParams::default(), 1000.0, 0.0))
            .collect();
        let mut unit = SerialDriveUnit::new(drives);
        let mut buf = [0u8; 512];
        let mut out = Vec::new();
        let mut ms = 0;
        while !stop_drive.load(std::sync::atomic::Ordering::Relaxed) {
            if let Ok(n) = master.read(&mut buf) {
                ms += 4;
                unit.on_bytes(&buf[..n], ms, &mut out);
                master.write_all(&out).unwrap();
                out.clear();
            }
        }
    });
    let mut cfg = SerialConfig::new(
        &path,
        (1..=2)
            .map(|node_id| SerialAxis::new(node_id, 1000.0))
            .collect(),
    );
    // Generous: this test is about allocations, not timing on a loaded machine.
    cfg.reply_timeout_ticks = 250;
    let mut bus = SerialBus::open(cfg).unwrap();
    let mut cmd = CycleCommand::default();
    let mut fb = CycleFeedback::default();
    let before = allocations();
    bus.enable();
    for i in 0..400 {
        std::thread::sleep(Duration::from_millis(2));
        if fb.axes[0].state == DriveState::Operational {
            cmd.positions_mm[0] = f64::from(i) * 0.01;
        }
        bus.cycle(&cmd, &mut fb).unwrap();
    }
    let during = allocations() - before;
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    drive.join().unwrap();
    assert_eq!(fb.axes[0].state, DriveState::Operational);
    assert_eq!(during, 0, "allocations in the serial cycle");
}
