//! Shared by the tests that run the real `cncd` binary (`systemd_notify.rs`,
//! `check_config.rs`); each uses a part of it.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;
use std::time::SystemTime;

/// The repository root.
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The `cncd` binary of this build. The tests package cannot name another package's binary:
/// `cargo test --workspace` builds it next to the test executables (daemon has integration
/// tests); when it is missing or older than any source it is built from, it is built here with
/// `cargo build -p daemon --bin cncd` into the same target directory. Once per test process.
pub fn cncd_binary() -> PathBuf {
    static BIN: OnceLock<PathBuf> = OnceLock::new();
    BIN.get_or_init(|| {
        let exe = std::env::current_exe().unwrap();
        // target/<profile>/deps/<test> → target/<profile>
        let profile_dir = exe.parent().and_then(Path::parent).unwrap().to_owned();
        let bin = profile_dir.join("cncd");
        if built_after_sources(&bin) {
            return bin;
        }
        let mut cmd = Command::new(env!("CARGO"));
        cmd.args(["build", "--quiet", "-p", "daemon", "--bin", "cncd"])
            .current_dir(repo());
        // The same target directory however the outer run chose it (env or --target-dir).
        if let Some(target) = profile_dir.parent() {
            cmd.arg("--target-dir").arg(target);
        }
        if profile_dir.file_name().is_some_and(|n| n == "release") {
            cmd.arg("--release");
        }
        let status = cmd.status().expect("running cargo build for cncd");
        assert!(status.success(), "cargo build of cncd failed");
        assert!(bin.exists(), "{} missing after the build", bin.display());
        bin
    })
    .clone()
}

/// True when `bin` exists and is newer than every source file of the crates it is built from.
fn built_after_sources(bin: &Path) -> bool {
    let Ok(built) = bin.metadata().and_then(|m| m.modified()) else {
        return false;
    };
    let root = repo();
    let mut newest = SystemTime::UNIX_EPOCH;
    for dir in ["daemon", "kernel", "hal", "sim", "proto"] {
        newest_in(&root.join(dir), &mut newest);
    }
    for f in ["Cargo.toml", "Cargo.lock"] {
        if let Ok(t) = root.join(f).metadata().and_then(|m| m.modified()) {
            newest = newest.max(t);
        }
    }
    built >= newest
}

fn newest_in(dir: &Path, newest: &mut SystemTime) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let path = e.path();
        let name = e.file_name();
        if name == "target" || name.to_string_lossy().starts_with('.') {
            continue;
        }
        let Ok(meta) = e.metadata() else { continue };
        if meta.is_dir() {
            newest_in(&path, newest);
        } else if let Ok(t) = meta.modified() {
            *newest = (*newest).max(t);
        }
    }
}
