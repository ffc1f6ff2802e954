//! The daemon (its pipeline and RT core in the single-threaded harness, virtual time) with the
//! serial bus it builds from `[bus] kind = "serial"` (`buses::open_bus`), on a pseudo-terminal
//! served between ticks by the simulated drive unit. The serial master runs each drive through
//! the CiA 402 phase machine the CAN master uses too (`hal::cia402::Drive`), so the unit's
//! drives get what CAN drives get: enabled without a target jump even when one drive enables
//! later than the others; after a fault stop the healthy drives go to the configured safe
//! state; at shutdown (the SIGTERM path) every drive is walked down and stays off without a
//! watchdog fault.

mod serial_common;

use std::path::Path;
use std::sync::{Arc, Mutex};

use daemon::runtime::buses::open_bus;
use daemon::runtime::clock::SimClock;
use daemon::runtime::config::Config;
use daemon::runtime::harness::{Harness, JobEnd};
use daemon::runtime::rt::{MachineState, RtCommand};
use hal::cia402::PowerState;
use serial_common::{Line, UnitSide};
use sim::SimDriveParams;
use sim::cia402_drive::Cia402Drive;
use sim::serial_drive::SerialDriveUnit;

const INC_PER_MM: f64 = 10_000.0;
/// One tick's travel at the axes' limit: 12000 mm/min × 4 ms, increments.
const MAX_STEP: i32 = 8000;

/// A daemon with axes X, Y, Z on one serial drive unit whose drives stand at `start_mm`;
/// `faulted`: drives that report a fault at power-on (they enable a few ticks later, after
/// the fault reset).
fn daemon(
    start_mm: [f64; 3],
    faulted: &[usize],
    bus_keys: &str,
) -> (Harness, Arc<Mutex<UnitSide>>) {
    let mut drives: Vec<Cia402Drive> = start_mm
        .iter()
        .map(|&mm| Cia402Drive::new(SimDriveParams::default(), INC_PER_MM, mm))
        .collect();
    for &k in faulted {
        drives[k].fault(0x3210);
    }
    let (side, path) = UnitSide::open(SerialDriveUnit::new(drives));
    let mut toml = String::new();
    for (i, name) in ['X', 'Y', 'Z'].iter().enumerate() {
        toml.push_str(&format!(
            "[[axes]]\nname = '{name}'\nnode_id = {}\nincrements_per_mm = {INC_PER_MM}\n\n",
            i + 1
        ));
    }
    toml.push_str(&format!(
        "[bus]\nkind = 'serial'\nport = '{path}'\n{bus_keys}"
    ));
    let mut cfg = Config::parse(&toml, Path::new("serial.toml")).unwrap();
    let base = tests::test_config();
    cfg.storage = base.storage;
    cfg.rt = base.rt;
    let io = daemon::runtime::buses::IoWiring::of(&cfg);
    let bus = open_bus(&cfg.bus, &cfg.axes, &cfg.sim, &io).unwrap();
    let line = Line {
        bus,
        side: side.clone(),
    };
    let h = Harness::new(cfg, Box::new(line), SimClock::exact()).unwrap();
    (h, side)
}

/// The targets `axis` was sent while its power stage was commanded on (controlword "enable
/// operation"): the ones a drive follows.
fn enabled_targets(side: &UnitSide, axis: usize) -> Vec<i32> {
    side.requests
        .iter()
        .map(|r| r.axis[axis])
        .filter(|a| a.controlword & 0x0F == 0x0F)
        .map(|a| a.target_increments)
        .collect()
}

/// The largest step between consecutive targets.
fn largest_step(targets: &[i32]) -> i32 {
    targets
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .max()
        .unwrap()
}

/// Y's drive reports a fault at power-on, so X and Z are enabled ticks before it while the
/// controller still commands its start position (it takes the drives' positions once all are
/// enabled): their targets hold where they stand, no jump.
#[test]
fn drives_away_from_zero_enable_without_a_jump_when_one_enables_late() {
    let start = [25.0, -40.0, 7.5];
    let (mut h, side) = daemon(start, &[1], "");
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    let s = h.step();
    for (i, &mm) in start.iter().enumerate() {
        assert!(
            (s.axes.commanded[i] - mm).abs() < 1e-3,
            "{:?}",
            s.axes.commanded
        );
    }
    let end = h
        .run_program("G90 G1 X27 Y-38 Z8 F3000\n", 100_000)
        .unwrap();
    assert_eq!(end, JobEnd::Finished);
    let side = side.lock().unwrap();
    for (axis, &mm) in start.iter().enumerate() {
        let t = enabled_targets(&side, axis);
        assert_eq!(t[0], (mm * INC_PER_MM) as i32, "axis {axis}");
        let step = largest_step(&t);
        assert!(step <= MAX_STEP, "axis {axis}: target step {step}");
    }
    let enabled = PowerState::OperationEnabled;
    assert!(side.unit.drives.iter().all(|d| d.state() == enabled));
}

/// Issue #15 over serial: after a drive fault the healthy axes brake to rest, then their
/// drives go to the configured safe state; a reset enables them all again.
#[test]
fn after_a_fault_the_healthy_serial_drives_go_to_the_configured_safe_state() {
    for (keys, want) in [
        ("", PowerState::QuickStopActive),
        (
            "fault_reaction = 'disable_voltage'\n",
            PowerState::SwitchOnDisabled,
        ),
        ("fault_reaction = 'hold'\n", PowerState::OperationEnabled),
    ] {
        let (mut h, side) = daemon([0.0; 3], &[], keys);
        h.wait_state(MachineState::Idle, 10_000).unwrap();
        let job = h.start_program("G90 G1 X100 Y50 Z20 F3000\n").unwrap();
        h.run_until(10_000, |s| s.axes.commanded[0] > 5.0).unwrap();
        side.lock().unwrap().unit.drives[1].fault(0x2310);
        assert_eq!(h.finish_job(job, 10_000).unwrap(), JobEnd::Aborted);
        let f = h.snapshot().alarm.fault.unwrap();
        assert_eq!((f.axis, f.node), (Some(1), Some(2)), "{keys}");
        // At rest, then the safe state (bounded: the settle timeout is 1 s).
        for _ in 0..1000 {
            h.step();
        }
        {
            let side = side.lock().unwrap();
            let d = &side.unit.drives;
            for k in [0, 2] {
                assert_eq!(d[k].state(), want, "{keys}: axis {k}");
            }
            assert_eq!(d[1].state(), PowerState::Fault);
            assert!((h.snapshot().axes.actual[0] - d[0].position_mm()).abs() < 1e-3);
        }
        h.send(RtCommand::Reset).unwrap();
        h.wait_state(MachineState::Idle, 10_000).unwrap();
        let side = side.lock().unwrap();
        for (k, d) in side.unit.drives.iter().enumerate() {
            assert_eq!(d.state(), PowerState::OperationEnabled, "{keys}: axis {k}");
        }
    }
}

/// The SIGTERM path: the axes come to rest, then every drive is walked down (07h → 06h → 00h,
/// or 02h → 00h with `shutdown = 'quick_stop'`). Long after the daemon ended the unit's
/// communication watchdog has faulted nothing: the drives are off, where the program left them.
#[test]
fn shutdown_walks_every_serial_drive_down_and_the_watchdog_finds_none_enabled() {
    for (keys, walk) in [
        ("", [0x07, 0x06, 0x00].as_slice()),
        ("shutdown = 'quick_stop'\n", [0x02, 0x00].as_slice()),
    ] {
        let (mut h, side) = daemon([0.0; 3], &[], keys);
        h.wait_state(MachineState::Idle, 10_000).unwrap();
        let end = h.run_program("G90 G1 X12 Y-5 Z3 F3000\n", 100_000).unwrap();
        assert_eq!(end, JobEnd::Finished);
        let before = side.lock().unwrap().requests.len();
        h.shut_down(100_000).unwrap();
        let mut side = side.lock().unwrap();
        for axis in 0..3 {
            let mut words: Vec<u16> = side.requests[before..]
                .iter()
                .map(|r| r.axis[axis].controlword)
                .skip_while(|&c| c == 0x0F)
                .collect();
            words.dedup();
            assert_eq!(words, walk, "{keys}: axis {axis}");
        }
        side.idle(10_000);
        for (k, (d, want)) in side.unit.drives.iter().zip([12.0, -5.0, 3.0]).enumerate() {
            assert_eq!(d.state(), PowerState::SwitchOnDisabled, "{keys}: axis {k}");
            assert_eq!(d.error_code(), 0, "{keys}: axis {k}");
            assert!((d.position_mm() - want).abs() < 1e-3, "{keys}: axis {k}");
        }
    }
}
