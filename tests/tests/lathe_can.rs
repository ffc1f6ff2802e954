//! The manual's lathe example (issue #17, SPEC §5, §6) over CANopen: the daemon's pipeline and
//! RT core in the single-threaded harness with its CANopen master on an in-memory bus (as
//! `daemon_can.rs`): X and Z are CSP drives (nodes 1, 2), the spindle a CSV drive (node 3)
//! whose speed ramps at 1000 rpm/s and comes back over the bus. The feed per revolution
//! follows the spindle's actual speed as the bus reports it.

use std::path::Path;
use std::sync::{Arc, Mutex};

mod lathe_common;

use daemon::runtime::buses::{BusConfig, can_config};
use daemon::runtime::clock::SimClock;
use daemon::runtime::config::Config;
use daemon::runtime::harness::Harness;
use hal::canopen::CanOpenMaster;
use sim::SimDriveParams;
use sim::can_node::CanNode;
use sim::cia402_drive::Cia402Drive;
use tests::can_sim::{Bus, Port};

const INC_PER_MM: f64 = 10_000.0;

/// A lathe X (diameter programming; the drive stands at radius 150 = Ø300), Z at 100, gears
/// M41..M44, R67 = 1, R329 d3 = 3, spindle on node 3 (1 velocity unit per rpm).
fn lathe() -> Harness {
    let mut toml = String::new();
    for (i, name) in ['X', 'Z'].iter().enumerate() {
        toml.push_str(&format!(
            "[[axes]]\nname = '{name}'\nnode_id = {}\nincrements_per_mm = {INC_PER_MM}\n\
             max_velocity_mm_min = 6000\n\n",
            i + 1
        ));
    }
    toml.push_str("[kr]\nradius_input = 'diameter'\n");
    for (m, p) in tests::LATHE_GEARS {
        toml.push_str(&format!("[[kr.gears]]\nmax_rpm = {p}\nm_code = {m}\n"));
    }
    toml.push_str("[bus]\nkind = 'can'\ninterface = 'mem0'\nfollowing_window_mm = 50\n");
    toml.push_str("spindle_node = 3\nspindle_units_per_rpm = 1\n");
    let mut cfg = Config::parse(&toml, Path::new("lathe-can.toml")).unwrap();
    let base = tests::test_config();
    cfg.storage = base.storage;
    cfg.rt = base.rt;
    tests::save_lathe_constants(&cfg, true);

    let BusConfig::Can(can) = &cfg.bus else {
        panic!("{:?}", cfg.bus)
    };
    let master_cfg = can_config(can, &cfg.axes).unwrap();
    let mut spindle = Cia402Drive::new(SimDriveParams::default(), 1.0, 0.0);
    spindle.velocity_ramp_units_s2 = 1000.0; // rpm/s
    let nodes = vec![
        CanNode::new(
            1,
            Cia402Drive::new(SimDriveParams::default(), INC_PER_MM, 150.0),
        ),
        CanNode::new(
            2,
            Cia402Drive::new(SimDriveParams::default(), INC_PER_MM, 100.0),
        ),
        CanNode::new(3, spindle),
    ];
    let bus = Arc::new(Mutex::new(Bus {
        nodes,
        ..Bus::default()
    }));
    let master = CanOpenMaster::new(Port(bus), "mem0", master_cfg).unwrap();
    Harness::new(cfg, Box::new(master), SimClock::exact()).unwrap()
}

/// `N10 G0 X300 Z100 M44 M3 S100` / `N15 Z-1` / `N20 G96 G1 F200 S90 X50`: along the cut
/// v = 2π·n·r within 1 % (n the speed the spindle node reports) and the feed = n · 0.2 mm/rev
/// within 1 % (n of the tick the RT core fed from), every tick from Ø290 to Ø60.
#[test]
fn manual_lathe_example_over_can_feeds_per_revolution_of_the_spindle_node() {
    lathe_common::run_manual_example(lathe());
}
