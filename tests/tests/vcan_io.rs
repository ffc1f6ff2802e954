//! The machine's inputs and outputs on a real Linux CAN stack (issue #46, docs/io.md): `cncd`
//! with a CiA 401 I/O module and three drives simulated by `sim-can`, driven by `cncctl`. The
//! e-stop input on the module faults the machine and drops the coolant output on the bus;
//! Reset is refused until the chain closes; M8/M9 switch the module's output; a drive's
//! 0x60FD limit bit stops the machine naming the axis; SIGKILL of cncd: the module's outputs
//! fall to their safe values by themselves within its heartbeat consumer time. Skipped where
//! there is no vcan0; `tests/vcan/run.sh` runs it in a VM.

mod vcan_support;

use std::time::{Duration, Instant};

use vcan_support::{Daemon, Proc, sim_can, vcan_lock, vcan_ready};

/// Wide watch times, as in vcan_daemon: the emulated VM stalls processes for up to a second.
/// The module's consumer time is 3 s for the same reason (a stalled cncd must not trip it).
const BUS: &str = "[bus]\nkind = 'can'\ninterface = 'vcan0'\n\
    tpdo_missing_ticks = 1250\nheartbeat_timeout_ms = 10000\ndrive_consumer_timeout_ms = 20000\n\
    following_window_mm = 20\n\n\
    [io]\nmodule_consumer_timeout_ms = 3000\n\
    [[io.inputs]]\nname = 'estop'\nnode_id = 10\nbit = 0\nfunction = 'estop'\n\
    [[io.inputs]]\nname = 'x_limit_pos'\ndrive = 'X'\nbit = 1\nfunction = 'limit_pos'\n\
    [[io.outputs]]\nname = 'coolant'\nnode_id = 10\nbit = 0\non = ['M8']\noff = ['M9']\n\
    [[io.outputs]]\nname = 'lamp'\nnode_id = 10\nbit = 1\nsafe = 1\n";

/// The module's outputs as `sim-can` reports them.
fn module_outputs(sim: &mut Proc) -> u64 {
    sim.send("outputs 10");
    let l = sim.expect_line("outputs node 10", Duration::from_secs(20));
    u64::from_str_radix(l.rsplit(' ').next().unwrap().trim(), 16).unwrap()
}

fn wait_outputs(sim: &mut Proc, what: &str, within: Duration, f: impl Fn(u64) -> bool) -> Duration {
    let t0 = Instant::now();
    loop {
        let o = module_outputs(sim);
        if f(o) {
            return t0.elapsed();
        }
        assert!(t0.elapsed() < within, "{what}: outputs {o:016X}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn estop_limit_coolant_and_a_killed_cncd_on_vcan() {
    let _bus = vcan_lock();
    if !vcan_ready("estop_limit_coolant_and_a_killed_cncd_on_vcan") {
        return;
    }
    let mut sim = sim_can(&[61, 62, 63], &["--io-module", "10"]);
    sim.send("input 10 0 1"); // the chain closed
    let mut d = Daemon::start("vcan-io", BUS, [61, 62, 63]);
    let t = Duration::from_secs(60);
    // M8 switches the module's output on, M9 off.
    let (ok, out) = d.cncctl(&["mdi", "M8"], t);
    assert!(ok, "{out}");
    wait_outputs(&mut sim, "M8", t, |o| o & 1 == 1);
    // (The M8 job ends once its block has run: idle before the next MDI.)
    d.wait_state("idle", t);
    let (ok, out) = d.cncctl(&["mdi", "M9"], t);
    assert!(ok, "{out}");
    wait_outputs(&mut sim, "M9", t, |o| o & 1 == 0);
    // The chain opens during a move: fault, the coolant off on the bus, Reset refused.
    let (ok, out) = d.cncctl(&["mdi", "M8"], t);
    assert!(ok, "{out}");
    wait_outputs(&mut sim, "M8", t, |o| o & 1 == 1);
    d.wait_state("idle", t);
    let (ok, out) = d.cncctl(&["mdi", "G1 X300 F1200"], t);
    assert!(ok, "{out}");
    d.wait_state("running", t);
    sim.send("input 10 0 0");
    let s = d.wait_state("fault", t);
    assert!(s.contains("emergency stop"), "{s}");
    // Every output at its safe value: coolant 0, the lamp (safe = 1) on.
    wait_outputs(&mut sim, "safe values", t, |o| o & 0b11 == 0b10);
    let (ok, out) = d.cncctl(&["reset"], t);
    assert!(!ok && out.contains("emergency-stop chain is open"), "{out}");
    sim.send("input 10 0 1");
    // Refused until the closed chain has come over the bus.
    let t0 = std::time::Instant::now();
    loop {
        let (ok, out) = d.cncctl(&["reset"], t);
        if ok {
            break;
        }
        assert!(out.contains("emergency-stop chain is open"), "{out}");
        assert!(t0.elapsed() < t, "the closed chain never arrived");
        std::thread::sleep(Duration::from_millis(100));
    }
    d.wait_state("idle", t);
    // The X drive's own positive limit (0x60FD bit 1): fault naming X.
    sim.send("input 61 1 1");
    let s = d.wait_state("fault", t);
    assert!(s.contains("limit switch") && s.contains('X'), "{s}");
    let (ok, out) = d.cncctl(&["reset"], t);
    assert!(ok, "{out}");
    d.wait_state("idle", t);
    sim.send("input 61 1 0");
    // SIGKILL: the module falls to its safe values by itself within its consumer time.
    let (ok, out) = d.cncctl(&["mdi", "M8"], t);
    assert!(ok, "{out}");
    wait_outputs(&mut sim, "M8", t, |o| o & 0b11 == 0b01);
    d.proc.kill();
    let took = wait_outputs(
        &mut sim,
        "safe after SIGKILL",
        Duration::from_secs(10),
        |o| o & 0b11 == 0b10,
    );
    eprintln!("module outputs safe {took:?} after SIGKILL (consumer time 3 s)");
    assert!(
        took < Duration::from_secs(3) + Duration::from_millis(1500),
        "{took:?}"
    );
}
