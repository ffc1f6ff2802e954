//! What a configuration that cannot be used reports: stable codes and the key at fault.

use std::path::PathBuf;

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
