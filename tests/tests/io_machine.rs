//! The machine's inputs and outputs (issue #46, docs/io.md) in the single-threaded simulation
//! harness, on the simulated machine with its own I/O set (the configuration's default) or a
//! configured `[io]`: the e-stop chain and limit switches stop every axis in the tick they are
//! seen, outputs fall to their safe values in the same tick, M8/M9 switch the coolant before
//! the next move, an M function waits for its input and holds when it times out.

use std::sync::{Arc, Mutex};

use daemon::runtime::clock::SimClock;
use daemon::runtime::config::Config;
use daemon::runtime::harness::{Harness, JobEnd};
use daemon::runtime::rt::{MachineState, RtCommand, Snapshot};
use hal::FaultReason;
use io_support::OutputsBus;
use kernel::jog::JogRequest;

mod io_support;

const MAX_TICKS: u64 = 200_000;

struct Machine {
    h: Harness,
    inputs: sim::io::SimInputs,
    sent: Arc<Mutex<Vec<(u64, f64)>>>,
    cfg: Config,
}

fn machine(cfg: Config) -> Machine {
    let wiring = daemon::runtime::buses::IoWiring::of(&cfg);
    let bus = sim::SimBus::new(sim::SimDriveParams::default(), &vec![0.0; cfg.axes.len()])
        .with_spindle_ramp(0.0)
        .with_inputs(wiring.sim);
    let inputs = bus.input_handle();
    let sent = Arc::new(Mutex::new(Vec::new()));
    let b = OutputsBus {
        inner: bus,
        sent: sent.clone(),
    };
    let mut h = Harness::new(cfg.clone(), Box::new(b), SimClock::seeded(46, 0, 0)).unwrap();
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    Machine {
        h,
        inputs,
        sent,
        cfg,
    }
}

impl Machine {
    fn input(&self, name: &str) -> usize {
        let (inputs, _) = daemon::runtime::io_setup::names(&self.cfg);
        inputs.iter().position(|n| n == name).unwrap()
    }
    fn output(&self, name: &str) -> u64 {
        let (_, outputs) = daemon::runtime::io_setup::names(&self.cfg);
        1 << outputs.iter().position(|n| n == name).unwrap()
    }
    fn set(&self, name: &str, v: Option<bool>) {
        self.inputs.set(self.input(name), v);
    }
    fn last_sent(&self) -> (u64, f64) {
        *self.sent.lock().unwrap().last().unwrap()
    }
}

/// Braking distance of one axis from `v` at deceleration `a`, with a tick of travel for the
/// tick the input is seen in.
fn stop_distance_mm(v_mm_s: f64, a_mm_s2: f64) -> f64 {
    v_mm_s * v_mm_s / (2.0 * a_mm_s2) + v_mm_s * 0.004 * 2.0
}

#[test]
fn estop_opens_during_a_move_every_axis_stops_outputs_fall_safe_reset_waits_for_the_chain() {
    let mut m = machine(tests::test_config());
    let coolant = m.output("coolant");
    let enable = m.output("spindle_enable");
    m.h.start_program("M3 S1000 M8\nG1 X300 Y150 F6000\nM30\n")
        .unwrap();
    let s =
        m.h.run_until(MAX_TICKS, |s| s.axes.commanded[0] > 100.0)
            .unwrap();
    assert_eq!(
        s.io.outputs.0 & (coolant | enable),
        coolant | enable,
        "{:?}",
        s.io
    );
    let v = {
        let sent = m.sent.lock().unwrap();
        (sent[sent.len() - 1].1 - sent[sent.len() - 2].1).abs() / 0.004
    };
    assert!(v > 50.0, "moving at {v} mm/s");
    let before = (s.axes.commanded[0], s.axes.commanded[1]);
    m.set("estop", Some(false));
    // The exchange that reads the open chain is followed by the reaction in the same tick:
    // the fault, and the safe outputs (0) in the next exchange, the earliest the bus carries.
    let s = m.h.step();
    let f = s.alarm.fault.expect("the e-stop chain faults at once");
    assert!(
        matches!(f.reason, FaultReason::EmergencyStop { .. }),
        "{f:?}"
    );
    assert_eq!(f.reason.code(), "emergency_stop");
    assert!(s.io.estop_open);
    let s = m.h.step();
    assert_eq!(
        m.last_sent().0,
        0,
        "the next exchange carries the safe outputs"
    );
    assert_eq!(s.io.outputs.0, 0);
    let s =
        m.h.run_until(MAX_TICKS, |s| {
            s.axes.path_v_mm_s == 0.0 && s.state == MachineState::Fault
        })
        .unwrap();
    let s =
        m.h.run_until(500, |_| false)
            .err()
            .map(|_| m.h.snapshot())
            .unwrap_or(s);
    // Every axis braked on its own within the fault-stop distance (default deceleration).
    let a = kernel::plan::DEFAULT_AXIS_LIMITS.a_max_mm_s2;
    let dx = s.axes.commanded[0] - before.0;
    let dy = s.axes.commanded[1] - before.1;
    assert!(
        dx >= 0.0 && dx <= stop_distance_mm(v, a),
        "X ran {dx} mm after the e-stop (v {v})"
    );
    assert!(
        dy >= 0.0 && dy <= stop_distance_mm(v / 2.0, a),
        "Y ran {dy} mm"
    );
    assert!(s.axes.commanded[0] < 300.0);
    // Reset is refused while the chain is open.
    m.h.send(RtCommand::Reset).unwrap();
    let s =
        m.h.run_until(250, |s| s.state != MachineState::Fault)
            .err()
            .map(|_| m.h.snapshot());
    assert_eq!(
        s.map(|s| s.state),
        Some(MachineState::Fault),
        "Reset with the chain open"
    );
    m.set("estop", None);
    m.h.step();
    m.h.send(RtCommand::Reset).unwrap();
    let s = m.h.wait_state(MachineState::Idle, 10_000).unwrap();
    assert!(s.alarm.fault.is_none() && !s.io.estop_open);
    assert_eq!(
        s.io.outputs.0 & coolant,
        0,
        "coolant stays off after the fault"
    );
}

fn jog(axis: usize, target_mm: f64) -> RtCommand {
    RtCommand::Jog(JogRequest {
        axis,
        target_mm,
        speed_mm_s: 20.0,
        accel_mm_s2: 500.0,
        lease_ticks: 1000,
    })
}

#[test]
fn a_limit_switch_stops_the_machine_names_axis_and_side_and_only_a_jog_away_moves() {
    let mut m = machine(tests::test_config());
    m.h.start_program("G1 X200 F3000\nM30\n").unwrap();
    m.h.run_until(MAX_TICKS, |s| s.axes.commanded[0] > 20.0)
        .unwrap();
    m.set("x_limit_pos", Some(true));
    let s = m.h.step();
    let f = s.alarm.fault.expect("the limit switch faults");
    assert_eq!(f.axis, Some(0), "names axis X");
    assert!(
        matches!(f.reason, FaultReason::LimitSwitch { positive: true, .. }),
        "{f:?}"
    );
    assert!(f.to_string().contains("positive side"), "{f}");
    m.h.run_until(MAX_TICKS, |s| s.axes.path_v_mm_s == 0.0)
        .unwrap();
    m.h.run_until(300, |_| false).ok();
    // Reset acknowledges the switch still reached: no program, no jog toward it.
    m.h.send(RtCommand::Reset).unwrap();
    let s = m.h.wait_state(MachineState::Idle, 10_000).unwrap();
    assert!(s.io.limits.0 != 0 && s.io.limits_acknowledged == s.io.limits);
    let x = s.axes.commanded[0];
    assert!(m.h.start_program("G1 X0 F1000\n").is_ok());
    let s =
        m.h.run_until(50, |_| false)
            .err()
            .map(|_| m.h.snapshot())
            .unwrap();
    assert_eq!(
        s.state,
        MachineState::Idle,
        "no program with a limit switch reached"
    );
    m.h.send(jog(0, x + 10.0)).unwrap();
    let s =
        m.h.run_until(50, |_| false)
            .err()
            .map(|_| m.h.snapshot())
            .unwrap();
    assert_eq!(
        (s.state, s.axes.commanded[0]),
        (MachineState::Idle, x),
        "jog into the switch"
    );
    m.h.send(jog(0, x - 5.0)).unwrap();
    let s =
        m.h.run_until(2000, |s| s.axes.commanded[0] <= x - 5.0 + 1e-9)
            .unwrap();
    assert!(s.alarm.fault.is_none(), "a jog away from the switch moves");
    m.set("x_limit_pos", None);
    let s =
        m.h.run_until(2000, |s| {
            s.state == MachineState::Idle && s.io.limits.0 == 0
        })
        .unwrap();
    assert_eq!(s.io.limits_acknowledged.0, 0);
}

/// Tick by tick: (coolant on, X) as the bus received them.
fn coolant_timeline(m: &Machine) -> Vec<(bool, f64)> {
    let c = m.output("coolant");
    m.sent
        .lock()
        .unwrap()
        .iter()
        .map(|&(o, x)| (o & c != 0, x))
        .collect()
}

#[test]
fn m8_sets_the_coolant_before_the_next_move_m9_clears_it_m30_too() {
    let mut m = machine(tests::test_config());
    m.sent.lock().unwrap().clear();
    let end =
        m.h.run_program(
            "G1 X10 F1200\nM8\nG1 X20\nM9\nG1 X30\nG1 X40 M8\nM30\n",
            MAX_TICKS,
        )
        .unwrap();
    assert_eq!(end, JobEnd::Finished);
    let t = coolant_timeline(&m);
    let first_on = t.iter().position(|&(on, _)| on).expect("coolant on");
    let (_, x_on) = t[first_on];
    assert!(
        (x_on - 10.0).abs() < 1e-9,
        "M8 acts at rest at X10, before X moves: {x_on}"
    );
    let off = first_on + t[first_on..].iter().position(|&(on, _)| !on).unwrap();
    assert!(
        (t[off].1 - 20.0).abs() < 1e-9,
        "M9 acts at rest at X20: {}",
        t[off].1
    );
    // M8 in a motion block: on before its motion starts (X still at 30 when it switches).
    let again = off + t[off..].iter().position(|&(on, _)| on).unwrap();
    assert!(
        (t[again].1 - 30.0).abs() < 1e-6,
        "M8 with a move: before it, {}",
        t[again].1
    );
    // M30 switches what the program switched on off.
    assert!(!t.last().unwrap().0, "M30 ends the coolant");
}

/// The configuration `text` with the tests' storage and real-time settings.
fn config_of(text: &str) -> Config {
    let base = tests::test_config();
    let mut cfg = Config::parse(text, std::path::Path::new("io.toml")).unwrap();
    cfg.storage = base.storage;
    cfg.rt = base.rt;
    cfg
}

fn clamp_config() -> Config {
    let text = "[[io.inputs]]\nname = \"estop\"\nfunction = \"estop\"\n\
        [[io.inputs]]\nname = \"clamped\"\nconfirms = [\"M10\"]\ntimeout_ms = 200\n\
        [[io.outputs]]\nname = \"clamp\"\non = [\"M10\"]\noff = [\"M11\"]\n";
    config_of(text)
}

#[test]
fn a_waiting_m_function_holds_with_its_alarm_when_the_input_does_not_come() {
    let mut m = machine(clamp_config());
    // The chain input of this configuration is closed only when set so.
    m.set("estop", Some(true));
    m.h.step();
    m.h.send(RtCommand::Reset).unwrap();
    m.h.wait_state(MachineState::Idle, 10_000).unwrap();
    let clamp = m.output("clamp");
    let clamped = m.input("clamped");
    m.h.start_program("G1 X5 F1200\nM10\nG1 X20\nM11\nM30\n")
        .unwrap();
    // At X5 the clamp output is on and the block waits for its confirmation…
    let s =
        m.h.run_until(MAX_TICKS, |s: &Snapshot| s.io.waiting.get(clamped))
            .unwrap();
    assert_eq!(s.io.outputs.0 & clamp, clamp);
    assert!((s.axes.commanded[0] - 5.0).abs() < 1e-9);
    // …for its 200 ms, then holds with the alarm, X still at 5.
    let s =
        m.h.run_until(100, |s| s.io.wait_timed_out.get(clamped))
            .unwrap();
    let s = m.h.wait_state(MachineState::Hold, 1000).unwrap_or(s);
    assert_eq!(s.state, MachineState::Hold);
    assert!((s.axes.commanded[0] - 5.0).abs() < 1e-9);
    // The confirmation comes; Resume goes on.
    m.set("clamped", Some(true));
    m.h.step();
    m.h.send(RtCommand::Resume).unwrap();
    let s =
        m.h.run_until(MAX_TICKS, |s| s.axes.commanded[0] > 6.0)
            .unwrap();
    assert!(s.io.wait_timed_out.0 == 0);
    m.h.run_until(MAX_TICKS, |s| s.state == MachineState::Idle)
        .unwrap();
    assert_eq!(m.last_sent().0 & clamp, 0, "M11 released the clamp");
}

#[test]
fn an_open_door_holds_the_program_and_stops_the_spindle_start_is_refused() {
    let mut m = machine(tests::test_config());
    m.h.start_program("M3 S800\nG1 X100 F3000\nM30\n").unwrap();
    m.h.run_until(MAX_TICKS, |s| s.axes.commanded[0] > 10.0)
        .unwrap();
    m.set("door", Some(false));
    let s =
        m.h.run_until(2000, |s| s.state == MachineState::Hold)
            .unwrap();
    assert!(s.io.door_open);
    let s =
        m.h.run_until(50, |s| s.spindle.kr.spindle_rpm == 0.0)
            .unwrap();
    assert_eq!(s.io.outputs.0 & m.output("spindle_enable"), 0);
    // Resume is refused while open; closing and resuming finishes the job.
    m.h.send(RtCommand::Resume).unwrap();
    let s =
        m.h.run_until(50, |_| false)
            .err()
            .map(|_| m.h.snapshot())
            .unwrap();
    assert_eq!(s.state, MachineState::Hold);
    m.set("door", None);
    m.h.step();
    m.h.send(RtCommand::Resume).unwrap();
    m.h.run_until(MAX_TICKS, |s| s.state == MachineState::Idle)
        .unwrap();
    assert!(m.h.snapshot().axes.commanded[0] > 99.0);
}

/// A home switch wired as an input (the drive does not home itself): the reference run
/// searches it, and the axis is referenced where it is pressed.
#[test]
fn a_home_switch_input_references_the_axis() {
    let text = "[[axes]]\nname = \"X\"\nhoming = \"required\"\nhoming_direction = -1\n\
        reference_mm = 0\n[[axes]]\nname = \"Y\"\n[[axes]]\nname = \"Z\"\n\
        [[io.inputs]]\nname = \"estop\"\nfunction = \"estop\"\n\
        [[io.inputs]]\nname = \"x_home\"\nfunction = \"home\"\naxis = \"X\"\nsim_at_mm = -20\n";
    let mut m = machine(config_of(text));
    // Without the input the search would run its whole travel and fail.
    assert_eq!(m.h.home("X", MAX_TICKS).unwrap(), "X");
    let s = m.h.snapshot();
    assert_eq!(s.axes.homed & 1, 1);
    // The switch (at -20 before the run) is the reference 0 now: the axis stands within the
    // braking distance past it.
    assert!(s.axes.commanded[0].abs() < 5.0, "{}", s.axes.commanded[0]);
}
