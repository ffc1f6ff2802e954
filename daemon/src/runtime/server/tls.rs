//! TLS of the remote API listeners (`api.tls_cert`, `api.tls_key`) and of the HMI's listener
//! (`hmi.tls_cert`, `hmi.tls_key`), and their check at `--check-config` and start-up.

use std::path::Path;

use tonic::transport::{Identity, Server, ServerTlsConfig};

use super::ServerError;
use crate::runtime::config::{ApiConfig, Config};

/// TLS settings of remote listeners, when configured.
pub fn tls_config(api: &ApiConfig) -> Result<Option<ServerTlsConfig>, ServerError> {
    match (&api.tls_cert, &api.tls_key) {
        (Some(c), Some(k)) => tls_from_files(("api.tls_cert", c), ("api.tls_key", k)).map(Some),
        _ => Ok(None),
    }
}

/// TLS settings from a PEM certificate and key file, each with the configuration key it
/// came from (named when it cannot be read).
pub fn tls_from_files(
    cert: (&'static str, &Path),
    key: (&'static str, &Path),
) -> Result<ServerTlsConfig, ServerError> {
    let read = |(key, path): (&'static str, &Path)| {
        std::fs::read(path).map_err(|source| ServerError::TlsFile {
            key,
            path: path.to_path_buf(),
            source,
        })
    };
    let (cert, key) = (read(cert)?, read(key)?);
    Ok(ServerTlsConfig::new().identity(Identity::from_pem(cert, key)))
}

/// TLS of the HMI's listener: on a non-loopback `hmi.listen` the HMI's files, else the
/// API's; on loopback only when the HMI's own are set (a loopback screen stays plain HTTP
/// when only the API has a certificate).
pub fn hmi_tls_config(cfg: &Config) -> Result<Option<ServerTlsConfig>, ServerError> {
    let hmi = &cfg.hmi;
    if hmi.listen.ip().is_loopback() && hmi.tls_cert.is_none() {
        return Ok(None);
    }
    hmi.tls_files(&cfg.api)
        .map(|f| tls_from_files(f.cert, f.key))
        .transpose()
}

/// Reads and parses the TLS certificate and key when configured (`--check-config` and
/// start-up): a missing or unreadable file, or PEM without a certificate or key, is refused
/// with the key's name.
pub fn check_tls(api: &ApiConfig) -> Result<(), ServerError> {
    if let Some(t) = tls_config(api)? {
        Server::builder()
            .tls_config(t)
            .map_err(|e| ServerError::Tls(e.to_string()))?;
    }
    Ok(())
}

/// As [`check_tls`] for the HMI's listener when it is enabled.
pub fn check_hmi_tls(cfg: &Config) -> Result<(), ServerError> {
    if !cfg.hmi.enabled {
        return Ok(());
    }
    if let Some(t) = hmi_tls_config(cfg)? {
        Server::builder()
            .tls_config(t)
            .map_err(|e| ServerError::Tls(e.to_string()))?;
    }
    Ok(())
}
