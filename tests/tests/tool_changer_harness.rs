//! The automatic tool changer (docs/setup.md "Automatic tool changer") in the single-threaded
//! simulation harness: at each M6 the RT core puts the tool number on its outputs and runs the
//! configured steps in order, each waiting for its confirmation, then the program goes on by
//! itself; a confirmation that does not come holds with its alarm until it comes and Resume.

use std::sync::{Arc, Mutex};

use daemon::runtime::clock::SimClock;
use daemon::runtime::config::Config;
use daemon::runtime::harness::Harness;
use daemon::runtime::rt::{MachineState, RtCommand, Snapshot};
use io_support::OutputsBus;

mod io_support;

const MAX_TICKS: u64 = 20_000;

/// Outputs 0 unclamp (M61 on, M63 off), 1 arm (M65, a 40 ms pulse), 2 and 3 the tool number;
/// inputs 1 unclamped (confirms M62), 2 clamped (confirms M64), each within 200 ms.
const CONFIG: &str = "[[io.inputs]]\nname = \"estop\"\nfunction = \"estop\"\n\
    [[io.inputs]]\nname = \"unclamped\"\nconfirms = [\"M62\"]\ntimeout_ms = 200\n\
    [[io.inputs]]\nname = \"clamped\"\nconfirms = [\"M64\"]\ntimeout_ms = 200\n\
    [[io.outputs]]\nname = \"unclamp\"\non = [\"M61\"]\noff = [\"M63\"]\n\
    [[io.outputs]]\nname = \"arm\"\non = [\"M65\"]\npulse_ms = 40\n\
    [[io.outputs]]\nname = \"tool_bit0\"\n\
    [[io.outputs]]\nname = \"tool_bit1\"\n\
    [tool_change]\nmode = \"automatic\"\nsequence = [61, 62, 65, 63, 64]\n\
    tool_number_outputs = [\"tool_bit0\", \"tool_bit1\"]\n";

const UNCLAMP: u64 = 1;
const ARM: u64 = 2;
const BITS: u64 = 0b1100;

struct Machine {
    h: Harness,
    inputs: sim::io::SimInputs,
    sent: io_support::Sent,
}

fn machine() -> Machine {
    let base = tests::test_config();
    let mut cfg = Config::parse(CONFIG, std::path::Path::new("atc.toml")).unwrap();
    cfg.storage = base.storage;
    cfg.rt = base.rt;
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
    let mut h = Harness::new(cfg, Box::new(b), SimClock::seeded(47, 0, 0)).unwrap();
    // The chain input of this configuration is closed only when set so.
    inputs.set(0, Some(true));
    h.step();
    h.send(RtCommand::Reset).unwrap();
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    Machine { h, inputs, sent }
}

impl Machine {
    /// One tick of the machine; the changer's mechanics answer the outputs sent (unclamped
    /// while the unclamp valve is on, clamped otherwise) unless `clamp_sensor` is false.
    fn step(&mut self, clamp_sensor: bool) -> Snapshot {
        let out = self.sent.lock().unwrap().last().map_or(0, |s| s.0);
        let unclamped = out & UNCLAMP != 0;
        self.inputs.set(1, Some(unclamped));
        self.inputs.set(2, Some(!unclamped && clamp_sensor));
        self.h.step()
    }

    /// The distinct output words sent since `from`, in order.
    fn changes(&self, from: usize) -> Vec<u64> {
        let sent = self.sent.lock().unwrap();
        let mut v: Vec<u64> = Vec::new();
        for &(o, _) in &sent[from..] {
            if v.last() != Some(&o) {
                v.push(o);
            }
        }
        v
    }
}

#[test]
fn two_tool_changes_run_their_steps_in_order_and_the_program_ends_without_resume() {
    let mut m = machine();
    let from = m.sent.lock().unwrap().len();
    let job =
        m.h.start_program("G1 X5 F1200\nT2 M6\nG1 X10\nT3 M6\nG1 X15\nM2\n")
            .unwrap();
    let mut prompted = false;
    let mut ticks = 0;
    loop {
        let s = m.step(true);
        prompted |= s.progress.tool_change.is_some() || s.progress.program_stop;
        assert!(s.io.wait_timed_out.0 == 0, "{:?}", s.io);
        assert_ne!(s.state, MachineState::Hold, "no hold: {s:?}");
        if s.progress.finished_job == job {
            break;
        }
        ticks += 1;
        assert!(ticks < MAX_TICKS, "{s:?}");
    }
    assert!(!prompted, "no manual prompt in automatic mode");
    assert!((m.h.snapshot().axes.commanded[0] - 15.0).abs() < 1e-9);
    let c = m.changes(from);
    // T2: number 0b10 (bit 1 = output 3) with the unclamp valve, the arm's pulse once the
    // unclamped input confirms, the valve off one step later (the 40 ms pulse runs on), the
    // pulse ends; then T3 (0b11) the same way.
    let (t2, t3) = (0b1000, BITS);
    let expected = vec![
        0,
        t2 | UNCLAMP,
        t2 | UNCLAMP | ARM,
        t2 | ARM,
        t2,
        t3 | UNCLAMP,
        t3 | UNCLAMP | ARM,
        t3 | ARM,
        t3,
    ];
    assert_eq!(c, expected, "{c:?}");
}

#[test]
fn a_confirmation_that_does_not_come_holds_until_it_comes_and_resume() {
    let mut m = machine();
    let job = m.h.start_program("T1 M6\nG1 X5 F1200\nM2\n").unwrap();
    // The clamp sensor never reports: the last step's wait times out (200 ms) and holds.
    let mut s = m.step(false);
    for _ in 0..MAX_TICKS {
        if s.io.wait_timed_out.get(2) {
            break;
        }
        s = m.step(false);
    }
    assert!(s.io.wait_timed_out.get(2), "{:?}", s.io);
    for _ in 0..200 {
        s = m.step(false);
    }
    assert_eq!(s.state, MachineState::Hold);
    assert!(s.io.waiting.get(2) && s.io.wait_timed_out.get(2));
    assert_eq!(s.progress.tool_change, None, "no manual prompt");
    assert!(
        s.axes.commanded[0].abs() < 1e-9,
        "the program has not gone on"
    );
    // The sensor reports: still held until Resume, which retries the wait and goes on.
    for _ in 0..50 {
        s = m.step(true);
    }
    assert_eq!(s.state, MachineState::Hold);
    m.h.send(RtCommand::Resume).unwrap();
    for _ in 0..MAX_TICKS {
        s = m.step(true);
        if s.progress.finished_job == job {
            break;
        }
    }
    assert_eq!(s.progress.finished_job, job, "{s:?}");
    assert!((s.axes.commanded[0] - 5.0).abs() < 1e-9);
    assert_eq!(s.io.wait_timed_out.0, 0);
}

#[test]
fn a_stop_during_the_change_ends_it_and_nothing_resumes() {
    let mut m = machine();
    m.h.start_program("T1 M6\nG1 X5 F1200\nM2\n").unwrap();
    let mut s = m.step(false);
    for _ in 0..MAX_TICKS {
        if s.io.waiting.get(2) {
            break;
        }
        s = m.step(false);
    }
    assert!(s.io.waiting.get(2), "{:?}", s.io);
    m.h.send(RtCommand::Stop).unwrap();
    for _ in 0..500 {
        s = m.step(true);
    }
    assert_eq!(s.state, MachineState::Idle, "{s:?}");
    assert!(s.axes.commanded[0].abs() < 1e-9, "nothing resumed");
    assert_eq!(s.io.outputs.0, 0, "the changer's outputs fell");
}
