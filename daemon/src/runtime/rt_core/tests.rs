//! The core driven directly, single-threaded, on the simulated bus: the deadline grid, the
//! enabling phase and the spindle rules. Whole programs through the core are tested through
//! the harness (`tests/tests/sim_harness.rs`) and the RT thread's no-allocation rule in
//! `tests/tests/rt_noalloc.rs`.

use std::sync::Arc;
use std::sync::atomic::AtomicU32;

use kernel::constants::Constants;
use kernel::kr::{Gear, Kr, KrConfig, RadiusInput};
use kernel::units::{AxesMm, MAX_AXES, TS_NS};

use super::motion::{spindle_at_speed, spindle_feed_rpm};
use super::*;

const AXES: usize = 3;

/// A 3-axis core on the simulated bus at a 4 ms bus period, built at time `now_ns`.
/// The core's configuration: 3 axes at 0, default constants, a 4 ms bus, I/O `io`.
fn config_with(io: IoFunctions) -> RtCoreConfig {
    let kr = KrConfig::from_constants(
        &Constants::new(),
        RadiusInput::Radius,
        vec![Gear {
            max_rpm: 6000.0,
            output_range: 0x7FFF,
            m_code: None,
        }],
    )
    .expect("the default constants are valid");
    RtCoreConfig {
        axes: AXES,
        start: AxesMm::ZERO,
        kr: Kr::new(kr),
        in_position_mm: AxesMm::ZERO,
        stop_decel_mm_s2: [1000.0; MAX_AXES],
        cycle_ns: TS_NS,
        io,
        tool_changer: ToolChanger::default(),
    }
}

fn core_at(now_ns: u64) -> (RtCore, RtRings, sim::SimBus) {
    let cfg = config_with(IoFunctions::default());
    let mut bus = sim::SimBus::new(sim::SimDriveParams::default(), &[0.0; AXES]);
    let core = RtCore::new(cfg, &mut bus, now_ns);
    let (_, commands) = rtrb::RingBuffer::new(4);
    let (_, segments) = rtrb::RingBuffer::new(4);
    let rings = RtRings {
        commands,
        segments,
        planned_job: Arc::new(AtomicU32::new(0)),
    };
    (core, rings, bus)
}

#[test]
fn the_first_deadline_is_one_period_after_start() {
    let (core, _, _) = core_at(1_000);
    assert_eq!(core.next_deadline_ns(), 1_000 + TS_NS);
}

// A late tick skips the deadlines it missed and stays on the grid (no drift), counting them
// as overruns.
#[test]
fn a_late_tick_stays_on_the_deadline_grid() {
    let (mut core, mut rings, mut bus) = core_at(0);
    let due = core.next_deadline_ns();
    // Woke two and a half periods late: two deadlines missed.
    let snap = *core.tick(due + 5 * TS_NS / 2, &mut rings, &mut bus);
    assert_eq!(core.next_deadline_ns(), due + 3 * TS_NS);
    assert_eq!(snap.tick.stats.overruns, 2);
    assert_eq!(snap.tick.sequence, 1);
    // On time again: one period on.
    let due = core.next_deadline_ns();
    core.tick(due, &mut rings, &mut bus);
    assert_eq!(core.next_deadline_ns(), due + TS_NS);
}

#[test]
fn the_drives_enable_then_the_machine_is_idle() {
    let (mut core, mut rings, mut bus) = core_at(0);
    assert_eq!(core.snapshot().state, MachineState::Enabling);
    for _ in 0..100 {
        let due = core.next_deadline_ns();
        if core.tick(due, &mut rings, &mut bus).state != MachineState::Enabling {
            break;
        }
    }
    assert_eq!(core.snapshot().state, MachineState::Idle);
    assert_eq!(core.snapshot().alarm.fault, None);
}

#[test]
fn the_spindle_is_at_speed_within_five_percent_or_two_rpm() {
    assert!(spindle_at_speed(1000.0, 951.0));
    assert!(!spindle_at_speed(1000.0, 949.0));
    assert!(spindle_at_speed(10.0, 8.5));
    assert!(!spindle_at_speed(1000.0, -1000.0));
}

// SPEC §5: feed per revolution holds below 1 rpm or against the setpoint, else follows the
// actual speed.
#[test]
fn feed_per_revolution_follows_the_actual_spindle_speed() {
    assert_eq!(spindle_feed_rpm(1000.0, 0.5), 0.0);
    assert_eq!(spindle_feed_rpm(1000.0, -500.0), 0.0);
    assert_eq!(spindle_feed_rpm(-1000.0, -500.0), 500.0);
    assert_eq!(spindle_feed_rpm(1000.0, 800.0), 800.0);
}

/// A core whose input 0 is the e-stop chain and input 1 the probe, over a simulated
/// workpiece whose top is at Z -10; the command ring's producer and the sim's input handle.
fn probing_core() -> (
    RtCore,
    RtRings,
    sim::SimBus,
    rtrb::Producer<RtCommand>,
    sim::io::SimInputs,
) {
    let io = IoFunctions {
        inputs: 2,
        estop: 0b01,
        probe: 0b10,
        ..IoFunctions::default()
    };
    let cfg = config_with(io);
    let input = |probe: bool| sim::io::SimInput {
        rest: !probe,
        switch: None,
        probe,
    };
    let workpiece = sim::probe::SimProbe {
        axes: [Some(0), Some(1), Some(2)],
        tool_length_mm: 0.0,
        ball_radius_mm: 0.0,
        workpiece: Some(sim::probe::SimBox {
            min_mm: [-100.0, -100.0, -60.0],
            max_mm: [100.0, 100.0, -10.0],
        }),
        bores: vec![],
        setter: None,
    };
    let handle = sim::io::SimInputs::default();
    let mut bus = sim::SimBus::new(sim::SimDriveParams::default(), &[0.0; AXES])
        .with_inputs(vec![input(false), input(true)])
        .with_probe(Some(workpiece))
        .with_input_handle(handle.clone());
    let mut core = RtCore::new(cfg, &mut bus, 0);
    let (producer, commands) = rtrb::RingBuffer::new(8);
    let (_, segments) = rtrb::RingBuffer::new(4);
    let mut rings = RtRings {
        commands,
        segments,
        planned_job: Arc::new(AtomicU32::new(0)),
    };
    for _ in 0..100 {
        let due = core.next_deadline_ns();
        core.tick(due, &mut rings, &mut bus);
    }
    assert_eq!(core.snapshot().state, MachineState::Idle);
    (core, rings, bus, producer, handle)
}

fn probe_down(feed_mm_min: f64) -> RtCommand {
    RtCommand::Probe(ProbeRequest {
        axis: 2,
        target_mm: -20.0,
        speed_mm_s: feed_mm_min / 60.0,
        accel_mm_s2: 1000.0,
        toward: true,
    })
}

/// Ticks until the probing move has ended (at most `n` ticks); the last snapshot.
fn until_probed(core: &mut RtCore, rings: &mut RtRings, bus: &mut sim::SimBus) -> Snapshot {
    for _ in 0..20_000 {
        let due = core.next_deadline_ns();
        let s = *core.tick(due, rings, bus);
        if s.probe.outcome != ProbeOutcome::Moving && s.state != MachineState::Jog {
            return s;
        }
    }
    panic!("the probing move did not end");
}

#[test]
fn a_probing_move_takes_the_position_within_one_period_and_brakes() {
    let (mut core, mut rings, mut bus, mut cmd, _) = probing_core();
    cmd.push(probe_down(300.0)).unwrap();
    let s = until_probed(&mut core, &mut rings, &mut bus);
    assert_eq!(s.probe.outcome, ProbeOutcome::Contact);
    let z = s.probe.position[2];
    let step = 300.0 / 60.0 * 0.004;
    assert!((-10.0 - step..=-10.0).contains(&z), "{z}");
    // Braked within the stop distance (with the drive's lag), at rest, idle.
    assert!(s.axes.commanded[2] > -10.5, "{:?}", s.axes.commanded);
    assert_eq!(s.state, MachineState::Idle);
    // It touches now: a second move toward the part does not start.
    cmd.push(probe_down(300.0)).unwrap();
    let s = until_probed(&mut core, &mut rings, &mut bus);
    assert_eq!(s.probe.outcome, ProbeOutcome::AlreadyTriggered);
}

#[test]
fn the_e_stop_during_a_probing_move_aborts_it_and_stops_the_axis() {
    let (mut core, mut rings, mut bus, mut cmd, inputs) = probing_core();
    cmd.push(probe_down(300.0)).unwrap();
    for _ in 0..100 {
        let due = core.next_deadline_ns();
        core.tick(due, &mut rings, &mut bus);
    }
    inputs.set(0, Some(false));
    let s = until_probed(&mut core, &mut rings, &mut bus);
    assert_eq!(s.probe.outcome, ProbeOutcome::Aborted);
    assert_eq!(s.state, MachineState::Fault);
    // The axis brakes at once (5 mm/s at 1000 mm/s²: 12.5 µm) and stays above the part.
    let z = s.axes.commanded[2];
    for _ in 0..500 {
        let due = core.next_deadline_ns();
        core.tick(due, &mut rings, &mut bus);
    }
    let rest = core.snapshot().axes.commanded[2];
    assert!(rest > -10.0 && (rest - z).abs() < 0.02, "{z} {rest}");
}

#[test]
fn a_probing_move_that_misses_ends_at_its_target() {
    let (mut core, mut rings, mut bus, mut cmd, _) = probing_core();
    cmd.push(RtCommand::Probe(ProbeRequest {
        target_mm: -5.0,
        ..match probe_down(600.0) {
            RtCommand::Probe(r) => r,
            _ => unreachable!(),
        }
    }))
    .unwrap();
    let s = until_probed(&mut core, &mut rings, &mut bus);
    assert_eq!(s.probe.outcome, ProbeOutcome::NoContact);
    assert!((s.axes.commanded[2] + 5.0).abs() < 1e-9);
}
