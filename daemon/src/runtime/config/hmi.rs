//! `[hmi]`: the browser HMI's listener (issue #30, docs/hmi.md): the HMI's files and every
//! gRPC service over grpc-web on one origin.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::{ApiConfig, InvalidConfig};

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct HmiSection {
    /// Serve the HMI at all.
    #[serde(default = "default_enabled")]
    pub enabled: bool,
    /// Loopback: tokenless browsers get `api.loopback_role`; any other address needs TLS and
    /// tokens, as a remote API listener does.
    #[serde(default = "default_listen")]
    pub listen: SocketAddr,
    /// TLS of a non-loopback `listen`; unset, `api.tls_cert` and `api.tls_key` are used.
    #[serde(default)]
    pub tls_cert: Option<PathBuf>,
    #[serde(default)]
    pub tls_key: Option<PathBuf>,
}

fn default_enabled() -> bool {
    true
}

fn default_listen() -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], 8080))
}

impl Default for HmiSection {
    fn default() -> Self {
        HmiSection {
            enabled: default_enabled(),
            listen: default_listen(),
            tls_cert: None,
            tls_key: None,
        }
    }
}

/// The certificate and key of the HMI, with the keys they were configured under.
pub struct HmiTlsFiles<'a> {
    pub cert: (&'static str, &'a Path),
    pub key: (&'static str, &'a Path),
}

impl HmiSection {
    /// The TLS files in force: this section's, else the API's; `None` when neither is set.
    pub fn tls_files<'a>(&'a self, api: &'a ApiConfig) -> Option<HmiTlsFiles<'a>> {
        match (&self.tls_cert, &self.tls_key, &api.tls_cert, &api.tls_key) {
            (Some(c), Some(k), _, _) => Some(HmiTlsFiles {
                cert: ("hmi.tls_cert", c),
                key: ("hmi.tls_key", k),
            }),
            (None, None, Some(c), Some(k)) => Some(HmiTlsFiles {
                cert: ("api.tls_cert", c),
                key: ("api.tls_key", k),
            }),
            _ => None,
        }
    }

    /// Checks the listener against TLS, tokens and the API's addresses; the message names
    /// the key.
    pub fn validate(&self, api: &ApiConfig) -> Result<(), InvalidConfig> {
        if self.tls_cert.is_some() != self.tls_key.is_some() {
            return Err(InvalidConfig::Missing {
                key: "hmi.tls_cert, hmi.tls_key".into(),
                detail: "give both or neither".into(),
            });
        }
        if !self.enabled {
            return Ok(());
        }
        let a = self.listen;
        if !a.ip().is_loopback() {
            if self.tls_files(api).is_none() {
                return Err(InvalidConfig::Missing {
                    key: "hmi.tls_cert, hmi.tls_key".into(),
                    detail: format!(
                        "listening on {a} (not loopback) requires TLS (these, or api.tls_cert \
                         and api.tls_key)"
                    ),
                });
            }
            if api.tokens.is_empty() {
                return Err(InvalidConfig::Missing {
                    key: "api.tokens".into(),
                    detail: format!(
                        "the HMI listening on {a} (not loopback) requires at least one token"
                    ),
                });
            }
        }
        if a.port() != 0 && api.tcp_addresses().contains(&a) {
            return Err(InvalidConfig::Duplicate {
                key: "hmi.listen".into(),
                detail: format!("{a} is also an API address (api.listen, api.extra_listen)"),
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_serve_on_loopback_8080() {
        let h = HmiSection::default();
        assert!(h.enabled);
        assert_eq!(h.listen.to_string(), "127.0.0.1:8080");
        assert!(h.validate(&ApiConfig::default()).is_ok());
    }

    #[test]
    fn a_remote_hmi_needs_tls_and_a_token() {
        let h = HmiSection {
            listen: "0.0.0.0:8443".parse().unwrap(),
            ..HmiSection::default()
        };
        let mut api = ApiConfig::default();
        let e = h.validate(&api).unwrap_err();
        assert_eq!(e.key(), "hmi.tls_cert, hmi.tls_key");
        api.tls_cert = Some("c.pem".into());
        api.tls_key = Some("k.pem".into());
        assert_eq!(h.validate(&api).unwrap_err().key(), "api.tokens");
        let off = HmiSection {
            enabled: false,
            ..h.clone()
        };
        assert!(off.validate(&ApiConfig::default()).is_ok());
    }

    #[test]
    fn the_hmi_port_is_not_an_api_port() {
        let h = HmiSection {
            listen: ApiConfig::default().listen,
            ..HmiSection::default()
        };
        assert_eq!(
            h.validate(&ApiConfig::default()).unwrap_err().code(),
            "config_duplicate"
        );
    }
}
