//! The daemon (its pipeline and RT core in the single-threaded harness, virtual time) with its CANopen master on an in-memory
//! bus of simulated CiA 402 drives (`sim::can_node`): the configuration the daemon builds from
//! `[bus] kind = "can"`, deterministic and without vcan. Issue #23: drives standing away from
//! 0 are enabled without a target jump; a drive that never boots is named by the bus before
//! the daemon's enabling window; a program runs and a shutdown (the SIGTERM path) leaves every
//! drive switched off, unwatched and without a fault.

use std::path::Path;
use std::sync::{Arc, Mutex};

use daemon::runtime::buses::{BusConfig, can_config};
use daemon::runtime::clock::SimClock;
use daemon::runtime::config::Config;
use daemon::runtime::controller::ControlError;
use daemon::runtime::harness::{Harness, HarnessError, JobEnd};
use daemon::runtime::homing;
use daemon::runtime::rt::{MachineState, RtCommand};
use hal::FaultReason;
use hal::canopen::pdo::Rpdo;
use hal::canopen::{CanOpenMaster, Frame, nmt};
use hal::cia402::PowerState;
use sim::SimDriveParams;
use sim::can_node::CanNode;
use sim::cia402_drive::Cia402Drive;
use tests::can_sim::{Bus, Port};

const INC_PER_MM: f64 = 10_000.0;

/// A daemon with axes X, Y, Z on CAN nodes 1..3 whose drives stand at `start_mm`.
fn daemon(start_mm: [f64; 3], silent: Option<usize>, bus_keys: &str) -> (Harness, Arc<Mutex<Bus>>) {
    daemon_with(start_mm, silent, bus_keys, ["", "", ""], [None; 3])
}

/// As [`daemon`], with more keys per axis and the drives' home switches (drive coordinates).
fn daemon_with(
    start_mm: [f64; 3],
    silent: Option<usize>,
    bus_keys: &str,
    axis_keys: [&str; 3],
    switches: [Option<f64>; 3],
) -> (Harness, Arc<Mutex<Bus>>) {
    let mut toml = String::new();
    for (i, name) in ['X', 'Y', 'Z'].iter().enumerate() {
        toml.push_str(&format!(
            "[[axes]]\nname = '{name}'\nnode_id = {}\nincrements_per_mm = {INC_PER_MM}\n{}\n\n",
            i + 1,
            axis_keys[i]
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
    let master_cfg = can_config(can, &cfg.axes).unwrap();
    let mut nodes: Vec<CanNode> = start_mm
        .iter()
        .enumerate()
        .map(|(i, &mm)| {
            let mut drive = Cia402Drive::new(SimDriveParams::default(), INC_PER_MM, mm);
            drive.home_switch_mm = switches[i];
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
        assert!(
            (s.axes.commanded[i] - mm).abs() < 1e-3,
            "{:?}",
            s.axes.commanded
        );
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
        .alarm
        .fault
        .unwrap();
    assert_eq!(
        (f.axis, f.node, f.reason),
        (Some(1), Some(2), FaultReason::NoBootUp)
    );
}

/// The 1-byte expedited SDO downloads of 0x6060 (modes of operation) to `node`, with the
/// index of the frame in `sent`.
fn mode_writes(sent: &[Frame], node: u8) -> Vec<(usize, u8)> {
    sent.iter()
        .enumerate()
        .filter(|(_, f)| {
            f.id == 0x600 + u16::from(node) && f.data[0] == 0x2F && f.data[1..4] == [0x60, 0x60, 0]
        })
        .map(|(k, f)| (k, f.data[4]))
        .collect()
}

/// Z (method 19, switch above) and X (method 21, switch below) need homing, Z first; Y has
/// an absolute encoder.
const HOMING_AXES: [&str; 3] = [
    "homing = 'required'\nhome_order = 2\nhoming_direction = -1\nreference_mm = 10\n\
     homing_speed_mm_min = 600\nhoming_zero_speed_mm_min = 60",
    "",
    "homing = 'required'\nhome_order = 1\nhoming_direction = 1\nreference_mm = -2\n\
     homing_speed_mm_min = 600\nhoming_zero_speed_mm_min = 60",
];

/// Issue #15 on CANopen: `home` runs each drive's own reference run (CiA 402 homing mode 6) in
/// the configured order; programs are refused before; the home offset is the reference; the
/// return to CSP has no target jump and the commanded position is re-based on the homed one.
#[test]
fn can_drives_home_in_order_and_return_to_csp_without_a_jump() {
    let (mut h, bus) = daemon_with(
        [0.0, 4.0, 0.0],
        None,
        "homing_timeout_ms = 20000\n",
        HOMING_AXES,
        [Some(-5.0), None, Some(3.0)],
    );
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    let e = h.start_program("G90 G1 X1 F1000\n").unwrap_err();
    assert!(
        matches!(e, HarnessError::Control(ControlError::WrongState(_))),
        "{e:?}"
    );
    let before = h.snapshot();
    assert!(!homing::axis_homed(h.config(), &before, 0));

    assert_eq!(h.home("", 100_000).unwrap(), "ZX");
    let s = h.step();
    assert_eq!(s.axes.homed & 0b101, 0b101);
    assert!((0..3).all(|i| homing::axis_homed(h.config(), &s, i)));
    // The switch edge became the reference (offset 0x607C); the drive stands just past it
    // (braking from 1 mm/s at 800 mm/s²), and the commanded position is where it stands.
    assert!((s.axes.actual[0] - 10.0).abs() < 0.01, "{s:?}");
    assert!((s.axes.actual[2] + 2.0).abs() < 0.01, "{s:?}");
    for i in [0, 2] {
        assert!(
            (s.axes.commanded[i] - s.axes.actual[i]).abs() < 1e-3,
            "{s:?}"
        );
    }
    assert_eq!(s.axes.commanded[1], 4.0, "Y did not move");

    let max_step = 200.0 * 0.004 * INC_PER_MM;
    {
        let b = bus.lock().unwrap();
        let (z, x) = (mode_writes(&b.sent, 3), mode_writes(&b.sent, 1));
        // Z: 8 at start-up, 6, back to 8; then X the same: the configured order.
        let modes = |w: &[(usize, u8)]| w.iter().map(|&(_, m)| m).collect::<Vec<_>>();
        assert_eq!((modes(&z), modes(&x)), (vec![8, 6, 8], vec![8, 6, 8]));
        assert!(
            z[2].0 < x[1].0,
            "Z returned to CSP before X entered homing mode"
        );
        for (node, w) in [(1u8, &x), (3, &z)] {
            // In CSP again: the first target is the drive's homed position, then no step
            // beyond one tick's travel at the axis limit.
            let back = w[2].0;
            let targets: Vec<i32> = b.sent[back..]
                .iter()
                .filter(|f| f.id == 0x200 + u16::from(node))
                .map(|f| Rpdo::decode(f.payload()).unwrap().target_increments)
                .collect();
            let homed = if node == 1 { 10.0 } else { -2.0 };
            assert!(
                (f64::from(targets[0]) / INC_PER_MM - homed).abs() < 0.01,
                "node {node}: {}",
                targets[0]
            );
            let step = targets
                .windows(2)
                .map(|p| (p[1] - p[0]).abs())
                .max()
                .unwrap();
            assert!(f64::from(step) <= max_step, "node {node}: step {step}");
            // The handshake: bit 4 started it, the drive answered bits 12 + 10.
            let cws: Vec<u16> = b.sent[w[1].0..back]
                .iter()
                .filter(|f| f.id == 0x200 + u16::from(node))
                .map(|f| Rpdo::decode(f.payload()).unwrap().controlword)
                .collect();
            assert!(cws.contains(&0x1F), "node {node}: {cws:X?}");
        }
    }

    // Homed: a program runs, in the homed coordinates.
    let end = h.run_program("G90 G1 X12 Z-1 F3000\n", 100_000).unwrap();
    assert_eq!(end, JobEnd::Finished);
    h.run_until(1000, |s| (s.axes.actual[0] - 12.0).abs() < 1e-3)
        .unwrap();
    let b = bus.lock().unwrap();
    assert!((b.nodes[0].drive.position_mm() - 12.0).abs() < 1e-3);
    assert!((b.nodes[2].drive.position_mm() + 1.0).abs() < 1e-2);
}

/// A drive without a home switch ends its run with the homing error bit: a typed fault naming
/// axis and node, the run ABORTED, the axis not homed.
#[test]
fn a_homing_error_of_the_drive_is_a_fault_naming_axis_and_node() {
    let (mut h, _bus) = daemon_with(
        [0.0; 3],
        None,
        "",
        ["", "homing = 'required'", ""],
        [None; 3],
    );
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    let e = h.home("Y", 100_000).unwrap_err();
    assert!(
        matches!(e, HarnessError::Control(ControlError::Aborted(_))),
        "{e:?}"
    );
    let s = h.snapshot();
    let f = s.alarm.fault.unwrap();
    assert_eq!((f.axis, f.node), (Some(1), Some(2)));
    assert!(
        matches!(f.reason, FaultReason::HomingError { statusword } if statusword & 0x2000 != 0),
        "{f:?}"
    );
    assert_eq!(s.axes.homed & 0b010, 0);
}

/// Issue #15: after a drive fault the healthy axes brake to rest, then their drives go to the
/// configured safe state: quick stop (default) or disable voltage; a reset enables them again.
#[test]
fn after_a_fault_the_healthy_drives_go_to_the_configured_safe_state() {
    for (keys, want) in [
        ("", PowerState::QuickStopActive),
        (
            "fault_reaction = 'disable_voltage'\n",
            PowerState::SwitchOnDisabled,
        ),
        ("fault_reaction = 'hold'\n", PowerState::OperationEnabled),
    ] {
        let (mut h, bus) = daemon([0.0; 3], None, keys);
        h.wait_state(MachineState::Idle, 10_000).unwrap();
        let job = h.start_program("G90 G1 X100 Y50 Z20 F3000\n").unwrap();
        h.run_until(10_000, |s| s.axes.commanded[0] > 5.0).unwrap();
        {
            let mut b = bus.lock().unwrap();
            let mut out = Vec::new();
            b.nodes[1].force_fault(0x2310, &mut out);
            b.to_master.extend(out);
        }
        assert_eq!(h.finish_job(job, 10_000).unwrap(), JobEnd::Aborted);
        let f = h.snapshot().alarm.fault.unwrap();
        assert_eq!((f.axis, f.node), (Some(1), Some(2)));
        // At rest, then the safe state (bounded: the settle timeout is 1 s).
        for _ in 0..1000 {
            h.step();
        }
        let b = bus.lock().unwrap();
        for k in [0, 2] {
            assert_eq!(b.nodes[k].drive.state(), want, "{keys}: node {}", k + 1);
        }
        assert_eq!(b.nodes[1].drive.state(), PowerState::Fault);
        let x = b.nodes[0].drive.position_mm();
        drop(b);
        assert!((h.snapshot().axes.actual[0] - x).abs() < 1e-3);
        // Reset walks every drive up again from its state.
        h.send(RtCommand::Reset).unwrap();
        h.wait_state(MachineState::Idle, 10_000).unwrap();
        let b = bus.lock().unwrap();
        for n in &b.nodes {
            assert_eq!(
                n.drive.state(),
                PowerState::OperationEnabled,
                "{keys}: node {}",
                n.id
            );
        }
    }
}

/// A stop during a drive's reference run interrupts it: the drive stops, returns to CSP, the
/// run ends not homed and the commanded position is where the drive stands. A run longer
/// than `homing_timeout_ms` is a typed fault; reset restarts the drive (its configuration
/// sets CSP again) and the machine is idle again.
#[test]
fn a_stop_interrupts_a_drive_homing_and_a_timeout_is_a_fault() {
    let keys = "homing = 'required'\nhoming_speed_mm_min = 600";
    let (mut h, bus) = daemon_with(
        [0.0; 3],
        None,
        "homing_timeout_ms = 2000\n",
        [keys, "", ""],
        [Some(-100.0), None, None],
    );
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    h.send(RtCommand::Home(homing::home_request(h.config(), 0)))
        .unwrap();
    h.run_until(10_000, |s| s.axes.actual[0] < -1.0).unwrap();
    h.send(RtCommand::Stop).unwrap();
    let s = h
        .run_until(10_000, |s| s.state != MachineState::Homing)
        .unwrap();
    assert_eq!(s.state, MachineState::Idle);
    assert_eq!((s.axes.homed & 1, s.axes.homing_failed & 1), (0, 1));
    assert!(s.alarm.fault.is_none());
    let s = h.run_until(100, |_| true).unwrap();
    assert!(
        (s.axes.commanded[0] - s.axes.actual[0]).abs() < 1e-3,
        "{s:?}"
    );
    {
        let b = bus.lock().unwrap();
        let modes: Vec<u8> = mode_writes(&b.sent, 1).iter().map(|&(_, m)| m).collect();
        assert_eq!(modes, [8, 6, 8]);
        assert_eq!(b.nodes[0].drive.state(), PowerState::OperationEnabled);
    }

    // The switch is 100 mm away at 10 mm/s: the 2 s timeout ends the run.
    let e = h.home("X", 10_000).unwrap_err();
    assert!(
        matches!(e, HarnessError::Control(ControlError::Aborted(_))),
        "{e:?}"
    );
    let f = h.snapshot().alarm.fault.unwrap();
    assert_eq!(
        (f.axis, f.node, f.reason),
        (Some(0), Some(1), FaultReason::HomingTimeout)
    );
    h.send(RtCommand::Reset).unwrap();
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    let b = bus.lock().unwrap();
    let modes: Vec<u8> = mode_writes(&b.sent, 1).iter().map(|&(_, m)| m).collect();
    assert_eq!(modes, [8, 6, 8, 6, 8], "the restart wrote CSP again");
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
    assert_eq!(h.snapshot().tick.cycle_ns, 2_000_000);
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
        assert!(
            (s.axes.actual[i] - want).abs() < 1e-3,
            "{:?}",
            s.axes.actual
        );
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
