//! Bus selection: builds the configured [`hal::DriveBus`] backend.
//!
//! ```toml
//! [bus]
//! kind = "can"            # or "sim" (default), "serial"
//! interface = "can0"
//! record = "/var/log/cnc/can.log"   # optional: candump log of all traffic
//! spindle_node = 10       # optional: the spindle drive (CiA 402 velocity mode)
//! spindle_units_per_rpm = 1
//! ```
//! Every key is listed in `docs/buses.md`.

use hal::canopen::{
    CanOpenConfig, CanOpenMaster, NodeConfig, ShutdownMode, SocketCanPort, SpindleNodeConfig,
};
use hal::serial::{SerialAxis, SerialBus, SerialConfig, SerialSpindle};

use super::config::{AxisConfig, HomingMode, SimConfig};
pub use super::config::{BusConfig, CanBusConfig, SerialBusConfig, ShutdownKey};

/// The master settings for `axes` (validated: every axis has a node id).
pub fn can_config(c: &CanBusConfig, axes: &[AxisConfig]) -> CanOpenConfig {
    let nodes = axes
        .iter()
        .enumerate()
        .map(|(i, a)| NodeConfig {
            node_id: a.node_id.unwrap_or(i as u8 + 1),
            increments_per_mm: a.increments_per_mm,
            following_window_increments: c
                .following_window_mm
                .map(|mm| (mm * a.increments_per_mm).round().min(f64::from(u32::MAX)) as u32),
            max_velocity_mm_s: a.max_velocity_mm_min / 60.0,
        })
        .collect();
    CanOpenConfig {
        master_node_id: c.master_node_id,
        tpdo_missing_ticks: c.tpdo_missing_ticks,
        drive_heartbeat_ms: c.drive_heartbeat_ms,
        heartbeat_timeout_ms: c.heartbeat_timeout_ms,
        master_heartbeat_ms: c.master_heartbeat_ms,
        drive_consumer_timeout_ms: c.drive_consumer_timeout_ms,
        sdo_timeout_ms: c.sdo_timeout_ms,
        boot_timeout_ms: c.boot_timeout_ms,
        enable_timeout_ms: c.enable_timeout_ms,
        following_error_limit_mm: c.following_error_limit_mm,
        error_frame_limit: c.error_frame_limit,
        cycle_us: c.cycle_ms * 1000,
        shutdown: match c.shutdown {
            ShutdownKey::Disable => ShutdownMode::Disable,
            ShutdownKey::QuickStop => ShutdownMode::QuickStop,
        },
        spindle: c.spindle_node.map(|node_id| SpindleNodeConfig {
            node_id,
            units_per_rpm: c.spindle_units_per_rpm,
        }),
        ..CanOpenConfig::new(nodes)
    }
}

/// Opens the configured bus for `axes`.
pub fn open_bus(
    bus: &BusConfig,
    axes: &[AxisConfig],
    sim: &SimConfig,
) -> Result<Box<dyn hal::DriveBus>, String> {
    match bus {
        BusConfig::Sim {} => {
            let params = sim::SimDriveParams {
                kv_per_s: sim.kv_per_s,
                following_window_mm: sim.following_window_mm,
                ..Default::default()
            };
            let start: Vec<f64> = axes.iter().map(|a| a.home_mm).collect();
            let mut bus =
                sim::SimBus::new(params, &start).with_spindle_ramp(sim.spindle_ramp_rpm_s);
            for (i, a) in axes.iter().enumerate() {
                if let Some(at) = a.sim_home_switch_mm {
                    bus = bus.with_home_switch(i, at, f64::from(a.homing_direction));
                }
            }
            Ok(Box::new(bus))
        }
        BusConfig::Can(c) => {
            let mut port = SocketCanPort::open(&c.interface)?;
            if let Some(path) = &c.record {
                // The writer thread ends when the bus (and its tap) is dropped.
                let (tap, _writer) = hal::candump::start(path, &c.interface)?;
                port = port.with_recording(tap);
            }
            let master = CanOpenMaster::new(port, &c.interface, can_config(c, axes))?;
            Ok(Box::new(master))
        }
        BusConfig::Serial(s) => {
            let cfg = SerialConfig {
                baud: s.baud,
                reply_timeout_ticks: s.reply_timeout_ticks,
                enable_timeout_ticks: s.enable_timeout_ticks,
                // Reference runs need protocol version 3; without them the link stays on the
                // version older units speak.
                homing: axes.iter().any(|a| a.homing == HomingMode::Required),
                spindle: s.spindle_node.map(|node_id| SerialSpindle {
                    node_id,
                    units_per_rpm: s.spindle_units_per_rpm,
                }),
                ..SerialConfig::new(
                    &s.port,
                    axes.iter()
                        .enumerate()
                        .map(|(i, a)| SerialAxis {
                            node_id: a.node_id.unwrap_or(i as u8 + 1),
                            increments_per_mm: a.increments_per_mm,
                        })
                        .collect(),
                )
            };
            Ok(Box::new(SerialBus::open(cfg)?))
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::super::config::Config;
    use super::*;

    #[test]
    fn can_section_parses_with_defaults_and_names_bad_keys() {
        let c = Config::parse(
            "[bus]\nkind = 'can'\ninterface = 'vcan0'\nrecord = '/tmp/c.log'\nfollowing_window_mm = 5\n",
            Path::new("m.toml"),
        )
        .unwrap();
        let BusConfig::Can(can) = &c.bus else {
            panic!("{:?}", c.bus)
        };
        assert_eq!(can.tpdo_missing_ticks, 25);
        let m = can_config(can, &c.axes);
        assert_eq!(m.nodes.len(), 3);
        assert_eq!(m.nodes[2].node_id, 3);
        assert_eq!(m.nodes[0].following_window_increments, Some(50_000));
        // The axis speed limit bounds the hand-over step at enable; the cycle is 4 ms.
        assert_eq!(m.nodes[0].max_velocity_mm_s, 200.0);
        assert_eq!(m.cycle_us, 4000);
        assert_eq!(m.shutdown, ShutdownMode::Disable);
        let c = Config::parse(
            "[bus]\nkind = 'can'\ninterface = 'vcan0'\nshutdown = 'quick_stop'\n",
            Path::new("m.toml"),
        )
        .unwrap();
        let BusConfig::Can(can) = &c.bus else {
            panic!()
        };
        assert_eq!(can_config(can, &c.axes).shutdown, ShutdownMode::QuickStop);
        for (ms, what) in [
            (0, "outside 1..10"),
            (11, "outside 1..10"),
            (2, "real-time tick"),
        ] {
            let e = Config::parse(
                &format!("[bus]\nkind = 'can'\ninterface = 'vcan0'\ncycle_ms = {ms}\n"),
                Path::new("m.toml"),
            )
            .unwrap_err();
            assert!(
                e.to_string().contains("bus.cycle_ms") && e.to_string().contains(what),
                "{e}"
            );
        }

        let e = Config::parse(
            "[bus]\nkind = 'can'\ninterface = 'vcan0'\ntpdo_timeout = 3\n",
            Path::new("m.toml"),
        )
        .unwrap_err();
        assert!(e.to_string().contains("tpdo_timeout"), "{e}");
        let e = Config::parse(
            "[[axes]]\nname = 'X'\n[bus]\nkind = 'can'\ninterface = 'vcan0'\n",
            Path::new("m.toml"),
        )
        .unwrap_err();
        assert!(e.to_string().contains("axes[0].node_id"), "{e}");

        // The spindle drive: node id and scaling reach the master; bad values name the key.
        let c = Config::parse(
            "[bus]\nkind = 'can'\ninterface = 'vcan0'\nspindle_node = 10\nspindle_units_per_rpm = 10\n",
            Path::new("m.toml"),
        )
        .unwrap();
        let BusConfig::Can(can) = &c.bus else {
            panic!()
        };
        assert_eq!(
            can_config(can, &c.axes).spindle,
            Some(SpindleNodeConfig {
                node_id: 10,
                units_per_rpm: 10.0
            })
        );
        assert_eq!(
            can_config(
                &CanBusConfig {
                    spindle_node: None,
                    ..can.clone()
                },
                &c.axes
            )
            .spindle,
            None
        );
        for (bad, key) in [
            ("spindle_node = 3", "node 3 is the drive of axis Z"),
            ("spindle_node = 127", "equals bus.master_node_id"),
            ("spindle_node = 0", "outside 1..127"),
            (
                "spindle_node = 9\nspindle_units_per_rpm = -1",
                "bus.spindle_units_per_rpm",
            ),
        ] {
            let e = Config::parse(
                &format!("[bus]\nkind = 'can'\ninterface = 'vcan0'\n{bad}\n"),
                Path::new("m.toml"),
            )
            .unwrap_err();
            assert!(e.to_string().contains(key), "{bad}: {e}");
        }
    }

    #[test]
    fn serial_section_parses() {
        let c = Config::parse(
            "[bus]\nkind = 'serial'\nport = '/dev/ttyUSB0'\n",
            Path::new("m.toml"),
        )
        .unwrap();
        assert_eq!(
            c.bus,
            BusConfig::Serial(SerialBusConfig {
                port: "/dev/ttyUSB0".into(),
                baud: 460_800,
                reply_timeout_ticks: 25,
                enable_timeout_ticks: 500,
                spindle_node: None,
                spindle_units_per_rpm: 1.0,
            })
        );
        let c = Config::parse(
            "[bus]\nkind = 'serial'\nport = '/dev/ttyUSB0'\nspindle_node = 4\nspindle_units_per_rpm = 10\n",
            Path::new("m.toml"),
        )
        .unwrap();
        let BusConfig::Serial(s) = &c.bus else {
            panic!()
        };
        assert_eq!((s.spindle_node, s.spindle_units_per_rpm), (Some(4), 10.0));
        let e = Config::parse(
            "[bus]\nkind = 'serial'\nport = 'x'\nspindle_node = 2\n",
            Path::new("m.toml"),
        )
        .unwrap_err();
        assert!(
            e.to_string()
                .contains("bus.spindle_node: node 2 is the drive of axis Y"),
            "{e}"
        );
        let e = Config::parse("[bus]\nkind = 'sim'\nport = 'x'\n", Path::new("m.toml"));
        assert!(e.is_err(), "unknown key of the sim bus: {e:?}");
        let e = Config::parse("[bus]\nkind = 'usb'\n", Path::new("m.toml")).unwrap_err();
        assert!(e.to_string().contains("usb"), "{e}");
    }
}
