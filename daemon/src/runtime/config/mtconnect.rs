//! `[mtconnect]`: the MTConnect agent (docs/mtconnect.md *Configuration*).

use std::net::SocketAddr;

use serde::Deserialize;

use super::InvalidConfig;

/// The agent's settings. On by default on loopback at the port agents conventionally use.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MtconnectConfig {
    /// Serve the agent at all.
    #[serde(default = "default_enabled")]
    pub enabled: bool,
    /// HTTP listen address. A non-loopback address is served over TLS with the API's
    /// certificate (`api.tls_cert`, `api.tls_key`), and refused without it.
    #[serde(default = "default_listen")]
    pub listen: SocketAddr,
    /// Observations the buffer holds (`bufferSize`): `/sample` can resume from any of them.
    #[serde(default = "default_buffer_size")]
    pub buffer_size: usize,
    /// Device name (`/probe`, `/{name}/current`).
    #[serde(default = "default_device_name")]
    pub device_name: String,
    /// Device uuid: give each machine of a shop its own, stable across restarts.
    #[serde(default = "default_device_uuid")]
    pub device_uuid: String,
    /// How often the agent looks at the controller's status, ms (samples are at most this
    /// fine; events such as Execution are never lost, they persist in the status).
    #[serde(default = "default_sample_period_ms")]
    pub sample_period_ms: u64,
    /// Most `/sample` or `/current` streams (`interval=`) open at once (TOO_MANY beyond).
    #[serde(default = "default_max_streams")]
    pub max_streams: usize,
}

fn default_enabled() -> bool {
    true
}
fn default_listen() -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], 5000))
}
fn default_buffer_size() -> usize {
    131_072
}
fn default_device_name() -> String {
    "cncd".into()
}
fn default_device_uuid() -> String {
    "cncd-machine".into()
}
fn default_sample_period_ms() -> u64 {
    10
}
fn default_max_streams() -> usize {
    32
}

impl Default for MtconnectConfig {
    fn default() -> Self {
        MtconnectConfig {
            enabled: default_enabled(),
            listen: default_listen(),
            buffer_size: default_buffer_size(),
            device_name: default_device_name(),
            device_uuid: default_device_uuid(),
            sample_period_ms: default_sample_period_ms(),
            max_streams: default_max_streams(),
        }
    }
}

fn bad(key: &str, detail: String) -> InvalidConfig {
    InvalidConfig::BadValue {
        key: key.into(),
        detail,
    }
}

impl MtconnectConfig {
    /// Ranges and names; a non-loopback `listen` needs the API's TLS files (`tls`: both
    /// `api.tls_cert` and `api.tls_key` are set).
    pub fn validate(&self, tls: bool) -> Result<(), InvalidConfig> {
        if !(16..=16_777_216).contains(&self.buffer_size) {
            return Err(bad(
                "mtconnect.buffer_size",
                format!("{} is outside 16..16777216 observations", self.buffer_size),
            ));
        }
        let name_ok = |s: &str| {
            !s.is_empty()
                && s.chars()
                    .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'))
        };
        if !name_ok(&self.device_name) {
            return Err(bad(
                "mtconnect.device_name",
                format!(
                    "{:?}: letters, digits, '_', '-' and '.' only",
                    self.device_name
                ),
            ));
        }
        if self.device_uuid.trim().is_empty() {
            return Err(bad("mtconnect.device_uuid", "must not be empty".into()));
        }
        if !(1..=1000).contains(&self.sample_period_ms) {
            return Err(bad(
                "mtconnect.sample_period_ms",
                format!("{} is outside 1..1000 ms", self.sample_period_ms),
            ));
        }
        if self.max_streams == 0 {
            return Err(bad("mtconnect.max_streams", "must be at least 1".into()));
        }
        if self.enabled && !self.listen.ip().is_loopback() && !tls {
            return Err(InvalidConfig::Missing {
                key: "mtconnect.listen".into(),
                detail: format!(
                    "{} is not a loopback address: serving the agent beyond the machine needs \
                     TLS (api.tls_cert and api.tls_key)",
                    self.listen
                ),
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_non_loopback_agent_needs_tls_and_bad_values_name_their_key() {
        let mut c = MtconnectConfig::default();
        assert_eq!(c.validate(false), Ok(()));
        c.listen = "192.168.10.2:5000".parse().unwrap();
        let e = c.validate(false).unwrap_err();
        assert_eq!((e.code(), e.key()), ("config_missing", "mtconnect.listen"));
        assert_eq!(c.validate(true), Ok(()));
        c.enabled = false;
        assert_eq!(c.validate(false), Ok(()));
        let mut c = MtconnectConfig {
            buffer_size: 8,
            ..MtconnectConfig::default()
        };
        assert_eq!(
            c.validate(false).unwrap_err().key(),
            "mtconnect.buffer_size"
        );
        c.buffer_size = 1024;
        c.device_name = "my machine".into();
        assert_eq!(
            c.validate(false).unwrap_err().key(),
            "mtconnect.device_name"
        );
    }
}
