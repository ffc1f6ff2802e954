//! The CANopen master against simulated drive nodes and CiA 401 I/O modules on an in-memory
//! bus: start-up, CSP motion, every fault path, enabling from anywhere, orderly shutdown and
//! resets, digital I/O, in virtual time (4 ms per tick unless a test sets the cycle).

use std::collections::VecDeque;

use hal::canopen::pdo::Rpdo;
use hal::canopen::{
    CanOpenConfig, CanOpenMaster, CanPort, Frame, NodeConfig, NodeId, PortError, RxEvent,
    ShutdownMode,
};
use hal::cia402::PowerState;
use hal::io::{IoBits, IoMap, IoPoint};
use hal::{BusFault, CycleCommand, CycleFeedback, DriveBus, DriveState, FaultReason};
use sim::SimDriveParams;
use sim::can_node::CanNode;
use sim::cia401_module::Cia401Module;
use sim::cia402_drive::Cia402Drive;

const INC_PER_MM: f64 = 1000.0;

/// The bus: what the master sends reaches every node at once; answers queue for the master.
struct Net {
    nodes: Vec<CanNode>,
    /// CiA 401 I/O modules beside the drives.
    modules: Vec<Cia401Module>,
    now_ms: u64,
    tick: u64,
    to_master: VecDeque<Frame>,
    /// Every frame the master sent, with the tick.
    log: Vec<(u64, Frame)>,
    /// Every frame the nodes sent, with the tick.
    from_nodes: Vec<(u64, Frame)>,
    /// Index of a node that does not hear the master's heartbeat (a broken receive path).
    deaf_to_heartbeat: Option<usize>,
}

impl Net {
    fn new(nodes: Vec<CanNode>) -> Net {
        Net {
            nodes,
            modules: Vec::new(),
            now_ms: 0,
            tick: 0,
            to_master: VecDeque::new(),
            log: Vec::new(),
            from_nodes: Vec::new(),
            deaf_to_heartbeat: None,
        }
    }

    fn deliver(&mut self, out: Vec<Frame>) {
        let t = self.tick;
        self.from_nodes.extend(out.iter().map(|f| (t, *f)));
        self.to_master.extend(out);
    }
}

impl CanPort for Net {
    fn send(&mut self, f: &Frame) -> Result<(), PortError> {
        self.log.push((self.tick, *f));
        let mut out = Vec::new();
        for (k, n) in self.nodes.iter_mut().enumerate() {
            if f.id == 0x77F && self.deaf_to_heartbeat == Some(k) {
                continue;
            }
            n.handle(f, self.now_ms, &mut out);
        }
        for m in &mut self.modules {
            m.handle(f, self.now_ms, &mut out);
        }
        self.deliver(out);
        Ok(())
    }
    fn try_recv(&mut self) -> Result<Option<RxEvent>, PortError> {
        Ok(self.to_master.pop_front().map(RxEvent::Frame))
    }
}

struct Rig {
    m: CanOpenMaster<Net>,
    cmd: CycleCommand,
    fb: CycleFeedback,
    cycle_ms: u64,
}

impl Rig {
    fn new(ids: &[u8]) -> Rig {
        Rig::with(ids, &[0.0; 6], 4)
    }

    /// Drives `ids` standing at `start_mm`, bus cycle `cycle_ms`.
    fn with(ids: &[u8], start_mm: &[f64], cycle_ms: u32) -> Rig {
        Rig::build(ids, start_mm, cycle_ms, ShutdownMode::Disable)
    }

    fn build(ids: &[u8], start_mm: &[f64], cycle_ms: u32, shutdown: ShutdownMode) -> Rig {
        Rig::build_io(ids, start_mm, cycle_ms, shutdown, &[], IoMap::default())
    }

    fn build_io(
        ids: &[u8],
        start_mm: &[f64],
        cycle_ms: u32,
        shutdown: ShutdownMode,
        modules: &[u8],
        io: IoMap,
    ) -> Rig {
        let nodes = ids
            .iter()
            .zip(start_mm)
            .map(|(&id, &mm)| {
                CanNode::new(
                    id,
                    Cia402Drive::new(SimDriveParams::default(), INC_PER_MM, mm),
                )
            })
            .collect();
        let mut net = Net::new(nodes);
        net.modules = modules.iter().map(|&id| Cia401Module::new(id, 2)).collect();
        let mut cfg = CanOpenConfig::new(
            ids.iter()
                .map(|&node_id| NodeConfig {
                    node_id: NodeId::new(node_id).unwrap(),
                    increments_per_mm: INC_PER_MM,
                    following_window_increments: Some(10_000),
                    max_velocity_mm_s: 200.0,
                    homing: None,
                })
                .collect(),
        );
        cfg.cycle = std::time::Duration::from_millis(u64::from(cycle_ms));
        cfg.shutdown = shutdown;
        cfg.io = io;
        let mut m = CanOpenMaster::new(net, "mem", cfg).unwrap();
        m.enable();
        Rig {
            m,
            cmd: CycleCommand::default(),
            fb: CycleFeedback::default(),
            cycle_ms: u64::from(cycle_ms),
        }
    }

    fn net(&mut self) -> &mut Net {
        self.m.port_mut()
    }

    /// One tick (4 ms unless set): nodes see time pass, then the master cycles.
    fn tick(&mut self) -> Result<(), BusFault> {
        self.pass_time();
        self.m.cycle(&self.cmd, &mut self.fb)
    }

    /// The nodes see one tick pass (heartbeats, their watch on the master's).
    fn pass_time(&mut self) {
        let cycle_ms = self.cycle_ms;
        let net = self.m.port_mut();
        net.now_ms += cycle_ms;
        net.tick += 1;
        let mut out = Vec::new();
        for n in &mut net.nodes {
            n.poll(net.now_ms, &mut out);
        }
        for m in &mut net.modules {
            m.poll(net.now_ms, &mut out);
        }
        net.deliver(out);
    }

    fn until_operational(&mut self) -> usize {
        for t in 0..1000 {
            self.tick().expect("no fault during start-up");
            let n = self.m.axes();
            if self.fb.axes[..n]
                .iter()
                .all(|a| a.state == DriveState::Operational)
            {
                return t;
            }
        }
        panic!("not operational after 4 s: {:?}", self.fb);
    }

    fn until_fault(&mut self, max_ticks: usize) -> (usize, BusFault) {
        for t in 0..max_ticks {
            if let Err(e) = self.tick() {
                return (t, e);
            }
        }
        panic!("no fault within {max_ticks} ticks");
    }
}

#[test]
fn starts_up_moves_and_keeps_the_traffic_pattern() {
    let mut r = Rig::new(&[1, 2, 3]);
    let t = r.until_operational();
    assert!(t < 100, "start-up took {t} ticks");
    // Ramp X to 20 mm at 100 mm/s; Y and Z hold.
    for i in 1..=50 {
        r.cmd.positions_mm[0] = i as f64 * 0.4;
        r.tick().unwrap();
        if i == 40 {
            // Steady lag v/Kv = 3.3 mm plus two ticks of bus delay (0.8 mm).
            let lag = 16.0 - r.fb.axes[0].position_mm;
            assert!((3.0..5.0).contains(&lag), "drive lags its setpoint: {lag}");
        }
    }
    for _ in 0..300 {
        r.tick().unwrap();
    }
    assert!(
        (r.fb.axes[0].position_mm - 20.0).abs() < 0.002,
        "{:?}",
        r.fb.axes[0]
    );
    assert!(r.fb.axes[1].position_mm.abs() < 1e-9);

    // Steady state: every tick is SYNC then one RPDO per node, in node order.
    let log = &r.net().log;
    let last_tick = log.last().unwrap().0;
    for tick in last_tick - 100..last_tick {
        let ids: Vec<u16> = log
            .iter()
            .filter(|(t, f)| *t == tick && f.id != 0x77F)
            .map(|(_, f)| f.id)
            .collect();
        assert_eq!(ids, [0x080, 0x201, 0x202, 0x203], "tick {tick}");
    }
}

#[test]
fn lost_heartbeat_names_axis_and_node_and_reset_restarts_the_drive() {
    let mut r = Rig::new(&[1, 2, 3]);
    r.until_operational();
    r.net().nodes[1].inject.drop_heartbeat = true;
    let (t, e) = r.until_fault(500);
    assert_eq!(
        e,
        BusFault {
            axis: Some(1),
            node: Some(2),
            reason: FaultReason::HeartbeatLost
        }
    );
    // 500 ms timeout, heartbeat every 100 ms: between 100 and 150 ticks.
    assert!((95..=160).contains(&t), "after {t} ticks");
    assert_eq!(
        r.fb.axes[0].state,
        DriveState::Operational,
        "others keep running"
    );
    r.net().nodes[1].inject.drop_heartbeat = false;
    r.m.reset();
    r.until_operational();
}

#[test]
fn silent_drives_time_out_and_short_tpdos_are_a_mapping_fault() {
    for corrupt in [false, true] {
        let mut r = Rig::new(&[5]);
        r.until_operational();
        if corrupt {
            r.net().nodes[0].inject.corrupt_pdo = true;
        } else {
            r.net().nodes[0].inject.silent = true;
        }
        let (t, e) = r.until_fault(100);
        let reason = if corrupt {
            // A 3-byte TPDO where the mapping gives 6: named at the first one.
            assert_eq!(t, 1);
            FaultReason::PdoLength {
                cob_id: 0x185,
                len: 3,
                expected: 6,
            }
        } else {
            // The first tick still reads the last answer; 25 missing ticks are tolerated.
            assert_eq!(t, 26);
            FaultReason::Timeout
        };
        assert_eq!(e.reason, reason);
        assert_eq!(r.fb.axes[0].state, DriveState::Fault);
        // Fault persists until reset; recovery after the drive answers again.
        assert_eq!(r.until_fault(1).1.reason, reason);
        let n = &mut r.net().nodes[0];
        n.inject = Default::default();
        r.m.reset();
        r.until_operational();
    }
}

#[test]
fn drive_fault_emcy_and_following_error() {
    let mut r = Rig::new(&[1, 2]);
    r.until_operational();
    let mut out = Vec::new();
    r.net().nodes[0].force_fault(0x2310, &mut out);
    r.net().to_master.extend(out);
    let (_, e) = r.until_fault(5);
    assert_eq!(e.reason, FaultReason::DriveFault { code: 0x2310 });
    assert_eq!((e.axis, e.node), (Some(0), Some(1)));
    r.m.reset();
    r.until_operational();

    // A setpoint jump beyond the 10 mm window (0x6065 = 10000 increments).
    r.cmd.positions_mm[1] = 50.0;
    let (_, e) = r.until_fault(5);
    assert_eq!(e.reason, FaultReason::FollowingError);
    assert_eq!((e.axis, e.node), (Some(1), Some(2)));
    assert!(e.to_string().contains("following error"), "{e}");
    r.cmd.positions_mm[1] = r.fb.axes[1].position_mm;
    r.m.reset();
    r.until_operational();
}

#[test]
fn drive_watches_the_master_heartbeat() {
    let mut r = Rig::new(&[1]);
    r.until_operational();
    for _ in 0..50 {
        r.tick().unwrap(); // master heartbeats (every 100 ms) reach the drive
    }
    // The master stops (no cycles): after the consumer time the drive faults itself.
    let net = r.net();
    let mut out = Vec::new();
    for _ in 0..200 {
        net.now_ms += 4;
        net.nodes[0].poll(net.now_ms, &mut out);
    }
    assert!(
        out.iter()
            .any(|f| f.id == 0x81 && f.data[..2] == [0x30, 0x81]),
        "EMCY 8130h expected: {out:?}"
    );
}

/// The spindle drive (CSV, node 5, 10 units per rpm, ramp 1000 rpm/s) next to axis node 1:
/// it is configured and enabled with the axis, its speed follows the setpoint on its ramp,
/// the actual speed comes back, and its faults name the spindle.
#[test]
fn spindle_node_follows_the_speed_setpoint_on_its_ramp() {
    const UNITS_PER_RPM: f64 = 10.0;
    let axis = CanNode::new(
        1,
        Cia402Drive::new(SimDriveParams::default(), INC_PER_MM, 0.0),
    );
    let mut spindle_drive = Cia402Drive::new(SimDriveParams::default(), INC_PER_MM, 0.0);
    spindle_drive.velocity_ramp_units_s2 = 1000.0 * UNITS_PER_RPM;
    let net = Net::new(vec![axis, CanNode::new(5, spindle_drive)]);
    let mut cfg = CanOpenConfig::new(vec![NodeConfig {
        node_id: NodeId::new(1).unwrap(),
        increments_per_mm: INC_PER_MM,
        following_window_increments: Some(10_000),
        max_velocity_mm_s: 200.0,
        homing: None,
    }]);
    cfg.spindle = Some(hal::canopen::SpindleNodeConfig {
        node_id: NodeId::new(5).unwrap(),
        units_per_rpm: UNITS_PER_RPM,
    });
    let mut m = CanOpenMaster::new(net, "mem", cfg).unwrap();
    m.enable();
    let mut rig = Rig {
        m,
        cmd: CycleCommand::default(),
        fb: CycleFeedback::default(),
        cycle_ms: 4,
    };
    rig.until_operational();
    let mut t = 0;
    while rig.fb.spindle_state != DriveState::Operational {
        rig.tick().unwrap();
        t += 1;
        assert!(t < 100, "spindle not operational: {:?}", rig.fb);
    }

    // M3 S800: the speed rises by at most 4 rpm per 4 ms tick and settles at 800.
    rig.cmd.spindle_rpm = 800.0;
    let mut speeds = vec![rig.fb.spindle_rpm];
    for _ in 0..300 {
        rig.tick().unwrap();
        speeds.push(rig.fb.spindle_rpm);
    }
    assert_eq!(*speeds.last().unwrap(), 800.0);
    assert!(
        speeds
            .windows(2)
            .all(|w| w[1] >= w[0] && w[1] - w[0] <= 4.0 + 1e-9),
        "ramp {speeds:?}"
    );
    assert!(speeds.iter().filter(|&&v| v > 0.0 && v < 800.0).count() > 150);
    // The setpoint on the bus: the RPDO of node 5 carries 8000 units (0x60FF).
    let last_rpdo = rig
        .net()
        .log
        .iter()
        .rev()
        .find(|(_, f)| f.id == 0x205)
        .map(|(_, f)| hal::canopen::pdo::Rpdo::decode(f.payload()).unwrap())
        .unwrap();
    assert_eq!(last_rpdo.target_increments, 8000);

    // M4: negative speed.
    rig.cmd.spindle_rpm = -200.0;
    for _ in 0..300 {
        rig.tick().unwrap();
    }
    assert_eq!(rig.fb.spindle_rpm, -200.0);

    // A spindle drive fault stops the machine like an axis fault, naming the spindle.
    let mut out = Vec::new();
    rig.net().nodes[1].force_fault(0x2310, &mut out);
    rig.net().to_master.extend(out);
    let (_, e) = rig.until_fault(5);
    assert_eq!(
        e,
        BusFault {
            axis: Some(hal::SPINDLE_AXIS),
            node: Some(5),
            reason: FaultReason::DriveFault { code: 0x2310 }
        }
    );
    assert_eq!(rig.fb.spindle_state, DriveState::Fault);
    assert_eq!(rig.fb.axes[0].state, DriveState::Operational);
}

/// Controlword and target of every RPDO the master sent to `node`, in order, with the tick.
fn rpdos(log: &[(u64, Frame)], node: u8) -> Vec<(u64, Rpdo)> {
    log.iter()
        .filter(|(_, f)| f.id == 0x200 + u16::from(node))
        .map(|(t, f)| (*t, Rpdo::decode(f.payload()).unwrap()))
        .collect()
}

/// One tick's travel at the axis's speed limit (200 mm/s at 4 ms, 1000 increments/mm).
const MAX_STEP: i64 = 800;

impl Rig {
    /// The daemon's enabling: the commanded positions stay where they were (`cmd`) until
    /// every axis reports Operational, then they are taken from the drives' actual positions.
    fn enable_like_the_daemon(&mut self, max_ticks: usize) {
        let n = self.m.axes();
        for _ in 0..max_ticks {
            self.tick().expect("no fault while enabling");
            if self.fb.axes[..n]
                .iter()
                .all(|a| a.state == DriveState::Operational)
            {
                for i in 0..n {
                    self.cmd.positions_mm[i] = self.fb.axes[i].position_mm;
                }
                return;
            }
        }
        panic!("not operational: {:?}", self.fb);
    }

    /// Largest step between consecutive targets sent to `node`, and its first target.
    fn target_steps(&mut self, node: u8) -> (i64, i32) {
        let r = rpdos(&self.net().log, node);
        let first = r[0].1.target_increments;
        let max = r
            .windows(2)
            .map(|w| {
                (i64::from(w[1].1.target_increments) - i64::from(w[0].1.target_increments)).abs()
            })
            .max()
            .unwrap_or(0);
        (max, first)
    }
}

/// Issue #23, seen 1: drives standing away from 0 while the controller's commanded position
/// is still 0, one drive held back by safe torque off so the others are enabled long before
/// it. Every target equals the drive's own position from the first RPDO on; none steps by
/// more than one tick's travel at the axis limit; nobody faults; then the axes move.
#[test]
fn enable_holds_every_drive_where_it_stands_until_the_command_takes_over() {
    let starts = [25.0, -40.0, 7.5];
    for late in [None, Some(0), Some(1), Some(2)] {
        let mut r = Rig::with(&[1, 2, 3], &starts, 4);
        if let Some(k) = late {
            r.net().nodes[k].drive.sto = true;
        }
        // The others come up and are enabled; the late one stays Switch On Disabled.
        for _ in 0..300 {
            r.tick()
                .expect("no fault while a drive waits for its power stage");
        }
        if let Some(k) = late {
            let n = r.m.axes();
            let up = (0..n).filter(|&i| r.fb.axes[i].state == DriveState::Operational);
            assert_eq!(up.count(), n - 1, "late {k}: {:?}", r.fb);
            r.net().nodes[k].drive.sto = false;
        }
        r.enable_like_the_daemon(200);
        for _ in 0..20 {
            r.tick().unwrap();
        }
        for (k, &mm) in starts.iter().enumerate() {
            let node = k as u8 + 1;
            let (max_step, first) = r.target_steps(node);
            assert_eq!(first, (mm * INC_PER_MM) as i32, "node {node}: first target");
            assert!(
                max_step <= MAX_STEP,
                "late {late:?}, node {node}: step {max_step}"
            );
            assert!(
                (r.fb.axes[k].position_mm - mm).abs() < 1e-3,
                "node {node} stood still"
            );
        }
        // The commanded positions lead now: X moves 2 mm.
        for i in 1..=50 {
            r.cmd.positions_mm[0] = starts[0] + f64::from(i) * 0.04;
            r.tick().unwrap();
        }
        for _ in 0..200 {
            r.tick().unwrap();
        }
        assert!(
            (r.fb.axes[0].position_mm - starts[0] - 2.0).abs() < 1e-3,
            "{:?}",
            r.fb
        );
    }
}

/// The master never sends SYNC or an RPDO before every drive is configured and started.
#[test]
fn sync_and_pdos_start_after_the_configuration_of_every_drive() {
    let mut r = Rig::new(&[1, 2, 3]);
    r.until_operational();
    let log = &r.net().log;
    let pos = |pred: &dyn Fn(&Frame) -> bool| log.iter().position(|(_, f)| pred(f));
    let first_sync = pos(&|f| f.id == 0x080).unwrap();
    let last_sdo = log
        .iter()
        .rposition(|(_, f)| f.id & 0x780 == 0x600)
        .unwrap();
    assert!(
        last_sdo < first_sync,
        "SDO {last_sdo} after SYNC {first_sync}"
    );
    for node in 1..=3u16 {
        let start = pos(&|f| f.id == 0 && f.payload() == [0x01, node as u8]).unwrap();
        let first_rpdo = pos(&|f| f.id == 0x200 + node).unwrap();
        assert!(start < first_sync && first_sync < first_rpdo, "node {node}");
    }
}

/// The CiA 301 remapping order is what the simulated drive insists on: a mapping entry of a
/// valid PDO, a count before the PDO is invalid, or a new COB-ID over a valid one is refused.
#[test]
fn the_simulated_drive_refuses_remapping_out_of_order() {
    use hal::canopen::sdo;
    let mut n = CanNode::new(
        4,
        Cia402Drive::new(SimDriveParams::default(), INC_PER_MM, 0.0),
    );
    let mut out = Vec::new();
    n.poll(0, &mut out);
    let mut write = |index: u16, sub: u8, value: u32, size: u8| {
        let mut out = Vec::new();
        n.handle(&sdo::download(4, index, sub, value, size), 0, &mut out);
        match sdo::parse_response(out[0].payload()).unwrap() {
            sdo::Response::Abort { code, .. } => Err(code),
            _ => Ok(()),
        }
    };
    // Valid COB-ID (as the drive would have from an earlier configuration).
    write(0x1400, 1, 0x204, 4).unwrap();
    assert_eq!(write(0x1400, 1, 0x305, 4), Err(sdo::abort::VALUE_RANGE));
    assert_eq!(write(0x1600, 0, 0, 1), Err(sdo::abort::DEVICE_STATE));
    assert_eq!(
        write(0x1600, 1, 0x6040_0010, 4),
        Err(sdo::abort::DEVICE_STATE)
    );
    // The order the master uses: invalid, count 0, entries, count, valid.
    write(0x1400, 1, 0x8000_0204, 4).unwrap();
    write(0x1600, 0, 0, 1).unwrap();
    write(0x1600, 1, 0x6040_0010, 4).unwrap();
    write(0x1600, 2, 0x607A_0020, 4).unwrap();
    write(0x1600, 0, 2, 1).unwrap();
    assert_eq!(
        write(0x1600, 1, 0x6040_0010, 4),
        Err(sdo::abort::DEVICE_STATE)
    );
    write(0x1400, 1, 0x204, 4).unwrap();
}

/// Issue #23, seen 2: an orderly shutdown walks every drive down 0Fh → 07h → 06h → 00h on
/// its statusword, clears its heartbeat consumer, sends it to pre-operational, then the bus
/// falls silent; long after, no drive has faulted.
#[test]
fn shutdown_leaves_the_drives_switched_off_without_a_fault() {
    let mut r = Rig::with(&[1, 2, 3], &[3.0, 4.0, 5.0], 4);
    r.enable_like_the_daemon(200);
    for _ in 0..50 {
        r.tick().unwrap();
    }
    let before = r.net().log.len();
    r.m.shutdown();
    let mut ticks = 0;
    while !r.m.is_shut_down() {
        r.tick().unwrap();
        ticks += 1;
        assert!(ticks < 500, "shutdown must end by itself");
    }
    let log = r.net().log[before..].to_vec();
    for node in 1..=3u8 {
        let cws: Vec<u16> = rpdos(&log, node)
            .iter()
            .map(|(_, p)| p.controlword)
            .collect();
        let mut walk = cws.clone();
        walk.dedup();
        assert_eq!(walk, [0x07, 0x06, 0x00], "node {node}: {cws:X?}");
        let clear = sdo_write_index(&log, node, 0x1016, 1).expect("0x1016:1 cleared");
        let pre_op = log
            .iter()
            .position(|(_, f)| f.id == 0 && f.payload() == [0x80, node])
            .expect("NMT pre-operational");
        let last_rpdo = log
            .iter()
            .rposition(|(_, f)| f.id == 0x200 + u16::from(node))
            .unwrap();
        assert!(clear < pre_op && last_rpdo < pre_op, "node {node}");
    }
    // After shutdown: nothing more goes out, and the drives, unwatched, stay fault-free.
    let sent = r.net().log.len();
    for _ in 0..500 {
        r.tick().unwrap();
    }
    assert_eq!(r.net().log.len(), sent, "the bus is silent after shutdown");
    for n in &r.net().nodes {
        assert_eq!(n.nmt_state(), hal::canopen::nmt::state::PRE_OPERATIONAL);
        assert_eq!(n.consumer(), 0);
        assert_eq!(
            n.drive.state(),
            PowerState::SwitchOnDisabled,
            "node {}",
            n.id
        );
        assert_eq!(n.drive.error_code(), 0, "node {}", n.id);
    }
    assert!(
        !r.net()
            .from_nodes
            .iter()
            .any(|(_, f)| f.id & 0x780 == 0x080 && f.data[0] != 0),
        "no EMCY"
    );
}

/// With `shutdown = quick_stop` the walk is quick stop (02h), then disable voltage (00h).
#[test]
fn shutdown_by_quick_stop() {
    let mut r = Rig::build(&[1], &[3.0], 4, ShutdownMode::QuickStop);
    r.enable_like_the_daemon(200);
    for _ in 0..10 {
        r.tick().unwrap();
    }
    let before = r.net().log.len();
    r.m.shutdown();
    let mut ticks = 0;
    while !r.m.is_shut_down() {
        r.tick().unwrap();
        ticks += 1;
        assert!(ticks < 500, "shutdown must end by itself");
    }
    let mut cws: Vec<u16> = rpdos(&r.net().log[before..], 1)
        .iter()
        .map(|(_, p)| p.controlword)
        .collect();
    cws.dedup();
    assert_eq!(cws, [0x02, 0x00], "{cws:X?}");
    let n = &r.net().nodes[0];
    assert_eq!(n.drive.state(), PowerState::SwitchOnDisabled);
    assert_eq!(n.consumer(), 0);
}

/// Index in `log` of the SDO write of `index:sub` with value 0 to `node`.
fn sdo_write_index(log: &[(u64, Frame)], node: u8, index: u16, sub: u8) -> Option<usize> {
    use hal::canopen::sdo;
    log.iter().position(|(_, f)| {
        f.id == 0x600 + u16::from(node)
            && matches!(
                sdo::parse_request(f.payload()),
                Ok(sdo::Request::Download { index: i, subindex: s, value: 0, .. }) if i == index && s == sub
            )
    })
}

/// Without the orderly shutdown (SIGKILL, power loss of the controller) the drives' own
/// heartbeat consumer is the safety net: each faults with 8130h and leaves operational.
#[test]
fn without_shutdown_the_drives_heartbeat_consumer_stops_them() {
    let mut r = Rig::new(&[1, 2]);
    r.until_operational();
    for _ in 0..100 {
        r.tick().unwrap();
    }
    for _ in 0..200 {
        r.pass_time(); // the master is gone
    }
    for n in &r.net().nodes {
        assert_eq!(n.drive.error_code(), 0x8130, "node {}", n.id);
        assert_eq!(n.nmt_state(), hal::canopen::nmt::state::PRE_OPERATIONAL);
    }
}

/// Issue #23, seen 3: a drive whose watch on the master's heartbeat fired (EMCY 8130h, it
/// left operational) gets no more RPDOs; a single reset restarts it fully (NMT reset
/// communication, configuration) and walks 06h → 07h → 0Fh on fresh statuswords, from where
/// it stands.
#[test]
fn reset_after_a_heartbeat_consumer_fault_restarts_the_drive_once() {
    let mut r = Rig::with(&[1, 2], &[10.0, -3.0], 4);
    r.enable_like_the_daemon(200);
    for _ in 0..50 {
        r.tick().unwrap(); // the drive's watch starts with the first heartbeat it hears
    }
    r.net().deaf_to_heartbeat = Some(1);
    let (_, e) = r.until_fault(300);
    assert_eq!(
        e,
        BusFault {
            axis: Some(1),
            node: Some(2),
            reason: FaultReason::DriveFault { code: 0x8130 }
        }
    );
    // Once its heartbeat says pre-operational, no RPDO goes to node 2.
    for _ in 0..100 {
        let _ = r.tick();
    }
    let quiet_from = r.net().tick - 50;
    let late: Vec<_> = rpdos(&r.net().log, 2)
        .into_iter()
        .filter(|(t, _)| *t > quiet_from)
        .collect();
    assert!(
        late.is_empty(),
        "RPDOs to a pre-operational node: {}",
        late.len()
    );

    r.net().deaf_to_heartbeat = None;
    let before = r.net().log.len();
    r.m.reset();
    r.enable_like_the_daemon(500);
    let log = r.net().log[before..].to_vec();
    assert!(
        log.iter()
            .any(|(_, f)| f.id == 0 && f.payload() == [0x82, 2])
    );
    assert!(
        !log.iter().any(|(_, f)| f.id == 0 && f.payload()[1] == 1),
        "node 1 untouched"
    );
    let mut cws: Vec<u16> = rpdos(&log, 2).iter().map(|(_, p)| p.controlword).collect();
    cws.dedup();
    // Reset communication leaves the drive's fault latched: its first TPDO says Fault, so a
    // fault reset comes first, then the enable walk.
    assert_eq!(
        cws,
        [0x00, 0x80, 0x00, 0x06, 0x07, 0x0F],
        "walk after the restart"
    );
    let (max_step, _) = r.target_steps(2);
    assert!(max_step <= MAX_STEP, "step {max_step}");
    assert!((r.fb.axes[1].position_mm + 3.0).abs() < 1e-3);
}

/// A drive fault while the drive stays operational: the reset acts on the statusword that
/// arrives after it, never on the one from before the fault (which still said enabled).
#[test]
fn reset_walks_the_enable_sequence_from_the_fresh_statusword() {
    let mut r = Rig::with(&[1], &[2.0], 4);
    r.enable_like_the_daemon(200);
    let mut out = Vec::new();
    r.net().nodes[0].force_fault(0x2310, &mut out);
    r.net().deliver(out);
    let (_, e) = r.until_fault(5);
    assert_eq!(e.reason, FaultReason::DriveFault { code: 0x2310 });
    let before = r.net().log.len();
    r.m.reset();
    r.enable_like_the_daemon(200);
    let mut cws: Vec<u16> = rpdos(&r.net().log[before..], 1)
        .iter()
        .map(|(_, p)| p.controlword)
        .collect();
    cws.dedup();
    // The TPDO answering the SYNC after the fault already says Fault: fault reset first.
    assert_eq!(cws, [0x80, 0x00, 0x06, 0x07, 0x0F], "{cws:X?}");
}

/// The bus's enable deadline covers its per-drive timeouts: a drive that never boots is
/// named by the bus before the deadline the daemon's enabling window derives from.
#[test]
fn a_missing_drive_is_named_before_the_enable_deadline() {
    let mut r = Rig::new(&[1, 2]);
    r.net().nodes[1].inject.silent = true;
    let deadline = r.m.enable_timeout_ticks() as usize;
    let (t, e) = r.until_fault(deadline);
    assert_eq!(
        (e.axis, e.node, e.reason),
        (Some(1), Some(2), FaultReason::NoBootUp)
    );
    assert!(t < deadline);
}

/// A 2 ms cycle: the drives are told so (0x60C2 = 2 × 10⁻³ s, 0x1006 = 2000 µs), timeouts
/// count in 2 ms ticks, and CSP motion works.
#[test]
fn the_cycle_time_is_configurable() {
    use hal::canopen::sdo;
    let mut r = Rig::with(&[1], &[0.0], 2);
    r.until_operational();
    let writes: Vec<(u16, u8, u32)> = r
        .net()
        .log
        .iter()
        .filter_map(|(_, f)| match sdo::parse_request(f.payload()) {
            Ok(sdo::Request::Download {
                index,
                subindex,
                value,
                ..
            }) if f.id == 0x601 => Some((index, subindex, value)),
            _ => None,
        })
        .collect();
    assert!(writes.contains(&(0x60C2, 1, 2)) && writes.contains(&(0x1006, 0, 2000)));
    for i in 1..=100 {
        r.cmd.positions_mm[0] = f64::from(i) * 0.01;
        r.tick().unwrap();
    }
    for _ in 0..500 {
        r.tick().unwrap();
    }
    assert!((r.fb.axes[0].position_mm - 1.0).abs() < 1e-3);
    // Heartbeat lost after 500 ms = 250 ticks of 2 ms (plus the 100 ms heartbeat period).
    r.net().nodes[0].inject.drop_heartbeat = true;
    let (t, e) = r.until_fault(500);
    assert_eq!(e.reason, FaultReason::HeartbeatLost);
    assert!((200..=320).contains(&t), "{t}");
    let cfg = CanOpenConfig {
        cycle: std::time::Duration::from_micros(500),
        ..CanOpenConfig::new(vec![NodeConfig::new(NodeId::new(1).unwrap(), 1000.0)])
    };
    assert!(CanOpenMaster::new(Net::new(vec![]), "mem", cfg).is_err());
}

/// Module node of the I/O tests.
const MODULE: u8 = 10;

/// Drive node 1 and module 10 (two groups). Inputs: module bits 0 and 12, the drive's 0x60FD
/// bit 2 (home switch). Outputs: module bits 1 and 8 (output 1 safe on), the drive's 0x60FE
/// bit 5.
fn io_rig() -> Rig {
    let m = |bit| IoPoint::Module { node: MODULE, bit };
    let io = IoMap {
        inputs: vec![m(0), m(12), IoPoint::Drive { axis: 0, bit: 2 }],
        outputs: vec![m(1), m(8), IoPoint::Drive { axis: 0, bit: 5 }],
        safe_outputs: IoBits(0b010),
    };
    let mut r = Rig::build_io(&[1], &[0.0], 4, ShutdownMode::Disable, &[MODULE], io);
    r.until_operational();
    r
}

/// The SDO writes the master sent to `node`: (index, subindex, value).
fn sdo_writes(log: &[(u64, Frame)], node: u8) -> Vec<(u16, u8, u32)> {
    use hal::canopen::sdo;
    log.iter()
        .filter(|(_, f)| f.id == 0x600 + u16::from(node))
        .filter_map(|(_, f)| match sdo::parse_request(f.payload()) {
            Ok(sdo::Request::Download {
                index,
                subindex,
                value,
                ..
            }) => Some((index, subindex, value)),
            _ => None,
        })
        .collect()
}

#[test]
fn a_module_boots_with_the_drives_and_is_configured() {
    let mut r = io_rig();
    let writes = sdo_writes(&r.net().log, MODULE);
    for w in [
        (0x1A00, 2, 0x6000_0208),
        (0x1600, 2, 0x6200_0208),
        (0x6206, 1, 0xFF),
        (0x6206, 2, 0xFF),
        (0x6207, 1, 0x00),
        (0x6207, 2, 0x01),
        (0x1016, 1, (127 << 16) | 500),
        (0x1017, 0, 100),
    ] {
        assert!(writes.contains(&w), "missing module write {w:X?}");
    }
    let module = &r.net().modules[0];
    assert_eq!(module.nmt_state(), hal::canopen::nmt::state::OPERATIONAL);
    assert_eq!(module.error_setting(2), (0xFF, 0x01));
    assert_eq!(module.consumer(), (127 << 16) | 500);
    // The drive maps 0x60FD and 0x60FE:1 because the map has points on it.
    let drive = sdo_writes(&r.net().log, 1);
    assert!(drive.contains(&(0x1A01, 1, 0x60FD_0020)));
    assert!(drive.contains(&(0x1601, 1, 0x60FE_0120)));
    // Faults: none for many ticks, the module is watched like a drive.
    for _ in 0..300 {
        r.tick().unwrap();
    }
}

#[test]
fn inputs_arrive_the_cycle_after_they_change_and_outputs_in_their_cycle() {
    let mut r = io_rig();
    for _ in 0..5 {
        r.tick().unwrap();
    }
    assert_eq!(r.fb.inputs, IoBits::NONE);
    // Module bit 12 (group 2 bit 4) and the drive's home switch change before a cycle: that
    // cycle's SYNC samples them, the next cycle reports them.
    r.net().modules[0].io.set_input(12, true);
    r.net().nodes[0].io.inputs = 1 << 2;
    r.tick().unwrap();
    assert_eq!(r.fb.inputs, IoBits::NONE, "sampled at this cycle's SYNC");
    r.tick().unwrap();
    assert_eq!(r.fb.inputs, IoBits(0b110));
    r.net().modules[0].io.set_input(0, true);
    r.net().modules[0].io.set_input(12, false);
    r.tick().unwrap();
    r.tick().unwrap();
    assert_eq!(r.fb.inputs, IoBits(0b101));

    // Outputs 0 and 1: module bits 1 and 8, in the cycle they are commanded.
    r.cmd.outputs = IoBits(0b011);
    r.tick().unwrap();
    assert_eq!(r.net().modules[0].io.outputs(), 0x0102);
    r.cmd.outputs = IoBits(0b001);
    r.tick().unwrap();
    assert_eq!(r.net().modules[0].io.outputs(), 0x0002);
    // Output 2 is the drive's 0x60FE:1 bit 5, applied at the drive's next SYNC.
    r.cmd.outputs = IoBits(0b100);
    r.tick().unwrap();
    r.tick().unwrap();
    assert_eq!(r.net().nodes[0].io.outputs, 1 << 5);
    assert_eq!(r.net().modules[0].io.outputs(), 0);
}

#[test]
fn without_the_master_the_module_falls_to_its_safe_outputs_by_itself() {
    let mut r = io_rig();
    // Output 0 on, output 1 (safe on) off: the unsafe pattern.
    r.cmd.outputs = IoBits(0b001);
    for _ in 0..50 {
        r.tick().unwrap();
    }
    assert_eq!(r.net().modules[0].io.outputs(), 0x0002);
    // The master stops: the last heartbeat it sent is at most 100 ms old now.
    let stopped_ms = r.net().now_ms;
    let mut fell_at = None;
    for _ in 0..300 {
        r.pass_time();
        let net = r.net();
        if fell_at.is_none() && net.modules[0].io.outputs() != 0x0002 {
            fell_at = Some(net.now_ms - stopped_ms);
        }
    }
    let after_ms = fell_at.expect("the module's heartbeat consumer must fire");
    // Consumer time 500 ms from the last heartbeat (sent up to 100 ms before the stop).
    assert!((400..=504).contains(&after_ms), "after {after_ms} ms");
    assert_eq!(
        r.net().modules[0].io.outputs(),
        0x0100,
        "output 0 off, output 1 on"
    );
    assert_eq!(
        r.net().modules[0].nmt_state(),
        hal::canopen::nmt::state::PRE_OPERATIONAL
    );
}

#[test]
fn a_module_heartbeat_loss_is_a_fault_naming_its_node() {
    let mut r = io_rig();
    r.net().modules[0].inject.drop_heartbeat = true;
    let (t, e) = r.until_fault(500);
    assert_eq!(
        e,
        BusFault {
            axis: None,
            node: Some(MODULE),
            reason: FaultReason::HeartbeatLost
        }
    );
    assert!((95..=160).contains(&t), "after {t} ticks");
    assert_eq!(r.fb.axes[0].state, DriveState::Operational, "drive runs on");
    // Back: the reset restarts the module (reset communication, configuration, start).
    r.net().modules[0].inject.drop_heartbeat = false;
    r.m.reset();
    for _ in 0..100 {
        r.tick().unwrap();
    }
    r.net().modules[0].io.set_input(0, true);
    r.cmd.outputs = IoBits(0b010);
    r.tick().unwrap();
    r.tick().unwrap();
    assert!(r.fb.inputs.get(0));
    assert_eq!(r.net().modules[0].io.outputs(), 0x0100);
}

#[test]
fn a_silent_module_times_out_and_a_short_tpdo_is_a_mapping_fault() {
    for corrupt in [false, true] {
        let mut r = io_rig();
        if corrupt {
            r.net().modules[0].inject.corrupt_pdo = true;
        } else {
            r.net().modules[0].inject.silent = true;
        }
        let (_, e) = r.until_fault(100);
        let reason = if corrupt {
            FaultReason::PdoLength {
                cob_id: 0x18A,
                len: 1,
                expected: 2,
            }
        } else {
            FaultReason::Timeout
        };
        assert_eq!((e.axis, e.node, e.reason), (None, Some(MODULE), reason));
    }
}

/// Shutdown: the drives walk down while the module still gets the caller's (safe) outputs;
/// then its heartbeat watch is cleared and it goes pre-operational, keeping them.
#[test]
fn shutdown_keeps_the_safe_outputs_and_leaves_the_module_pre_operational() {
    let mut r = io_rig();
    r.cmd.outputs = IoBits(0b001);
    for _ in 0..20 {
        r.tick().unwrap();
    }
    let before = r.net().log.len();
    r.m.shutdown();
    r.cmd.outputs = IoBits(0b010); // what the caller sends once it shuts down: the safe values
    let mut ticks = 0;
    while !r.m.is_shut_down() {
        r.tick().unwrap();
        ticks += 1;
        assert!(ticks < 500, "shutdown must end by itself");
    }
    let log = r.net().log[before..].to_vec();
    let pre_op = log
        .iter()
        .position(|(_, f)| f.id == 0 && f.payload() == [0x80, MODULE])
        .expect("module to pre-operational");
    let drive_pre_op = log
        .iter()
        .position(|(_, f)| f.id == 0 && f.payload() == [0x80, 1])
        .unwrap();
    let last_rpdo = log
        .iter()
        .rposition(|(_, f)| f.id == 0x20A)
        .expect("module RPDOs during shutdown");
    assert!(drive_pre_op < pre_op && last_rpdo < pre_op);
    assert!(sdo_write_index(&log, MODULE, 0x1016, 1).is_some());
    for _ in 0..500 {
        r.tick().unwrap();
    }
    let module = &r.net().modules[0];
    assert_eq!(module.io.outputs(), 0x0100);
    assert_eq!(module.consumer(), 0);
    assert_eq!(
        module.nmt_state(),
        hal::canopen::nmt::state::PRE_OPERATIONAL
    );
    assert!(
        !r.net()
            .from_nodes
            .iter()
            .any(|(_, f)| f.id == 0x80 + u16::from(MODULE)),
        "no EMCY of the module"
    );
}
