//! The CANopen master against simulated drive nodes on an in-memory bus: start-up, CSP
//! motion, and every fault path, in virtual time (4 ms per tick).

use std::collections::VecDeque;

use hal::canopen::{CanOpenConfig, CanOpenMaster, CanPort, Frame, NodeConfig, PortError, RxEvent};
use hal::{BusFault, CycleCommand, CycleFeedback, DriveBus, DriveState, FaultReason};
use sim::SimDriveParams;
use sim::can_node::CanNode;
use sim::cia402_drive::Cia402Drive;

const INC_PER_MM: f64 = 1000.0;

/// The bus: what the master sends reaches every node at once; answers queue for the master.
struct Net {
    nodes: Vec<CanNode>,
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
        let net = Net::new(nodes);
        let mut cfg = CanOpenConfig::new(
            ids.iter()
                .map(|&node_id| NodeConfig {
                    node_id,
                    increments_per_mm: INC_PER_MM,
                    following_window_increments: Some(10_000),
                    max_velocity_mm_s: 200.0,
                })
                .collect(),
        );
        cfg.cycle_us = cycle_ms * 1000;
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
        node_id: 1,
        increments_per_mm: INC_PER_MM,
        following_window_increments: Some(10_000),
        max_velocity_mm_s: 200.0,
    }]);
    cfg.spindle = Some(hal::canopen::SpindleNodeConfig {
        node_id: 5,
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
