//! The serial drive link (`hal::serial::SerialBus`) against the `sim-serial` process on a
//! pseudo-terminal: motion, unplug and replug, silent and corrupt replies, drive faults.

mod vcan_support;

use std::path::{Path, PathBuf};
use std::time::Duration;

use hal::serial::{SerialAxis, SerialBus, SerialConfig, SerialSpindle};
use hal::{BusFault, DriveBus, FaultReason};
use vcan_support::{Cycler, Proc, temp_dir};

const INC_PER_MM: f64 = 10_000.0;

fn sim_serial(link: &Path, axes: usize) -> Proc {
    sim_serial_with(link, axes, &[])
}

fn sim_serial_with(link: &Path, axes: usize, extra: &[&str]) -> Proc {
    let axes = axes.to_string();
    let mut args = vec!["--link", link.to_str().unwrap(), "--axes", &axes];
    args.extend_from_slice(extra);
    let mut p = Proc::spawn("sim-serial", &args);
    p.expect_line(" -> /dev/pts", Duration::from_secs(10));
    p
}

type Rig = Cycler<SerialBus>;

fn rig(link: &Path, axes: usize) -> Rig {
    let mut cfg = SerialConfig::new(
        link.to_str().unwrap(),
        (1..=axes as u8)
            .map(|node_id| SerialAxis::new(node_id, INC_PER_MM))
            .collect(),
    );
    // 1 s without a reply is a fault: a loaded machine can stall the simulator's process
    // for hundreds of ms.
    cfg.reply_timeout_ticks = 250;
    let mut bus = SerialBus::open(cfg).unwrap();
    bus.enable();
    Cycler::new(bus, Duration::from_secs(10))
}

fn link(test: &str) -> PathBuf {
    temp_dir(test).join("drive.tty")
}

#[test]
fn drive_unit_follows_setpoints_over_a_pty() {
    let link = link("serial-motion");
    let _sim = sim_serial(&link, 3);
    let mut rig = rig(&link, 3);
    rig.until_operational();
    rig.move_to(0, 12.5, 100.0);
    rig.move_to(1, -3.0, 50.0);
    let p: Vec<f64> = rig.fb.axes[..3].iter().map(|a| a.position_mm).collect();
    assert!((p[0] - 12.5).abs() <= 0.001 && (p[1] + 3.0).abs() <= 0.001 && p[2].abs() <= 0.001);
}

#[test]
fn unplug_is_link_down_and_replug_with_reset_resumes() {
    let link = link("serial-unplug");
    let mut sim = sim_serial(&link, 2);
    let mut rig = rig(&link, 2);
    rig.until_operational();
    rig.move_to(0, 5.0, 100.0);

    sim.send("unplug");
    let e = rig.until_fault(Duration::from_secs(10));
    assert_eq!(
        e,
        BusFault {
            axis: None,
            node: None,
            reason: FaultReason::LinkDown
        }
    );
    assert!(e.to_string().contains("serial link lost"), "{e}");
    // Reset while the port is still gone: the fault stays.
    rig.bus.reset();
    for _ in 0..10 {
        assert_eq!(rig.tick().unwrap_err().reason, FaultReason::LinkDown);
    }
    sim.send("plug");
    sim.expect_line(" -> /dev/pts", Duration::from_secs(5));
    // The drive faulted itself on the lost link (8130h); reset reopens and fault-resets it.
    rig.bus.reset();
    rig.until_operational();
    assert!((rig.fb.axes[0].position_mm - 5.0).abs() <= 0.001);
    rig.move_to(0, 6.0, 100.0);
}

#[test]
fn silent_corrupt_and_faulted_drives_are_named() {
    let link = link("serial-faults");
    let mut sim = sim_serial(&link, 2);
    let mut rig = rig(&link, 2);
    rig.until_operational();
    for (on, off, reason) in [
        ("silent on", "silent off", FaultReason::Timeout),
        ("corrupt on", "corrupt off", FaultReason::CorruptFrames),
    ] {
        sim.send(on);
        let e = rig.until_fault(Duration::from_secs(10));
        assert_eq!(e.reason, reason, "{on}");
        sim.send(off);
        rig.bus.reset();
        rig.until_operational();
    }
    sim.send("fault 2310 2");
    let e = rig.until_fault(Duration::from_secs(10));
    assert_eq!(
        e,
        BusFault {
            axis: Some(1),
            node: Some(2),
            reason: FaultReason::DriveFault { code: 0x2310 }
        }
    );
    assert!(e.to_string().contains("overcurrent"), "{e}");
    rig.bus.reset();
    rig.until_operational();

    // Following error beyond the drive's 50 mm window.
    rig.cmd.positions_mm[0] = 80.0;
    let e = rig.until_fault(Duration::from_secs(10));
    assert_eq!((e.axis, e.reason), (Some(0), FaultReason::FollowingError));
}

/// Protocol version 2 (issue #7): the spindle setpoint goes to the unit's spindle drive in
/// every request, its actual speed comes back in every reply (with the unit's ramp), M4 is
/// negative, and a spindle drive fault names the spindle.
#[test]
fn spindle_speed_crosses_the_link_both_ways() {
    let link = link("serial-spindle");
    let mut sim = sim_serial_with(
        &link,
        2,
        &["--spindle", "--units-per-rpm", "10", "--ramp-rpm-s", "5000"],
    );
    let mut cfg = SerialConfig::new(
        link.to_str().unwrap(),
        (1..=2)
            .map(|node_id| SerialAxis::new(node_id, INC_PER_MM))
            .collect(),
    );
    // 1 s without a reply is a fault: a loaded machine can stall the simulator's process
    // for hundreds of ms.
    cfg.reply_timeout_ticks = 250;
    cfg.spindle = Some(SerialSpindle {
        node_id: 3,
        units_per_rpm: 10.0,
    });
    let mut bus = SerialBus::open(cfg).unwrap();
    bus.enable();
    let mut rig = Cycler::new(bus, Duration::from_secs(10));
    assert_eq!(rig.bus.axes(), 2);
    rig.until_operational();
    rig.until_spindle_operational();
    // On the way up the actual speed passes through the ramp.
    rig.cmd.spindle_rpm = 900.0;
    let mut seen_between = 0;
    let t0 = std::time::Instant::now();
    while rig.fb.spindle_rpm != 900.0 {
        assert!(t0.elapsed() < Duration::from_secs(10), "{:?}", rig.fb);
        rig.tick().unwrap();
        seen_between += usize::from(rig.fb.spindle_rpm > 0.0 && rig.fb.spindle_rpm < 900.0);
    }
    assert!(seen_between > 10, "ramp seen in {seen_between} replies");
    rig.spindle_to(-123.4, Duration::from_secs(10));
    rig.move_to(0, 2.0, 100.0);
    assert!((rig.fb.spindle_rpm + 123.4).abs() < 1e-9);

    sim.send("fault 2310 3");
    let e = rig.until_fault(Duration::from_secs(10));
    assert_eq!(
        e,
        BusFault {
            axis: Some(hal::SPINDLE_AXIS),
            node: Some(3),
            reason: FaultReason::DriveFault { code: 0x2310 }
        }
    );
    rig.cmd.spindle_rpm = 0.0;
    rig.bus.reset();
    rig.until_operational();
    rig.until_spindle_operational();
}
