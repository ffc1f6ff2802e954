//! `[bus]`: the drive bus (simulated, CANopen or serial) and its cycle; opened by
//! `runtime::buses`.

use std::path::PathBuf;

use serde::Deserialize;

use super::InvalidConfig;
use super::axes::AxisConfig;

/// `[bus]` section of the configuration.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum BusConfig {
    /// The built-in simulated machine (default). A struct variant, so that serde rejects
    /// unknown keys next to `kind = "sim"` (a unit variant would ignore them).
    Sim {
        /// Bus period, ms (1..10): the real-time tick and the simulated drives' cycle.
        #[serde(default = "default_cycle_ms")]
        cycle_ms: f64,
    },
    /// CANopen CiA 402 drives on a SocketCAN interface; node ids from `axes[i].node_id`.
    Can(CanBusConfig),
    /// One drive unit on a serial port (`hal/SERIAL_PROTOCOL.md`).
    Serial(SerialBusConfig),
}

/// `[bus] kind = "can"`. Times in ms are converted to ticks of `cycle_ms`. One field per key
/// of the table (the file format is the API, see the `config` module doc).
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
    /// Consecutive bus cycles (SYNCs) without a drive's TPDO before it is a fault.
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
    /// Bus cycle (SYNC period), whole ms 1..10; the drives' interpolation period 0x60C2 and
    /// communication cycle 0x1006 follow it, and the real-time thread ticks at it (the
    /// interpolator keeps 4 ms: `runtime::resample`). Read as a number so that 3.5 gets a
    /// clear message from `validate`.
    #[serde(default = "default_cycle_ms")]
    pub cycle_ms: f64,
    /// How the drives are switched off when the daemon ends: `disable` (07h, 06h, 00h) or
    /// `quick_stop` (02h, 00h).
    #[serde(default)]
    pub shutdown: ShutdownKey,
    /// What the drives do after a fault stop, once the healthy axes are at rest:
    /// `quick_stop` (02h, default), `disable_voltage` (00h) or `hold` (stay enabled on the
    /// last setpoint). docs/operator.md.
    #[serde(default)]
    pub fault_reaction: FaultReactionKey,
    /// Time allowed for a drive's reference run (homing mode 6), ms.
    #[serde(default = "default_homing_timeout_ms")]
    pub homing_timeout_ms: u32,
    /// Node id of the spindle drive (CiA 402, cyclic synchronous velocity); unset: no spindle
    /// drive on this bus.
    #[serde(default)]
    pub spindle_node: Option<u8>,
    /// Spindle drive velocity units (0x60FF, 0x606C) per rpm.
    #[serde(default = "default_units_per_rpm")]
    pub spindle_units_per_rpm: f64,
}

/// `[bus] shutdown` of a CAN or serial bus.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum ShutdownKey {
    #[default]
    Disable,
    QuickStop,
}

fn default_cycle_ms() -> f64 {
    4.0
}

/// `[bus] fault_reaction` of a CAN or serial bus.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum FaultReactionKey {
    #[default]
    QuickStop,
    DisableVoltage,
    Hold,
}

fn default_homing_timeout_ms() -> u32 {
    60_000
}

fn default_units_per_rpm() -> f64 {
    1.0
}

/// Checks the spindle keys shared by the CAN and serial sections.
fn validate_spindle(
    node: Option<u8>,
    units_per_rpm: f64,
    axes: &[AxisConfig],
) -> Result<(), InvalidConfig> {
    if !(units_per_rpm.is_finite() && units_per_rpm > 0.0) {
        return Err(InvalidConfig::BadValue {
            key: "bus.spindle_units_per_rpm".into(),
            detail: format!("{units_per_rpm} must be a positive number"),
        });
    }
    if let Some(id) = node {
        if !(1..=127).contains(&id) {
            return Err(InvalidConfig::BadValue {
                key: "bus.spindle_node".into(),
                detail: format!("{id} is outside 1..127"),
            });
        }
        if let Some(a) = axes.iter().find(|a| a.node_id == Some(id)) {
            return Err(InvalidConfig::Duplicate {
                key: "bus.spindle_node".into(),
                detail: format!("node {id} is the drive of axis {}", a.name),
            });
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

/// `[bus] kind = "serial"`. One field per key of the table (the file format is the API).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SerialBusConfig {
    /// Device path; prefer a stable name (`/dev/serial/by-id/...`): reset reopens it by path.
    pub port: String,
    #[serde(default = "default_baud")]
    pub baud: u32,
    /// Consecutive ticks (bus cycles) without a valid reply before it is a fault.
    #[serde(default = "default_tpdo_missing_ticks")]
    pub reply_timeout_ticks: u32,
    /// Bus cycle, ms. The serial protocol fixes it at 4 ms (the drive unit advances its
    /// position loop by 4 ms per request), so 4 is the only value accepted.
    #[serde(default = "default_cycle_ms")]
    pub cycle_ms: f64,
    /// Ticks (bus cycles) allowed for the CiA 402 enable sequence (and for the switch-off
    /// walk when the daemon ends).
    #[serde(default = "default_enable_timeout_ticks")]
    pub enable_timeout_ticks: u32,
    /// How the drives are switched off when the daemon ends, as on CAN.
    #[serde(default)]
    pub shutdown: ShutdownKey,
    /// What the drives do after a fault stop, as on CAN.
    #[serde(default)]
    pub fault_reaction: FaultReactionKey,
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
        BusConfig::Sim {
            cycle_ms: default_cycle_ms(),
        }
    }
}

/// `[bus] cycle_ms` must be a whole number of ms in 1..10 (the CANopen interpolation period
/// 0x60C2 is whole ms; the deadline grid is exact in ns).
fn validate_cycle_ms(ms: f64) -> Result<(), InvalidConfig> {
    let range = crate::runtime::resample::CYCLE_MS_RANGE;
    let (lo, hi) = (f64::from(*range.start()), f64::from(*range.end()));
    if !(ms.is_finite() && ms.fract() == 0.0 && (lo..=hi).contains(&ms)) {
        return Err(InvalidConfig::BadValue {
            key: "bus.cycle_ms".into(),
            detail: format!("{ms} is not a whole number of milliseconds from {lo} to {hi}"),
        });
    }
    Ok(())
}

impl BusConfig {
    /// `[bus] cycle_ms`: the bus period, ms (validated: whole, 1..10).
    pub fn cycle_ms(&self) -> f64 {
        match self {
            BusConfig::Sim { cycle_ms } => *cycle_ms,
            BusConfig::Can(c) => c.cycle_ms,
            BusConfig::Serial(s) => s.cycle_ms,
        }
    }

    /// The bus period, ns: the tick of the real-time thread.
    pub fn cycle_ns(&self) -> u64 {
        (self.cycle_ms() * 1e6).round() as u64
    }

    /// The bus period.
    pub fn cycle(&self) -> std::time::Duration {
        std::time::Duration::from_nanos(self.cycle_ns())
    }

    /// Checks the bus settings against the axes; the message names the key.
    pub fn validate(&self, axes: &[AxisConfig]) -> Result<(), InvalidConfig> {
        validate_cycle_ms(self.cycle_ms())?;
        match self {
            BusConfig::Sim { .. } => Ok(()),
            BusConfig::Can(c) => validate_can(c, axes),
            BusConfig::Serial(s) => validate_serial(s, axes),
        }
    }
}

/// `[bus] kind = "can"`: an interface, node ids, positive windows and timeouts.
fn validate_can(c: &CanBusConfig, axes: &[AxisConfig]) -> Result<(), InvalidConfig> {
    if c.interface.is_empty() {
        return Err(InvalidConfig::Missing {
            key: "bus.interface".into(),
            detail: "give the CAN interface, e.g. \"can0\"".into(),
        });
    }
    if !(1..=127).contains(&c.master_node_id) {
        return Err(InvalidConfig::BadValue {
            key: "bus.master_node_id".into(),
            detail: format!("{} is outside 1..127", c.master_node_id),
        });
    }
    validate_can_nodes(c, axes)?;
    for (key, v) in [
        ("following_window_mm", c.following_window_mm),
        ("following_error_limit_mm", c.following_error_limit_mm),
    ] {
        if let Some(v) = v
            && !(v.is_finite() && v > 0.0)
        {
            return Err(InvalidConfig::BadValue {
                key: format!("bus.{key}"),
                detail: format!("{v} must be a positive number"),
            });
        }
    }
    if c.homing_timeout_ms == 0 {
        return Err(InvalidConfig::BadValue {
            key: "bus.homing_timeout_ms".into(),
            detail: "must be above 0".into(),
        });
    }
    if c.tpdo_missing_ticks == 0 || c.heartbeat_timeout_ms == 0 {
        return Err(InvalidConfig::BadValue {
            key: "bus.tpdo_missing_ticks, bus.heartbeat_timeout_ms".into(),
            detail: "must be above 0".into(),
        });
    }
    if c.spindle_node == Some(c.master_node_id) {
        return Err(InvalidConfig::Duplicate {
            key: "bus.spindle_node".into(),
            detail: format!("{} equals bus.master_node_id", c.master_node_id),
        });
    }
    validate_spindle(c.spindle_node, c.spindle_units_per_rpm, axes)
}

/// Every axis has a CANopen node id of its own in 1..127, not the controller's.
fn validate_can_nodes(c: &CanBusConfig, axes: &[AxisConfig]) -> Result<(), InvalidConfig> {
    for (i, a) in axes.iter().enumerate() {
        let Some(id) = a.node_id else {
            return Err(InvalidConfig::Missing {
                key: format!("axes[{i}].node_id"),
                detail: format!("axis {} needs the CANopen node id of its drive", a.name),
            });
        };
        if !(1..=127).contains(&id) || id == c.master_node_id {
            return Err(InvalidConfig::Duplicate {
                key: format!("axes[{i}].node_id"),
                detail: format!("{id} is outside 1..127 or equals bus.master_node_id"),
            });
        }
        if axes[..i].iter().any(|b| b.node_id == Some(id)) {
            return Err(InvalidConfig::Duplicate {
                key: format!("axes[{i}].node_id"),
                detail: format!("node {id} is used twice"),
            });
        }
    }
    Ok(())
}

/// `[bus] kind = "serial"`: a port, a reply timeout, the protocol's 4 ms cycle.
fn validate_serial(s: &SerialBusConfig, axes: &[AxisConfig]) -> Result<(), InvalidConfig> {
    if s.port.is_empty() {
        return Err(InvalidConfig::Missing {
            key: "bus.port".into(),
            detail: "give the serial device, e.g. \"/dev/ttyUSB0\"".into(),
        });
    }
    if s.reply_timeout_ticks == 0 {
        return Err(InvalidConfig::BadValue {
            key: "bus.reply_timeout_ticks".into(),
            detail: "must be above 0".into(),
        });
    }
    if s.cycle_ms != 4.0 {
        return Err(InvalidConfig::BadValue {
            key: "bus.cycle_ms".into(),
            detail: format!(
                "{} ms on a serial bus; the serial protocol's cycle is 4 ms (hal/SERIAL_PROTOCOL.md)",
                s.cycle_ms
            ),
        });
    }
    validate_spindle(s.spindle_node, s.spindle_units_per_rpm, axes)
}
