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

use std::path::PathBuf;

use hal::canopen::{CanOpenConfig, CanOpenMaster, NodeConfig, SocketCanPort, SpindleNodeConfig};
use hal::serial::{SerialAxis, SerialBus, SerialConfig, SerialSpindle};
use serde::Deserialize;

use super::config::{AxisConfig, SimConfig};

/// `[bus]` section of the configuration.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum BusConfig {
    /// The built-in simulated machine (default). A struct variant, so that serde rejects
    /// unknown keys next to `kind = "sim"` (a unit variant would ignore them).
    Sim {},
    /// CANopen CiA 402 drives on a SocketCAN interface; node ids from `axes[i].node_id`.
    Can(CanBusConfig),
    /// One drive unit on a serial port (`hal/SERIAL_PROTOCOL.md`).
    Serial(SerialBusConfig),
}

/// `[bus] kind = "can"`. Times in ms are converted to 4 ms ticks.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CanBusConfig {
    /// SocketCAN interface (`can0`, `vcan0`).
    pub interface: String,
    /// Append all CAN traffic to this file in candump log format (`candump -l`).
    #[serde(default)]
    pub record: Option<PathBuf>,
    /// The controller's own node id (its heartbeat is watched by the drives).
    #[serde(default = "default_master_node_id")]
    pub master_node_id: u8,
    /// Consecutive ticks without a drive's TPDO before it is a fault.
    #[serde(default = "default_tpdo_missing_ticks")]
    pub tpdo_missing_ticks: u32,
    /// Heartbeat period the drives are told to produce (0x1017).
    #[serde(default = "default_drive_heartbeat_ms")]
    pub drive_heartbeat_ms: u16,
    /// A drive heartbeat older than this is a fault.
    #[serde(default = "default_heartbeat_timeout_ms")]
    pub heartbeat_timeout_ms: u32,
    /// Period of the controller's heartbeat (0: none, drives do not watch it).
    #[serde(default = "default_master_heartbeat_ms")]
    pub master_heartbeat_ms: u16,
    /// The drives fault when the controller's heartbeat is older than this (0x1016).
    #[serde(default = "default_drive_consumer_timeout_ms")]
    pub drive_consumer_timeout_ms: u16,
    /// Answer time per start-up SDO request.
    #[serde(default = "default_sdo_timeout_ms")]
    pub sdo_timeout_ms: u32,
    /// Time from NMT reset to boot-up, and from NMT start to the first TPDO.
    #[serde(default = "default_boot_timeout_ms")]
    pub boot_timeout_ms: u32,
    /// Time for the CiA 402 enable sequence.
    #[serde(default = "default_enable_timeout_ms")]
    pub enable_timeout_ms: u32,
    /// Following-error window written to the drives (0x6065), mm; unset keeps the drives'.
    #[serde(default)]
    pub following_window_mm: Option<f64>,
    /// The controller's own following-error check (setpoint − actual), mm; unset: off.
    #[serde(default)]
    pub following_error_limit_mm: Option<f64>,
    /// Error frames tolerated (decaying by one per 40 ms) before a fault.
    #[serde(default = "default_error_frame_limit")]
    pub error_frame_limit: u32,
    /// Node id of the spindle drive (CiA 402, cyclic synchronous velocity); unset: no spindle
    /// drive on this bus.
    #[serde(default)]
    pub spindle_node: Option<u8>,
    /// Spindle drive velocity units (0x60FF, 0x606C) per rpm.
    #[serde(default = "default_units_per_rpm")]
    pub spindle_units_per_rpm: f64,
}

fn default_units_per_rpm() -> f64 {
    1.0
}

/// Checks the spindle keys shared by the CAN and serial sections.
fn validate_spindle(
    node: Option<u8>,
    units_per_rpm: f64,
    axes: &[AxisConfig],
) -> Result<(), String> {
    if !(units_per_rpm.is_finite() && units_per_rpm > 0.0) {
        return Err(format!(
            "bus.spindle_units_per_rpm: {units_per_rpm} must be a positive number"
        ));
    }
    if let Some(id) = node {
        if !(1..=127).contains(&id) {
            return Err(format!("bus.spindle_node: {id} is outside 1..127"));
        }
        if let Some(a) = axes.iter().find(|a| a.node_id == Some(id)) {
            return Err(format!(
                "bus.spindle_node: node {id} is the drive of axis {}",
                a.name
            ));
        }
    }
    Ok(())
}

fn default_master_node_id() -> u8 {
    127
}
fn default_tpdo_missing_ticks() -> u32 {
    25
}
fn default_drive_heartbeat_ms() -> u16 {
    100
}
fn default_heartbeat_timeout_ms() -> u32 {
    500
}
fn default_master_heartbeat_ms() -> u16 {
    100
}
fn default_drive_consumer_timeout_ms() -> u16 {
    500
}
fn default_sdo_timeout_ms() -> u32 {
    200
}
fn default_boot_timeout_ms() -> u32 {
    3000
}
fn default_enable_timeout_ms() -> u32 {
    2000
}
fn default_error_frame_limit() -> u32 {
    20
}

/// `[bus] kind = "serial"`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SerialBusConfig {
    /// Device path; prefer a stable name (`/dev/serial/by-id/...`): reset reopens it by path.
    pub port: String,
    #[serde(default = "default_baud")]
    pub baud: u32,
    /// Consecutive ticks without a valid reply before it is a fault.
    #[serde(default = "default_tpdo_missing_ticks")]
    pub reply_timeout_ticks: u32,
    /// Ticks allowed for the CiA 402 enable sequence.
    #[serde(default = "default_enable_timeout_ticks")]
    pub enable_timeout_ticks: u32,
    /// Address of the unit's spindle drive (named in alarms); set: the unit has a spindle and
    /// the link speaks protocol version 2. Unset: no spindle drive, protocol version 1.
    #[serde(default)]
    pub spindle_node: Option<u8>,
    /// Spindle drive velocity units per rpm.
    #[serde(default = "default_units_per_rpm")]
    pub spindle_units_per_rpm: f64,
}

fn default_baud() -> u32 {
    460_800
}
fn default_enable_timeout_ticks() -> u32 {
    500
}

impl Default for BusConfig {
    fn default() -> Self {
        BusConfig::Sim {}
    }
}

impl BusConfig {
    /// Checks the bus settings against the axes; the message names the key.
    pub fn validate(&self, axes: &[AxisConfig]) -> Result<(), String> {
        match self {
            BusConfig::Sim {} => Ok(()),
            BusConfig::Can(c) => {
                if c.interface.is_empty() {
                    return Err("bus.interface: give the CAN interface, e.g. \"can0\"".into());
                }
                if !(1..=127).contains(&c.master_node_id) {
                    return Err(format!(
                        "bus.master_node_id: {} is outside 1..127",
                        c.master_node_id
                    ));
                }
                for (i, a) in axes.iter().enumerate() {
                    let Some(id) = a.node_id else {
                        return Err(format!(
                            "axes[{i}].node_id: axis {} needs the CANopen node id of its drive",
                            a.name
                        ));
                    };
                    if !(1..=127).contains(&id) || id == c.master_node_id {
                        return Err(format!(
                            "axes[{i}].node_id: {id} is outside 1..127 or equals bus.master_node_id"
                        ));
                    }
                    if axes[..i].iter().any(|b| b.node_id == Some(id)) {
                        return Err(format!("axes[{i}].node_id: node {id} is used twice"));
                    }
                }
                for (key, v) in [
                    ("following_window_mm", c.following_window_mm),
                    ("following_error_limit_mm", c.following_error_limit_mm),
                ] {
                    if let Some(v) = v
                        && !(v.is_finite() && v > 0.0)
                    {
                        return Err(format!("bus.{key}: {v} must be a positive number"));
                    }
                }
                if c.tpdo_missing_ticks == 0 || c.heartbeat_timeout_ms == 0 {
                    return Err(
                        "bus.tpdo_missing_ticks and bus.heartbeat_timeout_ms must be above 0"
                            .into(),
                    );
                }
                if c.spindle_node == Some(c.master_node_id) {
                    return Err(format!(
                        "bus.spindle_node: {} equals bus.master_node_id",
                        c.master_node_id
                    ));
                }
                validate_spindle(c.spindle_node, c.spindle_units_per_rpm, axes)
            }
            BusConfig::Serial(s) => {
                if s.port.is_empty() {
                    return Err("bus.port: give the serial device, e.g. \"/dev/ttyUSB0\"".into());
                }
                if s.reply_timeout_ticks == 0 {
                    return Err("bus.reply_timeout_ticks must be above 0".into());
                }
                validate_spindle(s.spindle_node, s.spindle_units_per_rpm, axes)
            }
        }
    }
}

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
            Ok(Box::new(
                sim::SimBus::new(params, &start).with_spindle_ramp(sim.spindle_ramp_rpm_s),
            ))
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
