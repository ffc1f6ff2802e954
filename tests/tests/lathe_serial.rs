//! The manual's lathe example (issue #17) over the serial drive link: the daemon's pipeline and
//! RT core in the single-threaded harness with its serial bus (`hal::serial::SerialBus`) on a
//! pseudo-terminal whose other end is served, in the same thread between ticks, by the
//! simulated drive unit (`sim::serial_drive`, X, Z and a spindle drive ramping at 1000 rpm/s).
//! No second thread and no wall clock: each tick the unit answers the request of the tick
//! before, as a real unit does. The feed per revolution follows the spindle's actual speed as
//! the unit reports it.

mod lathe_common;
mod serial_common;

use daemon::runtime::clock::SimClock;
use daemon::runtime::config::{AxisConfig, Config, RadiusInputConfig};
use daemon::runtime::harness::Harness;
use hal::serial::{SerialAxis, SerialBus, SerialConfig, SerialSpindle};
use serial_common::{Line, UnitSide};
use sim::SimDriveParams;
use sim::cia402_drive::Cia402Drive;
use sim::serial_drive::SerialDriveUnit;

const INC_PER_MM: f64 = 10_000.0;

/// The lathe of `lathe_per_rev.rs` (X as a diameter at Ø300, Z100, gears M41..M44, R67 = 1,
/// R329 d3 = 3) on the serial line.
fn lathe() -> Harness {
    let mut cfg: Config = tests::test_config();
    cfg.axes = vec![AxisConfig::new('X'), AxisConfig::new('Z')];
    for a in &mut cfg.axes {
        a.max_velocity_mm_min = 6000.0;
    }
    cfg.axes[0].home_mm = 150.0;
    cfg.axes[1].home_mm = 100.0;
    cfg.kr.radius_input = RadiusInputConfig::Diameter;
    cfg.kr.gears = tests::lathe_gears();
    // The harness runs a serial unit under a simulated-machine configuration: its own I/O
    // set is not wired here.
    cfg.io = Some(Default::default());
    tests::save_lathe_constants(&cfg, true);

    let drives = [150.0, 100.0]
        .iter()
        .map(|&mm| Cia402Drive::new(SimDriveParams::default(), INC_PER_MM, mm))
        .collect();
    let mut unit = SerialDriveUnit::new(drives);
    let mut spindle = Cia402Drive::new(SimDriveParams::default(), 1.0, 0.0);
    spindle.velocity_ramp_units_s2 = 1000.0; // rpm/s
    unit.spindle = Some(spindle);
    let (side, path) = UnitSide::open(unit);
    let axes = (1..=2)
        .map(|node_id| SerialAxis::new(node_id, INC_PER_MM))
        .collect();
    let mut scfg = SerialConfig::new(&path, axes);
    scfg.spindle = Some(SerialSpindle {
        node_id: 3,
        units_per_rpm: 1.0,
    });
    let line = Line {
        bus: Box::new(SerialBus::open(scfg).unwrap()),
        side,
    };
    Harness::new(cfg, Box::new(line), SimClock::exact()).unwrap()
}

/// `N10 G0 X300 Z100 M44 M3 S100` / `N15 Z-1` / `N20 G96 G1 F200 S90 X50` over serial: along
/// the cut (Ø290 .. Ø60) v = 2π·n·r within 1 % with n as the unit reports it, and the feed
/// = n · 0.2 mm/rev within 1 % (n of the tick the RT core fed from), every tick.
#[test]
fn manual_lathe_example_over_serial_feeds_per_revolution_of_the_spindle_drive() {
    lathe_common::run_manual_example(lathe());
}
