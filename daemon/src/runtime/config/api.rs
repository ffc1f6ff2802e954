//! `[api]`: listeners, TLS, roles and tokens of the gRPC API.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::InvalidConfig;

/// `[api]`: listeners and access control of the gRPC API (docs/api.md).
///
/// Callers without a token get `local_role` on the Unix socket (its mode and group decide who
/// may connect) and `loopback_role` on loopback TCP (every local account can connect there, so
/// the default is observer); any other address needs TLS and a bearer token from `tokens`.
///
/// One field per key of `[api]`, which mixes listeners, TLS, roles and tokens, and stream
/// limits: grouping them would need `#[serde(flatten)]`, which loses `deny_unknown_fields`
/// (the check that names a mistyped key), so the fields stay flat in the file's order of
/// concerns.
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
    /// Machining time `GetPreview`'s velocity plot covers at most, hours (default 8, at most
    /// 24): its work grows with that time, not with the text, and plots run one at a time.
    #[serde(default = "default_velocity_plot_max_h")]
    pub velocity_plot_max_h: f64,
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
fn default_velocity_plot_max_h() -> f64 {
    ::preview::DEFAULT_PLOT_MAX_TICKS as f64 * kernel::TS_S / 3600.0
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
            velocity_plot_max_h: default_velocity_plot_max_h(),
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

    /// Ticks (4 ms) of [`ApiConfig::velocity_plot_max_h`].
    pub fn velocity_plot_max_ticks(&self) -> u64 {
        (self.velocity_plot_max_h * 3600.0 / kernel::TS_S)
            .round()
            .max(1.0) as u64
    }

    /// Checks listeners, TLS, tokens and the plot's bound; the message names the key.
    pub fn validate(&self) -> Result<(), InvalidConfig> {
        let h = self.velocity_plot_max_h;
        if !(h > 0.0 && h <= 24.0) {
            return Err(InvalidConfig::BadValue {
                key: "api.velocity_plot_max_h".into(),
                detail: format!("{h} is not a number of hours in (0, 24]"),
            });
        }
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
