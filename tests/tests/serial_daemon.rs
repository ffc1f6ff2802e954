//! `cncd` with `[bus] kind = "serial"` on a pseudo-terminal served by `sim-serial`, driven
//! by `cncctl`: a program end to end, the line unplugged (alarm, fault), replugged, reset,
//! and a program again.

mod vcan_support;

use std::time::Duration;

use vcan_support::{Daemon, Proc};

/// A three-axis `sim-serial` unit on a pseudo-terminal link in a directory of `test`'s own,
/// once it serves; the link's path. A long watchdog: on a loaded machine the daemon's ticks
/// may come late (the watchdog itself is tested in serial_link.rs).
fn drive_unit(test: &str) -> (Proc, String) {
    let link = vcan_support::temp_dir(test).join("drive.tty");
    let link_s = link.to_str().unwrap().to_owned();
    let mut sim = Proc::spawn(
        "sim-serial",
        &["--link", &link_s, "--axes", "3", "--watchdog-ms", "5000"],
    );
    sim.expect_line(" -> /dev/pts", Duration::from_secs(10));
    (sim, link_s)
}

#[test]
fn daemon_runs_a_program_over_serial_and_recovers_after_replug() {
    let (mut sim, link_s) = drive_unit("serial-daemon-link");
    // 2 s without a reply is a fault: a loaded test machine can stall the simulator's process
    // for hundreds of ms (400 ms failed a CI-like run); an unplug is "link lost" at once.
    let bus = format!("[bus]\nkind = 'serial'\nport = '{link_s}'\nreply_timeout_ticks = 500\n");
    let d = Daemon::start("serial-daemon", &bus, [1, 2, 3]);

    let prog = d.program(
        "part.nc",
        "N10 G1 X20 Y10 F3000\nN20 G0 Z-5\nN30 G1 X5 Y-4\n",
    );
    let (ok, out) = d.cncctl(&["run", "--quiet", &prog], Duration::from_secs(60));
    assert!(ok, "cncctl run failed: {out}");
    let s = d.wait_state("idle", Duration::from_secs(30));
    assert!(s.contains("X5.000 Y-4.000 Z-5.000"), "{s}");
    // The drive itself is there (actual position, from its replies), not only the setpoint.
    let end = std::time::Instant::now() + tests::PATIENCE;
    loop {
        let actual = vcan_support::actual_positions_mm(&d.addr);
        let want = [5.0, -4.0, -5.0];
        if actual.iter().zip(want).all(|(a, w)| (a - w).abs() < 0.001) {
            break;
        }
        assert!(
            std::time::Instant::now() < end,
            "drive positions {actual:?}, want {want:?}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }

    sim.send("unplug");
    let s = d.wait_state("fault", Duration::from_secs(30));
    assert!(s.contains("serial link lost"), "{s}");
    // Reset while unplugged: refused or without effect, the fault stays.
    let _ = d.cncctl(&["reset"], Duration::from_secs(60));
    std::thread::sleep(Duration::from_millis(300));
    assert!(d.status().starts_with("fault"), "{}", d.status());

    sim.send("plug");
    sim.expect_line(" -> /dev/pts", Duration::from_secs(30));
    let (ok, out) = d.cncctl(&["reset"], Duration::from_secs(60));
    assert!(ok, "{out}");
    d.wait_state("idle", Duration::from_secs(60));
    let back = d.program("back.nc", "N10 G1 X0 Y0 Z0 F3000\n");
    let (ok, out) = d.cncctl(&["run", "--quiet", &back], Duration::from_secs(60));
    assert!(ok, "run after replug failed: {out}");
    let s = d.wait_state("idle", Duration::from_secs(30));
    assert!(s.contains("X0.000 Y0.000 Z0.000"), "{s}");
}

/// A serial drive unit with a spindle (protocol version 2, issue #7): the daemon's M3 S… and
/// M5 reach the unit's spindle drive and its actual speed comes back into the status.
#[test]
fn daemon_runs_the_spindle_over_serial() {
    let dir = vcan_support::temp_dir("serial-daemon-spindle-link");
    let link = dir.join("drive.tty");
    let link_s = link.to_str().unwrap();
    let mut sim = Proc::spawn(
        "sim-serial",
        &[
            "--link",
            link_s,
            "--axes",
            "3",
            "--watchdog-ms",
            "5000",
            "--spindle",
            // The spindle runs up in 0.2 s: the cut waits for it (spindle at speed).
            "--ramp-rpm-s",
            "4000",
        ],
    );
    sim.expect_line(" -> /dev/pts", Duration::from_secs(10));
    let bus = format!(
        "[bus]\nkind = 'serial'\nport = '{link_s}'\nreply_timeout_ticks = 500\nspindle_node = 4\n"
    );
    let d = Daemon::start("serial-daemon-spindle", &bus, [1, 2, 3]);
    let prog = d.program("turn.nc", "N10 M3 S800\nN20 G1 X2 F3000\n");
    let (ok, out) = d.cncctl(&["run", "--quiet", &prog], Duration::from_secs(60));
    assert!(ok, "cncctl run failed: {out}");
    vcan_support::wait_spindle_rpm(&d.addr, 800.0, Duration::from_secs(30));
    // M5 alone (a program of technology blocks only) stops the spindle too.
    let prog = d.program("back.nc", "N10 G1 X0 F3000\n");
    let (ok, out) = d.cncctl(&["run", "--quiet", &prog], Duration::from_secs(60));
    assert!(ok, "cncctl run failed: {out}");
    let prog = d.program("stop.nc", "N10 M5\n");
    let (ok, out) = d.cncctl(&["run", "--quiet", &prog], Duration::from_secs(60));
    assert!(ok, "cncctl run failed: {out}");
    vcan_support::wait_spindle_rpm(&d.addr, 0.0, Duration::from_secs(30));

    sim.send("fault 2310 4");
    let s = d.wait_state("fault", Duration::from_secs(30));
    assert!(s.contains("spindle, node 4"), "{s}");
}

/// The start-up seam (issue #50): while the drives are still being enabled, a jog, an MDI or a
/// start typed at once is refused as `machine_not_ready` (UNAVAILABLE: try again), never as
/// `jog_busy` on a machine that is about to be idle; once idle, the same jog works. The drive
/// unit is frozen (SIGSTOP) so that the enabling lasts as long as the test needs.
#[test]
fn commands_while_the_drives_enable_are_refused_as_not_ready_then_work() {
    let (sim, link_s) = drive_unit("serial-daemon-start-up-link");
    sim.signal(libc::SIGSTOP);
    // 20 s to enable: the window stays open while the unit is frozen.
    let bus = format!(
        "[bus]\nkind = 'serial'\nport = '{link_s}'\nreply_timeout_ticks = 5000\n\
         enable_timeout_ticks = 5000\n"
    );
    let d = Daemon::spawn("serial-daemon-start-up", &bus, [1, 2, 3], ["", "", ""], &[]);
    let s = d.wait_state("enabling", Duration::from_secs(60));
    for cmd in [
        &["jog", "X", "--step", "1"][..],
        &["mdi", "G1 X1 F100"][..],
        &["start"][..],
    ] {
        let (ok, out) = d.cncctl(cmd, Duration::from_secs(60));
        assert!(!ok, "{cmd:?} during start-up was taken: {out}\n{s}");
        assert!(
            out.contains("machine_not_ready") && !out.contains("jog_busy"),
            "{cmd:?}: {out}"
        );
    }
    assert!(d.status().starts_with("enabling"), "{}", d.status());

    sim.signal(libc::SIGCONT);
    d.wait_state("idle", Duration::from_secs(60));
    let (ok, out) = d.cncctl(&["jog", "X", "--step", "1"], Duration::from_secs(60));
    assert!(ok, "jog once idle: {out}");
    let s = d.wait_state("idle", Duration::from_secs(30));
    assert!(s.contains("X1.000"), "{s}");
}
