//! Shared by the tests that run the real `cncd` binary (`systemd_notify.rs`,
//! `check_config.rs`); each uses a part of it.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// The repository root.
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The `cncd` binary of this build ([`tests::workspace_bin`]).
pub fn cncd_binary() -> PathBuf {
    tests::workspace_bin("cncd")
}
