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
    CanOpenConfig, CanOpenError, CanOpenMaster, FaultReaction, HomingParams, NodeConfig, NodeId,
    ShutdownMode, SocketCanPort, SpindleNodeConfig,
};
use std::time::Duration;

use hal::serial::{SerialAxis, SerialBus, SerialConfig, SerialSpindle};

use super::config::{AxisConfig, HomingMode, SimConfig};
pub use super::config::{BusConfig, CanBusConfig, FaultReactionKey, SerialBusConfig, ShutdownKey};

/// The master settings for `axes` (validated: every axis has a node id in 1..=127).
pub fn can_config(c: &CanBusConfig, axes: &[AxisConfig]) -> Result<CanOpenConfig, CanOpenError> {
    let nodes = axes
        .iter()
        .enumerate()
        .map(|(i, a)| {
            Ok(NodeConfig {
                following_window_increments: c
                    .following_window_mm
                    .map(|mm| (mm * a.increments_per_mm).round().min(f64::from(u32::MAX)) as u32),
                max_velocity_mm_s: a.max_velocity_mm_min / 60.0,
                homing: Some(homing_params(a)),
                ..NodeConfig::new(
                    NodeId::new(a.node_id.unwrap_or(i as u8 + 1))?,
                    a.increments_per_mm,
                )
            })
        })
        .collect::<Result<_, CanOpenError>>()?;
    let spindle = match c.spindle_node {
        Some(id) => Some(SpindleNodeConfig {
            node_id: NodeId::new(id)?,
            units_per_rpm: c.spindle_units_per_rpm,
        }),
        None => None,
    };
    // The [bus] keys count ms (and bus cycles for the TPDO watch); the master takes Durations.
    let ms = |v: u32| Duration::from_millis(u64::from(v));
    let cycle = Duration::from_micros((c.cycle_ms * 1000.0).round() as u64);
    Ok(CanOpenConfig {
        master_node_id: NodeId::new(c.master_node_id)?,
        tpdo_timeout: cycle * c.tpdo_missing_ticks,
        drive_heartbeat: ms(u32::from(c.drive_heartbeat_ms)),
        heartbeat_timeout: ms(c.heartbeat_timeout_ms),
        master_heartbeat: ms(u32::from(c.master_heartbeat_ms)),
        drive_consumer_timeout: ms(u32::from(c.drive_consumer_timeout_ms)),
        sdo_timeout: ms(c.sdo_timeout_ms),
        boot_timeout: ms(c.boot_timeout_ms),
        enable_timeout: ms(c.enable_timeout_ms),
        following_error_limit_mm: c.following_error_limit_mm,
        error_frame_limit: c.error_frame_limit,
        cycle,
        shutdown: shutdown_mode(c.shutdown),
        fault_reaction: fault_reaction(c.fault_reaction),
        homing_timeout: ms(c.homing_timeout_ms),
        spindle,
        ..CanOpenConfig::new(nodes)
    })
}

/// The `[bus] shutdown` key as the masters take it.
fn shutdown_mode(k: ShutdownKey) -> ShutdownMode {
    match k {
        ShutdownKey::Disable => ShutdownMode::Disable,
        ShutdownKey::QuickStop => ShutdownMode::QuickStop,
    }
}

/// The `[bus] fault_reaction` key as the masters take it.
fn fault_reaction(k: FaultReactionKey) -> FaultReaction {
    match k {
        FaultReactionKey::QuickStop => FaultReaction::QuickStop,
        FaultReactionKey::DisableVoltage => FaultReaction::DisableVoltage,
        FaultReactionKey::Hold => FaultReaction::Hold,
    }
}

/// The drive's homing settings of axis `a` in drive units (docs/buses.md#homing): the home
/// offset 0x607C is `reference_mm`, the position the axis has at its home position.
pub fn homing_params(a: &AxisConfig) -> HomingParams {
    let inc = a.increments_per_mm;
    let units = |v: f64| (v * inc).round().clamp(1.0, f64::from(u32::MAX)) as u32;
    let search_mm_s = a.homing_speed_mm_s();
    let zero_mm_s = a
        .homing_zero_speed_mm_min
        .map_or(search_mm_s / 10.0, |v| v / 60.0);
    HomingParams {
        method: a
            .can_homing_method
            .unwrap_or(if a.homing_direction < 0 { 21 } else { 19 }),
        offset_increments: (a.reference_mm * inc)
            .round()
            .clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32,
        search_speed: units(search_mm_s),
        zero_speed: units(zero_mm_s),
        accel: units(a.homing_accel_mm_s2.unwrap_or(a.max_accel_mm_s2)),
    }
}

/// The machine's I/O as the buses take it (docs/io.md).
#[derive(Clone, Debug, Default)]
pub struct IoWiring {
    pub map: hal::io::IoMap,
    /// The simulated machine's inputs, and the handle `cncctl io sim-set` flips them with.
    pub sim: Vec<sim::io::SimInput>,
    pub sim_handle: Option<sim::io::SimInputs>,
    /// What the simulated probe touches.
    pub sim_probe: Option<sim::probe::SimProbe>,
    /// Heartbeat consumer time of the CiA 401 modules, ms.
    pub module_consumer_ms: u16,
}

impl IoWiring {
    pub fn of(config: &super::config::Config) -> IoWiring {
        IoWiring {
            map: super::io_setup::io_map(config),
            sim: super::io_setup::sim_inputs(config)
                .into_iter()
                .map(|p| sim::io::SimInput {
                    rest: p.rest,
                    switch: p.switch,
                    probe: p.probe,
                })
                .collect(),
            sim_handle: None,
            sim_probe: Some(super::io_setup::sim_probe(config)),
            module_consumer_ms: config.io().module_consumer_timeout_ms,
        }
    }
}

/// Why the configured bus could not be opened (the message names the interface or port).
#[derive(Debug, thiserror::Error)]
pub enum OpenBusError {
    #[error(transparent)]
    Can(#[from] hal::canopen::CanOpenError),
    #[error(transparent)]
    Record(#[from] hal::candump::RecordError),
    #[error(transparent)]
    Serial(#[from] hal::serial::SerialError),
}

impl OpenBusError {
    /// Stable code of the underlying error (tests and logs match it).
    pub fn code(&self) -> &'static str {
        match self {
            OpenBusError::Can(e) => e.code(),
            OpenBusError::Record(e) => e.code(),
            OpenBusError::Serial(e) => e.code(),
        }
    }
}

/// Opens the configured bus for `axes`.
pub fn open_bus(
    bus: &BusConfig,
    axes: &[AxisConfig],
    sim: &SimConfig,
    io: &IoWiring,
) -> Result<Box<dyn hal::DriveBus>, OpenBusError> {
    match bus {
        BusConfig::Sim { cycle_ms } => {
            let params = sim::SimDriveParams {
                kv_per_s: sim.kv_per_s,
                following_window_mm: sim.following_window_mm,
                ..Default::default()
            };
            let start: Vec<f64> = axes.iter().map(|a| a.home_mm).collect();
            let mut bus = sim::SimBus::new(params, &start)
                .with_spindle_ramp(sim.spindle_ramp_rpm_s)
                .with_cycle_s(cycle_ms * 1e-3)
                .with_inputs(io.sim.clone())
                .with_probe(io.sim_probe.clone());
            if let Some(h) = &io.sim_handle {
                bus = bus.with_input_handle(h.clone());
            }
            for (i, a) in axes.iter().enumerate() {
                let at = a.sim_home_switch_at_mm();
                bus = bus.with_home_switch(i, at, f64::from(a.homing_direction));
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
            let master = can_config(c, axes).and_then(|cfg| {
                let cfg = CanOpenConfig {
                    io: io.map.clone(),
                    io_consumer_timeout: Duration::from_millis(u64::from(io.module_consumer_ms)),
                    ..cfg
                };
                CanOpenMaster::new(port, &c.interface, cfg)
            })?;
            Ok(Box::new(master))
        }
        BusConfig::Serial(s) => {
            let cfg = SerialConfig {
                baud: s.baud,
                reply_timeout_ticks: s.reply_timeout_ticks,
                enable_timeout_ticks: s.enable_timeout_ticks,
                cycle: Duration::from_secs_f64(s.cycle_ms / 1000.0),
                shutdown: shutdown_mode(s.shutdown),
                fault_reaction: fault_reaction(s.fault_reaction),
                // Reference runs need protocol version 3; without them the link stays on the
                // version older units speak.
                homing: axes.iter().any(|a| a.homing == HomingMode::Required),
                io: io.map.clone(),
                spindle: s.spindle_node.map(|node_id| SerialSpindle {
                    node_id,
                    units_per_rpm: s.spindle_units_per_rpm,
                }),
                ..SerialConfig::new(
                    &s.port,
                    axes.iter()
                        .enumerate()
                        .map(|(i, a)| SerialAxis {
                            max_velocity_mm_s: a.max_velocity_mm_min / 60.0,
                            ..SerialAxis::new(a.node_id.unwrap_or(i as u8 + 1), a.increments_per_mm)
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

    /// The CAN section of `toml` (after `[bus]\nkind = 'can'\ninterface = 'vcan0'\n`).
    fn can_section(extra: &str) -> (CanBusConfig, Vec<AxisConfig>) {
        let c = Config::parse(
            &format!("[bus]\nkind = 'can'\ninterface = 'vcan0'\n{extra}\n"),
            Path::new("m.toml"),
        )
        .unwrap();
        let BusConfig::Can(can) = c.bus else {
            panic!("{:?}", c.bus)
        };
        (can, c.axes)
    }

    /// The message of the configuration error of `toml`.
    fn config_error(toml: &str) -> String {
        Config::parse(toml, Path::new("m.toml"))
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn can_section_defaults_reach_the_master() {
        let (can, axes) = can_section("record = '/tmp/c.log'\nfollowing_window_mm = 5");
        assert_eq!(can.tpdo_missing_ticks, 25);
        let m = can_config(&can, &axes).unwrap();
        assert_eq!(m.nodes.len(), 3);
        assert_eq!(m.nodes[2].node_id.get(), 3);
        assert_eq!(m.nodes[0].following_window_increments, Some(50_000));
        // The axis speed limit bounds the hand-over step at enable; the cycle is 4 ms.
        assert_eq!(m.nodes[0].max_velocity_mm_s, 200.0);
        assert_eq!(m.cycle, Duration::from_millis(4));
        assert_eq!(m.shutdown, ShutdownMode::Disable);
        let (can, axes) = can_section("shutdown = 'quick_stop'");
        assert_eq!(
            can_config(&can, &axes).unwrap().shutdown,
            ShutdownMode::QuickStop
        );
    }

    /// The documented keys (docs/buses.md) keep their units: ms, and bus cycles for the
    /// TPDO watch; the master gets them as Durations.
    #[test]
    fn can_timeout_keys_in_ms_and_cycles_become_durations() {
        let (can, axes) = can_section(
            "cycle_ms = 2\ntpdo_missing_ticks = 50\ndrive_heartbeat_ms = 150\n\
             heartbeat_timeout_ms = 1000\nmaster_heartbeat_ms = 0\n\
             drive_consumer_timeout_ms = 2000\nsdo_timeout_ms = 500\nboot_timeout_ms = 4000\n\
             enable_timeout_ms = 3000\nhoming_timeout_ms = 9000",
        );
        let m = can_config(&can, &axes).unwrap();
        let ms = Duration::from_millis;
        assert_eq!(
            (
                m.cycle,
                m.tpdo_timeout,
                m.drive_heartbeat,
                m.heartbeat_timeout
            ),
            (ms(2), ms(100), ms(150), ms(1000))
        );
        assert_eq!(
            (m.master_heartbeat, m.drive_consumer_timeout, m.sdo_timeout),
            (Duration::ZERO, ms(2000), ms(500))
        );
        assert_eq!(
            (m.boot_timeout, m.enable_timeout, m.homing_timeout),
            (ms(4000), ms(3000), ms(9000))
        );
    }

    /// Every bus kind takes cycle_ms: whole ms from 1 to 10 (the serial protocol: 4 only).
    #[test]
    fn cycle_ms_is_whole_ms_from_1_to_10() {
        for kind in ["kind = 'can'\ninterface = 'vcan0'", "kind = 'sim'"] {
            for ms in ["0", "11", "3.5", "-4", "nan"] {
                let e = config_error(&format!("[bus]\n{kind}\ncycle_ms = {ms}\n"));
                assert!(
                    e.contains("bus.cycle_ms")
                        && e.contains("whole number of milliseconds from 1 to 10"),
                    "{e}"
                );
            }
            for ms in 1..=10u64 {
                let c = Config::parse(
                    &format!("[bus]\n{kind}\ncycle_ms = {ms}\n"),
                    Path::new("m.toml"),
                )
                .unwrap();
                assert_eq!(c.bus.cycle_ns(), ms * 1_000_000);
                if let BusConfig::Can(can) = &c.bus {
                    let m = can_config(can, &c.axes).unwrap();
                    assert_eq!(m.cycle, Duration::from_millis(ms));
                }
            }
        }
        let e = config_error("[bus]\nkind = 'serial'\nport = '/dev/null'\ncycle_ms = 2\n");
        assert!(e.contains("serial protocol's cycle is 4 ms"), "{e}");
    }

    #[test]
    fn can_section_names_unknown_keys_and_missing_node_ids() {
        let e = config_error("[bus]\nkind = 'can'\ninterface = 'vcan0'\ntpdo_timeout = 3\n");
        assert!(e.contains("tpdo_timeout"), "{e}");
        let e = config_error("[[axes]]\nname = 'X'\n[bus]\nkind = 'can'\ninterface = 'vcan0'\n");
        assert!(e.contains("axes[0].node_id"), "{e}");
    }

    /// The spindle drive: node id and scaling reach the master; bad values name the key.
    #[test]
    fn can_spindle_keys_reach_the_master_and_bad_ones_are_named() {
        let (can, axes) = can_section("spindle_node = 10\nspindle_units_per_rpm = 10");
        assert_eq!(
            can_config(&can, &axes).unwrap().spindle,
            Some(SpindleNodeConfig {
                node_id: NodeId::new(10).unwrap(),
                units_per_rpm: 10.0
            })
        );
        let without = CanBusConfig {
            spindle_node: None,
            ..can
        };
        assert_eq!(can_config(&without, &axes).unwrap().spindle, None);
        for (bad, key) in [
            ("spindle_node = 3", "node 3 is the drive of axis Z"),
            ("spindle_node = 127", "equals bus.master_node_id"),
            ("spindle_node = 0", "outside 1..127"),
            (
                "spindle_node = 9\nspindle_units_per_rpm = -1",
                "bus.spindle_units_per_rpm",
            ),
        ] {
            let e = config_error(&format!(
                "[bus]\nkind = 'can'\ninterface = 'vcan0'\n{bad}\n"
            ));
            assert!(e.contains(key), "{bad}: {e}");
        }
    }

    #[test]
    fn homing_and_fault_reaction_keys_reach_the_master() {
        let c = Config::parse(
            "[[axes]]\nname = 'X'\nnode_id = 1\nincrements_per_mm = 1000\nreference_mm = -2.5\n\
             homing_speed_mm_min = 600\nhoming_accel_mm_s2 = 50\n\
             [[axes]]\nname = 'Y'\nnode_id = 2\nhoming_direction = 1\ncan_homing_method = 37\n\
             [bus]\nkind = 'can'\ninterface = 'vcan0'\nfault_reaction = 'disable_voltage'\n\
             homing_timeout_ms = 9000\n",
            Path::new("m.toml"),
        )
        .unwrap();
        let BusConfig::Can(can) = &c.bus else {
            panic!()
        };
        let m = can_config(can, &c.axes).unwrap();
        assert_eq!(m.fault_reaction, FaultReaction::DisableVoltage);
        assert_eq!(m.homing_timeout, Duration::from_millis(9000));
        // 10 mm/s, a tenth of it leaving the switch, 50 mm/s², at 1000 increments/mm.
        assert_eq!(
            m.nodes[0].homing,
            Some(HomingParams {
                method: 21,
                offset_increments: -2500,
                search_speed: 10_000,
                zero_speed: 1000,
                accel: 50_000,
            })
        );
        assert_eq!(m.nodes[1].homing.map(|h| h.method), Some(37));
        let d = Config::parse(
            "[bus]\nkind = 'can'\ninterface = 'vcan0'\n",
            Path::new("m.toml"),
        )
        .unwrap();
        let BusConfig::Can(can) = &d.bus else {
            panic!()
        };
        let m = can_config(can, &d.axes).unwrap();
        assert_eq!(m.fault_reaction, FaultReaction::QuickStop);
        assert_eq!(m.nodes[0].homing.map(|h| h.method), Some(21));
        for (bad, key) in [
            (
                "[bus]\nkind = 'can'\ninterface = 'v'\nhoming_timeout_ms = 0",
                "bus.homing_timeout_ms",
            ),
            (
                "[bus]\nkind = 'can'\ninterface = 'v'\nfault_reaction = 'coast'",
                "coast",
            ),
            (
                "[[axes]]\nname = 'X'\nhoming_accel_mm_s2 = -1",
                "axes[0].homing_accel_mm_s2",
            ),
            (
                "[[axes]]\nname = 'X'\nhoming_zero_speed_mm_min = 0",
                "axes[0].homing_zero_speed_mm_min",
            ),
        ] {
            let e = Config::parse(bad, Path::new("m.toml")).unwrap_err();
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
                cycle_ms: 4.0,
                enable_timeout_ticks: 500,
                shutdown: ShutdownKey::Disable,
                fault_reaction: FaultReactionKey::QuickStop,
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
