//! Rotary axes (SPEC §5, docs/lathe.md "Rotary axes"): a rotary axis is positioned in degrees;
//! F of a block that moves only rotary axes is in thousands of encoder pulses per minute; in a
//! block that moves linear axes too, F is the path speed of the linear axes and the rotary
//! axes take the same time. Run through the daemon's pipeline and RT core in the harness.

use daemon::runtime::clock::SimClock;
use daemon::runtime::config::{AxisConfig, Config};
use daemon::runtime::harness::{Harness, JobEnd};
use daemon::runtime::rt::MachineState;
use kernel::constants::Constants;

/// Tick period of the default configuration, s.
const TS_S: f64 = 0.004;
/// 360 000 pulses per revolution: 1000 pulses (one thousand) per degree.
const PULSES_PER_REV: f64 = 360_000.0;

/// X linear, A rotary (degrees), both at 0.
fn machine() -> (Harness, tests::Recording) {
    let mut cfg: Config = tests::test_config();
    cfg.axes = vec![
        AxisConfig::new('X'),
        AxisConfig {
            max_velocity_mm_min: 36_000.0, // degrees per minute
            max_accel_mm_s2: 2_000.0,      // degrees per s²
            rotary_pulses_per_rev: Some(PULSES_PER_REV),
            ..AxisConfig::new('A')
        },
    ];
    let mut c = Constants::new();
    c.set(0, 1.0); // X
    c.set(1, 7.0); // A
    for r in 2..6 {
        c.set(r, 0.0);
    }
    c.set(67, 1.0);
    std::fs::create_dir_all(&cfg.storage.dir).unwrap();
    daemon::runtime::storage::save_constants(&cfg.storage.constants_path(), &c).unwrap();
    let bus = sim::SimBus::new(sim::SimDriveParams::default(), &[0.0, 0.0]);
    let (bus, record) = tests::RecordingBus::new(bus);
    let h = Harness::new(cfg, Box::new(bus), SimClock::exact()).unwrap();
    (h, record)
}

/// Top speed of X and A (units per second) over the run of `text`.
fn top_speeds(h: &mut Harness, record: &tests::Recording, text: &str) -> (f64, f64) {
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    record.lock().unwrap().clear();
    let end = h.run_program(text, 1_000_000).unwrap();
    assert!(matches!(end, JobEnd::Finished), "{end:?}");
    let r = tests::max_rates(&record.lock().unwrap(), 2, TS_S);
    (r[0].0, r[1].0)
}

fn within(a: f64, b: f64, share: f64) -> bool {
    (a - b).abs() <= share * b.abs()
}

/// A alone: F3600 = 3600 thousand pulses per minute = 3600 °/min with 1000 pulses per degree,
/// 60 °/s. With half the pulses per degree the same F turns twice as fast (see below).
#[test]
fn rotary_only_feed_is_in_thousands_of_pulses_per_minute() {
    let (mut h, record) = machine();
    let (x, a) = top_speeds(&mut h, &record, "N10 G1 A180 F3600\n");
    assert_eq!(x, 0.0);
    assert!(within(a, 60.0, 0.01), "A top speed {a} °/s");
    // Fsk: the speed at R100 of the work on A is F·2πR / thousands of pulses per revolution.
    let fsk = kernel::program::rotary_surface_speed_mm_min(3600.0, 100.0, PULSES_PER_REV / 1e3);
    assert!(within(
        fsk,
        a * 60.0 * std::f64::consts::PI * 100.0 / 180.0,
        1e-9
    ));
}

/// X and A together: F600 is the speed of X (the linear axes), 10 mm/s; A takes the same time:
/// X100 A180 → A at 18 °/s.
#[test]
fn mixed_move_feeds_the_linear_axes_and_the_rotary_follows() {
    let (mut h, record) = machine();
    let (x, a) = top_speeds(&mut h, &record, "N10 G1 X100 A180 F600\n");
    assert!(within(x, 10.0, 0.01), "X top speed {x} mm/s");
    assert!(within(a, 18.0, 0.01), "A top speed {a} °/s");
    let end = h.snapshot().axes.commanded;
    assert!((end[0] - 100.0).abs() < 1e-9 && (end[1] - 180.0).abs() < 1e-9);
}

/// A rotary axis cannot move in an arc (the arc is in the plane of linear axes): refused at
/// validation with its block.
#[test]
fn rotary_axis_in_an_arc_is_refused_with_the_block() {
    let (mut h, _) = machine();
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    let arc = "N10 G1 X10 F600\nN20 G2 X20 A90 I5 J0\n";
    tests::assert_refused_at(&mut h, arc, 20, "an arc with A");
}
