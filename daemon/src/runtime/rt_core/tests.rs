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
fn core_at(now_ns: u64) -> (RtCore, RtRings, sim::SimBus) {
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
    let cfg = RtCoreConfig {
        axes: AXES,
        start: AxesMm::ZERO,
        kr: Kr::new(kr),
        in_position_mm: AxesMm::ZERO,
        stop_decel_mm_s2: [1000.0; MAX_AXES],
        cycle_ns: TS_NS,
        io: Default::default(),
    };
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
