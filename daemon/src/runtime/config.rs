//! Daemon configuration: one TOML file. Every key has a default, so an empty file (or none)
//! gives the built-in simulated 3-axis mill.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::buses::BusConfig;

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

impl Default for StorageConfig {
    fn default() -> Self {
        StorageConfig {
            dir: default_storage_dir(),
            offsets_file: default_offsets_file(),
            constants_file: default_constants_file(),
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
}

/// How the controlling axis of constant cutting speed (R67) is read (SPEC §6).
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum RadiusInputConfig {
    /// The axis is programmed as a diameter (lathes): radius = |x| / 2.
    #[default]
    Diameter,
    /// The axis position is the radius.
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
}

fn default_v_max() -> f64 {
    12_000.0
}
fn default_a_max() -> f64 {
    800.0
}
fn default_increments() -> f64 {
    10_000.0
}

impl AxisConfig {
    pub fn new(name: char) -> Self {
        AxisConfig {
            name,
            max_velocity_mm_min: default_v_max(),
            max_accel_mm_s2: default_a_max(),
            increments_per_mm: default_increments(),
            node_id: None,
            home_mm: 0.0,
        }
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
/// Local listeners (the Unix socket and loopback TCP) serve callers without a token with
/// `local_role`; any other address needs TLS and a bearer token from `tokens`.
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
    /// Role of local callers (Unix socket, loopback TCP) that send no token.
    #[serde(default = "default_local_role")]
    pub local_role: Role,
    /// Bearer tokens, stored as SHA-256 hashes (`cncctl hash-token` prints one).
    #[serde(default)]
    pub tokens: Vec<TokenConfig>,
    /// Most status and alarm streams open at once (RESOURCE_EXHAUSTED beyond).
    #[serde(default = "default_max_streams")]
    pub max_streams: u32,
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
fn default_max_streams() -> u32 {
    64
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
            tokens: Vec::new(),
            max_streams: default_max_streams(),
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
    pub fn validate(&self) -> Result<(), String> {
        let remote = self
            .tcp_addresses()
            .into_iter()
            .find(|a| !a.ip().is_loopback());
        if let Some(a) = remote {
            if self.tls_cert.is_none() || self.tls_key.is_none() {
                return Err(format!(
                    "api.tls_cert, api.tls_key: listening on {a} (not loopback) requires TLS"
                ));
            }
            if self.tokens.is_empty() {
                return Err(format!(
                    "api.tokens: listening on {a} (not loopback) requires at least one token"
                ));
            }
        }
        if self.tls_cert.is_some() != self.tls_key.is_some() {
            return Err("api.tls_cert, api.tls_key: give both or neither".into());
        }
        if self.socket_mode > 0o777 {
            return Err(format!(
                "api.socket_mode: {:o} is not a permission mode (0o000..0o777)",
                self.socket_mode
            ));
        }
        for (i, t) in self.tokens.iter().enumerate() {
            if t.sha256.len() != 64 || !t.sha256.bytes().all(|b| b.is_ascii_hexdigit()) {
                return Err(format!(
                    "api.tokens[{i}].sha256: must be 64 hex digits (the SHA-256 of the token)"
                ));
            }
            if self.tokens[..i]
                .iter()
                .any(|u| u.sha256.eq_ignore_ascii_case(&t.sha256))
            {
                return Err(format!(
                    "api.tokens[{i}].sha256: the same token appears twice"
                ));
            }
        }
        if self.max_streams == 0 {
            return Err("api.max_streams: must be at least 1".into());
        }
        Ok(())
    }
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
    #[error("{path}: {message}")]
    Invalid { path: PathBuf, message: String },
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
        cfg.validate().map_err(|message| ConfigError::Invalid {
            path: path.to_owned(),
            message,
        })?;
        Ok(cfg)
    }

    /// Checks what serde cannot: counts, ranges, duplicates. The message names the key.
    pub fn validate(&self) -> Result<(), String> {
        if self.axes.is_empty() || self.axes.len() > kernel::MAX_AXES {
            return Err(format!(
                "axes: {} axes configured, between 1 and {} are supported",
                self.axes.len(),
                kernel::MAX_AXES
            ));
        }
        for (i, a) in self.axes.iter().enumerate() {
            if !a.name.is_ascii_uppercase() {
                return Err(format!(
                    "axes[{i}].name: '{}' is not an axis letter A..Z",
                    a.name
                ));
            }
            if !kernel::constants::AXIS_CODES.contains(&a.name) {
                return Err(format!(
                    "axes[{i}].name: '{}' is not one of the controller's axis letters {}",
                    a.name,
                    kernel::constants::AXIS_CODES.iter().collect::<String>()
                ));
            }
            if self.axes[..i].iter().any(|b| b.name == a.name) {
                return Err(format!("axes[{i}].name: axis {} appears twice", a.name));
            }
            for (key, v) in [
                ("max_velocity_mm_min", a.max_velocity_mm_min),
                ("max_accel_mm_s2", a.max_accel_mm_s2),
                ("increments_per_mm", a.increments_per_mm),
            ] {
                if !(v.is_finite() && v > 0.0) {
                    return Err(format!("axes[{i}].{key}: {v} must be a positive number"));
                }
            }
        }
        for (i, g) in self.kr.gears.iter().enumerate() {
            if !(g.max_rpm.is_finite() && g.max_rpm > 0.0) {
                return Err(format!(
                    "kr.gears[{i}].max_rpm: {} must be a positive speed",
                    g.max_rpm
                ));
            }
            if !(1..=0x7FFF).contains(&g.output_range) {
                return Err(format!(
                    "kr.gears[{i}].output_range: {} is outside 1..32767",
                    g.output_range
                ));
            }
        }
        if self.storage.dir.as_os_str().is_empty() {
            return Err("storage.dir: must name a directory".into());
        }
        for (key, f) in [
            ("storage.offsets_file", &self.storage.offsets_file),
            ("storage.constants_file", &self.storage.constants_file),
        ] {
            if f.file_name().is_none() {
                return Err(format!("{key}: {f:?} must name a file"));
            }
        }
        if self.storage.offsets_path() == self.storage.constants_path() {
            return Err("storage.constants_file: the same file as storage.offsets_file".into());
        }
        for (i, a) in self.axes.iter().enumerate() {
            if !a.home_mm.is_finite() {
                return Err(format!("axes[{i}].home_mm: {} is not a number", a.home_mm));
            }
        }
        for (key, v) in [
            ("sim.kv_per_s", self.sim.kv_per_s),
            ("sim.following_window_mm", self.sim.following_window_mm),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{key}: {v} must be a positive number"));
            }
        }
        let ramp = self.sim.spindle_ramp_rpm_s;
        if !(ramp.is_finite() && ramp >= 0.0) {
            return Err(format!(
                "sim.spindle_ramp_rpm_s: {ramp} must be 0 (at once) or a positive number"
            ));
        }
        if !(1..=99).contains(&self.rt.priority) {
            return Err(format!(
                "rt.priority: {} is outside 1..99",
                self.rt.priority
            ));
        }
        self.api.validate()?;
        self.bus.validate(&self.axes)
    }

    pub fn axis_names(&self) -> Vec<char> {
        self.axes.iter().map(|a| a.name).collect()
    }
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
        let e = Config::parse("[api]\nlisten = 5\n", Path::new("m.toml")).unwrap_err();
        assert!(e.to_string().contains("listen"), "{e}");
        let e = Config::parse("[rt]\nprio = 5\n", Path::new("m.toml")).unwrap_err();
        assert!(e.to_string().contains("prio"), "{e}");
    }
}
