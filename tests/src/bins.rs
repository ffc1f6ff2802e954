//! The workspace's programs (`cncd`, `cncctl`, `sim-can`, `sim-serial`) as the suites start
//! them: the binaries of this build, next to the test executables.

use std::path::PathBuf;
use std::process::Command;
use std::sync::Mutex;

/// Path of workspace binary `name` of this build (target/<profile>/<name>).
///
/// `cargo test --workspace` builds them there (daemon and sim have integration tests), with
/// the test run's features. `CNC_PREBUILT_BINS=1` (scripts/test-all.sh after its `--no-run`
/// build, and the vcan VM, which has no cargo) takes them as they are. Otherwise each is
/// built here once per test process, into the same target directory.
pub fn workspace_bin(name: &str) -> PathBuf {
    static BUILT: Mutex<Vec<String>> = Mutex::new(Vec::new());
    let exe = std::env::current_exe().expect("test executable path");
    // target/<profile>/deps/<test> → target/<profile>
    let profile_dir = exe.parent().and_then(|d| d.parent()).expect("target dir");
    let p = profile_dir.join(name);
    let prebuilt = std::env::var("CNC_PREBUILT_BINS").is_ok_and(|v| v == "1");
    let mut built = BUILT.lock().unwrap_or_else(|e| e.into_inner());
    if !prebuilt && !built.iter().any(|b| b == name) {
        let package = if name.starts_with("sim-") {
            "sim"
        } else {
            "daemon"
        };
        let mut cmd = Command::new(env!("CARGO"));
        cmd.args(["build", "--quiet", "-p", package, "--bin", name])
            .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/.."));
        // What cargo sets for this test process only: a build script (ring's) watches some
        // of it (CARGO_MANIFEST_DIR, CARGO_PKG_NAME…), and inherited here it rebuilt half the
        // dependency tree at every switch between `cargo test` and a plain `cargo build`.
        for (key, _) in std::env::vars_os() {
            let k = key.to_string_lossy();
            if ["CARGO_PKG_", "CARGO_MANIFEST_", "CARGO_BIN_"]
                .iter()
                .any(|p| k.starts_with(p))
                || [
                    "CARGO_CRATE_NAME",
                    "CARGO_PRIMARY_PACKAGE",
                    "CARGO_TARGET_TMPDIR",
                    "CARGO_RUSTC_CURRENT_DIR",
                    "OUT_DIR",
                ]
                .contains(&k.as_ref())
            {
                cmd.env_remove(&key);
            }
        }
        if let Some(target) = profile_dir.parent() {
            cmd.arg("--target-dir").arg(target);
        }
        if profile_dir.file_name().is_some_and(|n| n == "release") {
            cmd.arg("--release");
        }
        let ok = cmd.status().is_ok_and(|s| s.success());
        assert!(ok, "cargo build of {name} failed");
        built.push(name.to_owned());
    }
    assert!(p.exists(), "{} is not built", p.display());
    p
}
