//! Daemon configuration: one TOML file. Every key has a default, so an empty file (or none)
//! gives the built-in simulated 3-axis mill.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};

use serde::Deserialize;

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Config {
    /// Machine axes in machine order (R0..R5).
    #[serde(default = "default_axes")]
    pub axes: Vec<AxisConfig>,
    #[serde(default)]
    pub bus: BusConfig,
    #[serde(default)]
    pub api: ApiConfig,
    #[serde(default)]
    pub rt: RtConfig,
    #[serde(default)]
    pub sim: SimConfig,
    #[serde(default)]
    pub storage: StorageConfig,
    #[serde(default)]
    pub kr: KrSection,
    #[serde(default)]
    pub program: ProgramSection,
    #[serde(default)]
    pub planner: PlannerSection,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            axes: default_axes(),
            bus: BusConfig::default(),
            api: ApiConfig::default(),
            rt: RtConfig::default(),
            sim: SimConfig::default(),
            storage: StorageConfig::default(),
            kr: KrSection::default(),
            program: ProgramSection::default(),
            planner: PlannerSection::default(),
        }
    }
}

/// How part programs are read (SPEC §2 **decide** points that are settings).
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct ProgramSection {
    /// Arc centre words I J: `"relative"` to the arc's start point (default) or `"absolute"`
    /// program coordinates. Every path from text to motion (load, run, preview) reads it.
    #[serde(default)]
    pub ij: IjSetting,
}

/// `[program] ij`.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum IjSetting {
    #[default]
    Relative,
    Absolute,
}

impl From<IjSetting> for kernel::program::IjMode {
    fn from(s: IjSetting) -> Self {
        match s {
            IjSetting::Relative => kernel::program::IjMode::RelativeToStart,
            IjSetting::Absolute => kernel::program::IjMode::Absolute,
        }
    }
}

/// Where the controller keeps its data files.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct StorageConfig {
    /// Directory of the data files (systemd: the unit's StateDirectory, `/var/lib/cncd`).
    /// Relative paths are taken from the daemon's working directory.
    #[serde(default = "default_storage_dir")]
    pub dir: PathBuf,
    /// Offset table file (SPEC §3; `$21` of CNC836.KNF), relative to `dir`.
    #[serde(default = "default_offsets_file")]
    pub offsets_file: PathBuf,
    /// Machine constants file (`Rnnn=value` lines, see docs/files.md), relative to `dir`. A
    /// missing file means every constant at its default.
    #[serde(default = "default_constants_file")]
    pub constants_file: PathBuf,
    /// Program library directory (stored programs, survive restarts), relative to `dir`.
    #[serde(default = "default_programs_dir")]
    pub programs_dir: PathBuf,
    /// Most bytes the program library may hold (RESOURCE_EXHAUSTED beyond).
    #[serde(default = "default_programs_max_bytes")]
    pub programs_max_bytes: u64,
}

fn default_storage_dir() -> PathBuf {
    PathBuf::from("cncd-data")
}
fn default_offsets_file() -> PathBuf {
    PathBuf::from("TAB0.KOR")
}
fn default_constants_file() -> PathBuf {
    PathBuf::from("TAB0.REK")
}
fn default_programs_dir() -> PathBuf {
    PathBuf::from("programs")
}
fn default_programs_max_bytes() -> u64 {
    2 << 30
}

impl Default for StorageConfig {
    fn default() -> Self {
        StorageConfig {
            dir: default_storage_dir(),
            offsets_file: default_offsets_file(),
            constants_file: default_constants_file(),
            programs_dir: default_programs_dir(),
            programs_max_bytes: default_programs_max_bytes(),
        }
    }
}

impl StorageConfig {
    pub fn offsets_path(&self) -> PathBuf {
        self.dir.join(&self.offsets_file)
    }
    pub fn constants_path(&self) -> PathBuf {
        self.dir.join(&self.constants_file)
    }
    pub fn programs_path(&self) -> PathBuf {
        self.dir.join(&self.programs_dir)
    }
}

/// How the controlling axis of constant cutting speed (R67) is programmed (SPEC §6,
/// docs/lathe.md). Machine coordinates (setpoints, soft limits, `home_mm`, jog) are always
/// the radius: the true travel of the slide.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum RadiusInputConfig {
    /// Diameter programming (lathes): the axis's program words, its absolute arc centres and
    /// its TAB0.KOR lengths are diameters, halved by the interpreter; the status and the DRO
    /// show it as a diameter. The KŘR radius is the axis position.
    Diameter,
    /// The axis is programmed as a radius, like every other axis (mills; the default).
    #[default]
    Radius,
}

/// `[kr]`: constant cutting speed and the spindle gear ranges.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct KrSection {
    #[serde(default)]
    pub radius_input: RadiusInputConfig,
    /// Gear ranges in order (gear 1 first).
    #[serde(default = "default_gears")]
    pub gears: Vec<GearConfig>,
}

impl Default for KrSection {
    fn default() -> Self {
        KrSection {
            radius_input: RadiusInputConfig::default(),
            gears: default_gears(),
        }
    }
}

/// One spindle gear range.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct GearConfig {
    /// P: spindle speed at full output, rpm.
    pub max_rpm: f64,
    /// U: output value at speed P, 1..32767 (7FFFh).
    #[serde(default = "default_output_range")]
    pub output_range: u16,
    /// M code selecting this range (M41..M44 by convention).
    #[serde(default)]
    pub m_code: Option<u16>,
}

fn default_output_range() -> u16 {
    0x7FFF
}

fn default_gears() -> Vec<GearConfig> {
    vec![GearConfig {
        max_rpm: 6000.0,
        output_range: 0x7FFF,
        m_code: Some(41),
    }]
}

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AxisConfig {
    /// Axis letter used in programs (`X`, `Y`, `Z`, `U`...).
    pub name: char,
    /// Maximum axis speed, also the rapid speed, mm/min.
    #[serde(default = "default_v_max")]
    pub max_velocity_mm_min: f64,
    /// Maximum axis acceleration, mm/s².
    #[serde(default = "default_a_max")]
    pub max_accel_mm_s2: f64,
    /// Drive increments per mm (or per degree) for bus backends that talk increments.
    #[serde(default = "default_increments")]
    pub increments_per_mm: f64,
    /// Bus node id of the axis drive (CANopen node id, serial address).
    #[serde(default)]
    pub node_id: Option<u8>,
    /// Position at power-on of the simulated machine, mm.
    #[serde(default)]
    pub home_mm: f64,
    /// Soft limits (travel limits), machine coordinates, mm (degrees on a rotary axis).
    /// Programs, MDI and jogs never command the axis beyond them. Unset: no limit on that
    /// side (the axis is not protected there: docs/operator.md).
    #[serde(default)]
    pub soft_min_mm: Option<f64>,
    #[serde(default)]
    pub soft_max_mm: Option<f64>,
    /// Deceleration of this axis in an emergency stop (a fault of any axis), mm/s². Unset:
    /// `max_accel_mm_s2`. Each axis brakes on its own at this rate, not along the path.
    #[serde(default)]
    pub stop_decel_mm_s2: Option<f64>,
    /// Reference run (homing): `required` (incremental encoders: programs, MDI and continuous
    /// jogs are refused until the axis is homed) or `none` (absolute encoders; the default,
    /// so an existing configuration keeps working).
    #[serde(default)]
    pub homing: HomingMode,
    /// Machine coordinate of the home switch: the axis's position once it is found.
    #[serde(default)]
    pub reference_mm: f64,
    /// Direction of the switch search: -1 or +1.
    #[serde(default = "default_homing_direction")]
    pub homing_direction: i8,
    /// Search speed, mm/min (unset: 10 % of `max_velocity_mm_min`).
    #[serde(default)]
    pub homing_speed_mm_min: Option<f64>,
    /// Order of the reference run (lower first; unset: after the numbered axes, in machine
    /// order). Typically Z first, so the tool leaves the work before X and Y move.
    #[serde(default)]
    pub home_order: Option<u8>,
    /// Simulated machine only: where the home switch of this axis is, in the drive's power-on
    /// coordinates (pressed from there on in `homing_direction`). Unset: no switch.
    #[serde(default)]
    pub sim_home_switch_mm: Option<f64>,
    /// Rotary axis (SPEC §5, docs/lathe.md): encoder pulses per revolution. The axis is then
    /// positioned in degrees (its `_mm` settings are degrees), and F of a block that moves
    /// only rotary axes is in thousands of these pulses per minute. Unset: a linear axis.
    #[serde(default)]
    pub rotary_pulses_per_rev: Option<f64>,
    /// CANopen: homing method of the drive's reference run (0x6098, CiA 402). Unset: 21
    /// (home switch on the negative side) with `homing_direction = -1`, 19 (positive side)
    /// with +1; docs/buses.md#homing.
    #[serde(default)]
    pub can_homing_method: Option<i8>,
    /// CANopen: speed of the second homing phase, leaving the switch for the home position
    /// (0x6099:2), mm/min. Unset: a tenth of the search speed.
    #[serde(default)]
    pub homing_zero_speed_mm_min: Option<f64>,
    /// CANopen: acceleration of the drive's reference run (0x609A), mm/s². Unset:
    /// `max_accel_mm_s2`.
    #[serde(default)]
    pub homing_accel_mm_s2: Option<f64>,
}

/// Reference run of an axis.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum HomingMode {
    /// Absolute encoder, or the machine is referenced otherwise.
    #[default]
    None,
    /// The axis must be homed after power-on before it runs programs.
    Required,
}

fn default_homing_direction() -> i8 {
    -1
}

fn default_v_max() -> f64 {
    kernel::plan::DEFAULT_AXIS_LIMITS.v_max_mm_s * 60.0
}
fn default_a_max() -> f64 {
    kernel::plan::DEFAULT_AXIS_LIMITS.a_max_mm_s2
}
fn default_increments() -> f64 {
    10_000.0
}

impl AxisConfig {
    /// Emergency-stop deceleration, mm/s².
    pub fn stop_decel(&self) -> f64 {
        self.stop_decel_mm_s2.unwrap_or(self.max_accel_mm_s2)
    }

    pub fn new(name: char) -> Self {
        AxisConfig {
            name,
            max_velocity_mm_min: default_v_max(),
            max_accel_mm_s2: default_a_max(),
            increments_per_mm: default_increments(),
            node_id: None,
            home_mm: 0.0,
            soft_min_mm: None,
            soft_max_mm: None,
            stop_decel_mm_s2: None,
            homing: HomingMode::None,
            reference_mm: 0.0,
            homing_direction: -1,
            homing_speed_mm_min: None,
            home_order: None,
            sim_home_switch_mm: None,
            rotary_pulses_per_rev: None,
            can_homing_method: None,
            homing_zero_speed_mm_min: None,
            homing_accel_mm_s2: None,
        }
    }

    /// Search speed of the reference run, mm/s.
    pub fn homing_speed_mm_s(&self) -> f64 {
        self.homing_speed_mm_min
            .unwrap_or(0.1 * self.max_velocity_mm_min)
            / 60.0
    }
}

fn default_axes() -> Vec<AxisConfig> {
    ['X', 'Y', 'Z']
        .into_iter()
        .enumerate()
        .map(|(i, n)| AxisConfig {
            node_id: Some(i as u8 + 1),
            ..AxisConfig::new(n)
        })
        .collect()
}

/// `[api]`: listeners and access control of the gRPC API (docs/api.md).
///
/// Callers without a token get `local_role` on the Unix socket (its mode and group decide who
/// may connect) and `loopback_role` on loopback TCP (every local account can connect there, so
/// the default is observer); any other address needs TLS and a bearer token from `tokens`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ApiConfig {
    /// gRPC listen address. Default loopback port 50051.
    #[serde(default = "default_listen")]
    pub listen: SocketAddr,
    /// More TCP addresses to serve on (e.g. the HMI network). Non-loopback addresses need
    /// `tls_cert`, `tls_key` and at least one token.
    #[serde(default)]
    pub extra_listen: Vec<SocketAddr>,
    /// Unix socket path, relative to `storage.dir` unless absolute; "" disables the socket.
    #[serde(default = "default_unix_socket")]
    pub unix_socket: PathBuf,
    /// Permission bits of the socket file (TOML octal, e.g. `0o660`).
    #[serde(default = "default_socket_mode")]
    pub socket_mode: u32,
    /// Group owning the socket file (name); unset: the daemon's group.
    #[serde(default)]
    pub socket_group: Option<String>,
    /// PEM certificate chain and private key for TLS on non-loopback TCP listeners.
    #[serde(default)]
    pub tls_cert: Option<PathBuf>,
    #[serde(default)]
    pub tls_key: Option<PathBuf>,
    /// Role of callers on the Unix socket that send no token (the socket's mode and group
    /// decide who may connect). Also accepted as `socket_role`.
    #[serde(default = "default_local_role", alias = "socket_role")]
    pub local_role: Role,
    /// Role of callers on loopback TCP that send no token. Any local account can open a
    /// loopback port, so the default is `observer`: control needs the Unix socket or a token.
    #[serde(default = "default_loopback_role")]
    pub loopback_role: Role,
    /// Bearer tokens, stored as SHA-256 hashes (`cncctl hash-token` prints one).
    #[serde(default)]
    pub tokens: Vec<TokenConfig>,
    /// Most status and alarm streams open at once (RESOURCE_EXHAUSTED beyond).
    #[serde(default = "default_max_streams")]
    pub max_streams: u32,
    /// Of `max_streams`, how many only operator and admin callers may take: observers cannot
    /// lock the operator's status out by opening every stream.
    #[serde(default = "default_reserved_streams")]
    pub reserved_streams: u32,
    /// Alarms kept for `StreamAlarms` history.
    #[serde(default = "default_alarm_history")]
    pub alarm_history: u32,
}

/// Access roles, ordered: each includes the ones before it.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[serde(rename_all = "lowercase")]
pub enum Role {
    /// Status and every read.
    Observer,
    /// Programs, machine control, offsets and PLC writes.
    Operator,
    /// Machine constants.
    Admin,
}

impl Role {
    pub fn name(self) -> &'static str {
        match self {
            Role::Observer => "observer",
            Role::Operator => "operator",
            Role::Admin => "admin",
        }
    }
}

/// One bearer token: who it is, its role, and the SHA-256 of the token text (hex).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TokenConfig {
    /// Name for logs (e.g. "hmi-1").
    pub name: String,
    pub role: Role,
    /// Lower-case hex SHA-256 of the token (64 characters).
    pub sha256: String,
}

fn default_listen() -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], 50051))
}
fn default_unix_socket() -> PathBuf {
    PathBuf::from("cncd.sock")
}
fn default_socket_mode() -> u32 {
    0o660
}
fn default_local_role() -> Role {
    Role::Admin
}
fn default_loopback_role() -> Role {
    Role::Observer
}
fn default_max_streams() -> u32 {
    64
}
fn default_reserved_streams() -> u32 {
    8
}
fn default_alarm_history() -> u32 {
    256
}

impl Default for ApiConfig {
    fn default() -> Self {
        ApiConfig {
            listen: default_listen(),
            extra_listen: Vec::new(),
            unix_socket: default_unix_socket(),
            socket_mode: default_socket_mode(),
            socket_group: None,
            tls_cert: None,
            tls_key: None,
            local_role: default_local_role(),
            loopback_role: default_loopback_role(),
            tokens: Vec::new(),
            max_streams: default_max_streams(),
            reserved_streams: default_reserved_streams(),
            alarm_history: default_alarm_history(),
        }
    }
}

impl ApiConfig {
    /// Every TCP address served: `listen` first.
    pub fn tcp_addresses(&self) -> Vec<SocketAddr> {
        let mut v = vec![self.listen];
        v.extend(self.extra_listen.iter().copied());
        v
    }

    /// The socket path (relative paths from `storage_dir`), or `None` when disabled.
    pub fn unix_socket_path(&self, storage_dir: &Path) -> Option<PathBuf> {
        if self.unix_socket.as_os_str().is_empty() {
            None
        } else {
            Some(storage_dir.join(&self.unix_socket))
        }
    }

    /// Checks listeners, TLS and tokens; the message names the key.
    pub fn validate(&self) -> Result<(), InvalidConfig> {
        let remote = self
            .tcp_addresses()
            .into_iter()
            .find(|a| !a.ip().is_loopback());
        if let Some(a) = remote {
            if self.tls_cert.is_none() || self.tls_key.is_none() {
                return Err(InvalidConfig::Missing {
                    key: "api.tls_cert, api.tls_key".into(),
                    detail: format!("listening on {a} (not loopback) requires TLS"),
                });
            }
            if self.tokens.is_empty() {
                return Err(InvalidConfig::Missing {
                    key: "api.tokens".into(),
                    detail: format!("listening on {a} (not loopback) requires at least one token"),
                });
            }
        }
        if self.tls_cert.is_some() != self.tls_key.is_some() {
            return Err(InvalidConfig::Missing {
                key: "api.tls_cert, api.tls_key".into(),
                detail: "give both or neither".into(),
            });
        }
        if self.socket_mode > 0o777 {
            return Err(InvalidConfig::BadValue {
                key: "api.socket_mode".into(),
                detail: format!(
                    "{:o} is not a permission mode (0o000..0o777)",
                    self.socket_mode
                ),
            });
        }
        for (i, t) in self.tokens.iter().enumerate() {
            if t.sha256.len() != 64 || !t.sha256.bytes().all(|b| b.is_ascii_hexdigit()) {
                return Err(InvalidConfig::BadValue {
                    key: format!("api.tokens[{i}].sha256"),
                    detail: "must be 64 hex digits (the SHA-256 of the token)".into(),
                });
            }
            if self.tokens[..i]
                .iter()
                .any(|u| u.sha256.eq_ignore_ascii_case(&t.sha256))
            {
                return Err(InvalidConfig::Duplicate {
                    key: format!("api.tokens[{i}].sha256"),
                    detail: "the same token appears twice".into(),
                });
            }
        }
        if self.max_streams == 0 {
            return Err(InvalidConfig::BadValue {
                key: "api.max_streams".into(),
                detail: "must be at least 1".into(),
            });
        }
        if self.reserved_streams >= self.max_streams {
            return Err(InvalidConfig::BadValue {
                key: "api.reserved_streams".into(),
                detail: format!(
                    "{} must be below api.max_streams ({}): observers need at \
                 least one stream",
                    self.reserved_streams, self.max_streams
                ),
            });
        }
        Ok(())
    }
}

/// `[planner]`: machine settings of the look-ahead planner (docs/planner.md). The envelope
/// settings (continuity, criteria, dynamic sets) are machine constants, not keys here.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PlannerSection {
    /// Minimum block duration, ms (SPEC §7.2): a block runs no faster than its length over
    /// this time, and the automatic continuity rule (1.R97 = 2) makes a junction a stop when
    /// a block would be shorter. 0 (default) = off: the interpolator crosses several blocks
    /// per tick. 4 = the CNC8x9 behaviour.
    #[serde(default)]
    pub min_block_time_ms: f64,
}

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RtConfig {
    /// SCHED_FIFO priority of the real-time thread (1..99).
    #[serde(default = "default_priority")]
    pub priority: i32,
    /// Lock all memory (mlockall) so the RT thread never page-faults.
    #[serde(default = "default_true")]
    pub lock_memory: bool,
}

fn default_priority() -> i32 {
    80
}
fn default_true() -> bool {
    true
}

impl Default for RtConfig {
    fn default() -> Self {
        RtConfig {
            priority: default_priority(),
            lock_memory: true,
        }
    }
}

/// Parameters of the simulated drives (bus kind `sim`).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SimConfig {
    /// Position-loop gain of the simulated drives, 1/s.
    #[serde(default = "default_kv")]
    pub kv_per_s: f64,
    /// Following-error window, mm.
    #[serde(default = "default_window")]
    pub following_window_mm: f64,
    /// Acceleration of the simulated spindle, rpm/s (0: it reaches its setpoint at once).
    #[serde(default)]
    pub spindle_ramp_rpm_s: f64,
}

fn default_kv() -> f64 {
    30.0
}
fn default_window() -> f64 {
    50.0
}

impl Default for SimConfig {
    fn default() -> Self {
        SimConfig {
            kv_per_s: default_kv(),
            following_window_mm: default_window(),
            spindle_ramp_rpm_s: 0.0,
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("cannot read {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: {message}")]
    Parse { path: PathBuf, message: String },
    #[error("{path}: {source}")]
    Invalid {
        path: PathBuf,
        #[source]
        source: InvalidConfig,
    },
}

impl ConfigError {
    /// Stable code (tests and `cncd --check-config` show it; the message may improve).
    pub fn code(&self) -> &'static str {
        match self {
            ConfigError::Read { .. } => "config_read",
            ConfigError::Parse { .. } => "config_parse",
            ConfigError::Invalid { source, .. } => source.code(),
        }
    }
}

/// A value the validation refused (after serde accepted the file): the key it names and why.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum InvalidConfig {
    /// Out of its range, not a number, or not of the form the key takes.
    #[error("{key}: {detail}")]
    BadValue { key: String, detail: String },
    /// A name, node or file given twice (or the same as another key's).
    #[error("{key}: {detail}")]
    Duplicate { key: String, detail: String },
    /// A value required by the others is missing (or only one of a pair is given).
    #[error("{key}: {detail}")]
    Missing { key: String, detail: String },
}

impl InvalidConfig {
    /// Stable code (tests match it; the message may improve).
    pub fn code(&self) -> &'static str {
        match self {
            InvalidConfig::BadValue { .. } => "config_bad_value",
            InvalidConfig::Duplicate { .. } => "config_duplicate",
            InvalidConfig::Missing { .. } => "config_missing",
        }
    }

    /// The key the mistake is in, e.g. `axes[0].max_accel_mm_s2`.
    pub fn key(&self) -> &str {
        match self {
            InvalidConfig::BadValue { key, .. }
            | InvalidConfig::Duplicate { key, .. }
            | InvalidConfig::Missing { key, .. } => key,
        }
    }
}

impl Config {
    pub fn load(path: &Path) -> Result<Config, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: path.to_owned(),
            source,
        })?;
        Self::parse(&text, path)
    }

    /// Parses and validates a configuration text; `path` is used in messages.
    pub fn parse(text: &str, path: &Path) -> Result<Config, ConfigError> {
        let cfg: Config = toml::from_str(text).map_err(|e| ConfigError::Parse {
            path: path.to_owned(),
            message: e.to_string(),
        })?;
        cfg.validate().map_err(|source| ConfigError::Invalid {
            path: path.to_owned(),
            source,
        })?;
        Ok(cfg)
    }

    /// Checks what serde cannot: counts, ranges, duplicates. The message names the key.
    pub fn validate(&self) -> Result<(), InvalidConfig> {
        self.validate_axes()?;
        self.validate_gears()?;
        self.validate_storage()?;
        for (i, a) in self.axes.iter().enumerate() {
            if !a.home_mm.is_finite() {
                return Err(InvalidConfig::BadValue {
                    key: format!("axes[{i}].home_mm"),
                    detail: format!("{} is not a number", a.home_mm),
                });
            }
            validate_axis_safety(i, a)?;
        }
        self.validate_sim_planner_rt()?;
        self.api.validate()?;
        self.bus.validate(&self.axes)
    }

    /// `[[axes]]`: count, letters (once each) and positive dynamics.
    fn validate_axes(&self) -> Result<(), InvalidConfig> {
        if self.axes.is_empty() || self.axes.len() > kernel::MAX_AXES {
            return Err(InvalidConfig::BadValue {
                key: "axes".into(),
                detail: format!(
                    "{} axes configured, between 1 and {} are supported",
                    self.axes.len(),
                    kernel::MAX_AXES
                ),
            });
        }
        for (i, a) in self.axes.iter().enumerate() {
            if !a.name.is_ascii_uppercase() {
                return Err(InvalidConfig::BadValue {
                    key: format!("axes[{i}].name"),
                    detail: format!("'{}' is not an axis letter A..Z", a.name),
                });
            }
            if !kernel::constants::AXIS_CODES.contains(&a.name) {
                return Err(InvalidConfig::BadValue {
                    key: format!("axes[{i}].name"),
                    detail: format!(
                        "'{}' is not one of the controller's axis letters {}",
                        a.name,
                        kernel::constants::AXIS_CODES.iter().collect::<String>()
                    ),
                });
            }
            if self.axes[..i].iter().any(|b| b.name == a.name) {
                return Err(InvalidConfig::Duplicate {
                    key: format!("axes[{i}].name"),
                    detail: format!("axis {} appears twice", a.name),
                });
            }
            for (key, v) in [
                ("max_velocity_mm_min", a.max_velocity_mm_min),
                ("max_accel_mm_s2", a.max_accel_mm_s2),
                ("increments_per_mm", a.increments_per_mm),
            ] {
                if !(v.is_finite() && v > 0.0) {
                    return Err(InvalidConfig::BadValue {
                        key: format!("axes[{i}].{key}"),
                        detail: format!("{v} must be a positive number"),
                    });
                }
            }
            if let Some(p) = a.rotary_pulses_per_rev
                && !(p.is_finite() && p > 0.0)
            {
                return Err(InvalidConfig::BadValue {
                    key: format!("axes[{i}].rotary_pulses_per_rev"),
                    detail: format!("{p} must be a positive number of pulses"),
                });
            }
        }
        Ok(())
    }

    /// `[[kr.gears]]`: positive top speed, output within the DAC range.
    fn validate_gears(&self) -> Result<(), InvalidConfig> {
        for (i, g) in self.kr.gears.iter().enumerate() {
            if !(g.max_rpm.is_finite() && g.max_rpm > 0.0) {
                return Err(InvalidConfig::BadValue {
                    key: format!("kr.gears[{i}].max_rpm"),
                    detail: format!("{} must be a positive speed", g.max_rpm),
                });
            }
            if !(1..=0x7FFF).contains(&g.output_range) {
                return Err(InvalidConfig::BadValue {
                    key: format!("kr.gears[{i}].output_range"),
                    detail: format!("{} is outside 1..32767", g.output_range),
                });
            }
        }
        Ok(())
    }

    /// `[storage]`: a directory and two different files.
    fn validate_storage(&self) -> Result<(), InvalidConfig> {
        if self.storage.dir.as_os_str().is_empty() {
            return Err(InvalidConfig::Missing {
                key: "storage.dir".into(),
                detail: "must name a directory".into(),
            });
        }
        for (key, f) in [
            ("storage.offsets_file", &self.storage.offsets_file),
            ("storage.constants_file", &self.storage.constants_file),
        ] {
            if f.file_name().is_none() {
                return Err(InvalidConfig::Missing {
                    key: key.to_string(),
                    detail: format!("{f:?} must name a file"),
                });
            }
        }
        if self.storage.offsets_path() == self.storage.constants_path() {
            return Err(InvalidConfig::Duplicate {
                key: "storage.constants_file".into(),
                detail: "the same file as storage.offsets_file".into(),
            });
        }
        Ok(())
    }

    /// `[sim]`, `[planner]` and `[rt]` ranges.
    fn validate_sim_planner_rt(&self) -> Result<(), InvalidConfig> {
        for (key, v) in [
            ("sim.kv_per_s", self.sim.kv_per_s),
            ("sim.following_window_mm", self.sim.following_window_mm),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(InvalidConfig::BadValue {
                    key: key.to_string(),
                    detail: format!("{v} must be a positive number"),
                });
            }
        }
        let ramp = self.sim.spindle_ramp_rpm_s;
        if !(ramp.is_finite() && ramp >= 0.0) {
            return Err(InvalidConfig::BadValue {
                key: "sim.spindle_ramp_rpm_s".into(),
                detail: format!("{ramp} must be 0 (at once) or a positive number"),
            });
        }
        let t = self.planner.min_block_time_ms;
        if !(t.is_finite() && (0.0..=1000.0).contains(&t)) {
            return Err(InvalidConfig::BadValue {
                key: "planner.min_block_time_ms".into(),
                detail: format!("{t} is outside 0..1000 ms"),
            });
        }
        if !(1..=99).contains(&self.rt.priority) {
            return Err(InvalidConfig::BadValue {
                key: "rt.priority".into(),
                detail: format!("{} is outside 1..99", self.rt.priority),
            });
        }
        Ok(())
    }

    pub fn axis_names(&self) -> Vec<char> {
        self.axes.iter().map(|a| a.name).collect()
    }

    /// The soft limits of every axis (issue #15); unset sides are unlimited.
    pub fn soft_limits(&self) -> kernel::limits::SoftLimits {
        let mut l = kernel::limits::SoftLimits::NONE;
        for (i, a) in self.axes.iter().enumerate().take(kernel::MAX_AXES) {
            l.min_mm[i] = a.soft_min_mm.unwrap_or(f64::NEG_INFINITY);
            l.max_mm[i] = a.soft_max_mm.unwrap_or(f64::INFINITY);
        }
        l
    }
}

/// Soft limits and the stop deceleration of axis `i`.
fn validate_axis_safety(i: usize, a: &AxisConfig) -> Result<(), InvalidConfig> {
    for (key, v) in [
        ("soft_min_mm", a.soft_min_mm),
        ("soft_max_mm", a.soft_max_mm),
    ] {
        if let Some(v) = v
            && !v.is_finite()
        {
            return Err(InvalidConfig::BadValue {
                key: format!("axes[{i}].{key}"),
                detail: format!("{v} is not a number"),
            });
        }
    }
    if let (Some(lo), Some(hi)) = (a.soft_min_mm, a.soft_max_mm)
        && lo >= hi
    {
        return Err(InvalidConfig::BadValue {
            key: format!("axes[{i}].soft_max_mm"),
            detail: format!("{hi} must be above soft_min_mm {lo}"),
        });
    }
    if a.homing_direction != 1 && a.homing_direction != -1 {
        return Err(InvalidConfig::BadValue {
            key: format!("axes[{i}].homing_direction"),
            detail: format!("{} must be -1 or 1", a.homing_direction),
        });
    }
    if let Some(v) = a.homing_speed_mm_min
        && !(v.is_finite() && v > 0.0 && v <= a.max_velocity_mm_min)
    {
        return Err(InvalidConfig::BadValue {
            key: format!("axes[{i}].homing_speed_mm_min"),
            detail: format!("{v} must be above 0 and at most max_velocity_mm_min"),
        });
    }
    if let Some(v) = a.homing_zero_speed_mm_min
        && !(v.is_finite() && v > 0.0 && v <= a.max_velocity_mm_min)
    {
        return Err(InvalidConfig::BadValue {
            key: format!("axes[{i}].homing_zero_speed_mm_min"),
            detail: format!("{v} must be above 0 and at most max_velocity_mm_min"),
        });
    }
    if let Some(v) = a.homing_accel_mm_s2
        && !(v.is_finite() && v > 0.0)
    {
        return Err(InvalidConfig::BadValue {
            key: format!("axes[{i}].homing_accel_mm_s2"),
            detail: format!("{v} must be a positive number"),
        });
    }
    if let Some(d) = a.stop_decel_mm_s2
        && !(d.is_finite() && d > 0.0)
    {
        return Err(InvalidConfig::BadValue {
            key: format!("axes[{i}].stop_decel_mm_s2"),
            detail: format!("{d} must be a positive number"),
        });
    }
    Ok(())
}

// ---- [bus] section (opened by `super::buses`) ----------------------------------------------

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

/// `[bus] kind = "can"`. Times in ms are converted to ticks of `cycle_ms`.
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

/// `[bus] kind = "serial"`.
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
    let range = super::resample::CYCLE_MS_RANGE;
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
            BusConfig::Can(c) => {
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
                for (i, a) in axes.iter().enumerate() {
                    let Some(id) = a.node_id else {
                        return Err(InvalidConfig::Missing {
                            key: format!("axes[{i}].node_id"),
                            detail: format!(
                                "axis {} needs the CANopen node id of its drive",
                                a.name
                            ),
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
            BusConfig::Serial(s) => validate_serial(s, axes),
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_file_is_the_simulated_mill() {
        let c = Config::parse("", Path::new("x.toml")).unwrap();
        assert_eq!(c.axis_names(), ['X', 'Y', 'Z']);
        assert_eq!(c.api.listen.port(), 50051);
    }

    #[test]
    fn mistakes_name_the_key() {
        let e = Config::parse(
            "[[axes]]\nname = 'X'\nmax_accel_mm_s2 = -1\n",
            Path::new("m.toml"),
        )
        .unwrap_err();
        assert!(e.to_string().contains("axes[0].max_accel_mm_s2"), "{e}");
        let ConfigError::Invalid { source, .. } = &e else {
            panic!("{e}")
        };
        assert_eq!(
            (source.code(), source.key()),
            ("config_bad_value", "axes[0].max_accel_mm_s2")
        );
        let mut twice = Config::default();
        twice.axes[1].name = twice.axes[0].name;
        let e = twice.validate().unwrap_err();
        assert_eq!((e.code(), e.key()), ("config_duplicate", "axes[1].name"));
        let mut half_tls = Config::default();
        half_tls.api.tls_cert = Some("cert.pem".into());
        let e = half_tls.validate().unwrap_err();
        assert_eq!(e.code(), "config_missing");
        let e = Config::parse("[api]\nlisten = 5\n", Path::new("m.toml")).unwrap_err();
        assert!(e.to_string().contains("listen"), "{e}");
        let e = Config::parse("[rt]\nprio = 5\n", Path::new("m.toml")).unwrap_err();
        assert!(e.to_string().contains("prio"), "{e}");
    }

    // SPEC §2: I J relative (default) or absolute, a setting.
    #[test]
    fn program_ij_setting() {
        let c = Config::parse("", Path::new("x.toml")).unwrap();
        assert_eq!(c.program.ij, IjSetting::Relative);
        let c = Config::parse("[program]\nij = \"absolute\"\n", Path::new("x.toml")).unwrap();
        assert_eq!(
            kernel::program::IjMode::from(c.program.ij),
            kernel::program::IjMode::Absolute
        );
        let e =
            Config::parse("[program]\nij = \"incremental\"\n", Path::new("m.toml")).unwrap_err();
        assert!(e.to_string().contains("ij"), "{e}");
    }
}
