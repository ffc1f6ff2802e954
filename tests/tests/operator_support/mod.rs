//! The operator's doors for the issue #31 tests: the real `cncd` binary in a temporary
//! directory (its own data dir, runtime dir and a loopback port of its own) and the real
//! `cncctl`, run as a person runs them.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

#[path = "../vcan_support/mod.rs"]
mod vcan_support;

pub use vcan_support::bin;

/// How long a condition may take before the test calls it a hang (a bound, not a timing).
pub const PATIENCE: Duration = Duration::from_secs(120);

/// A fresh directory for one test.
pub fn temp_dir(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("op_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A `cncd` process, killed when dropped.
pub struct Cncd {
    pub child: Child,
    /// Where it runs (its configuration and data dir are here).
    pub cwd: PathBuf,
    /// Its data directory.
    pub data: PathBuf,
    /// Where it publishes its socket (`CNCD_RUNTIME_DIR`).
    pub runtime: PathBuf,
}

/// The simulated mill with everything local to `cwd`: data in `cwd/data`, the API, the HMI
/// and the MTConnect agent on loopback ports of their own (tests run side by side) and the
/// Unix socket in the data dir.
pub const MILL_TOML: &str = "[storage]\ndir = \"data\"\n\n[api]\nlisten = \"127.0.0.1:0\"\n\n\
[hmi]\nlisten = \"127.0.0.1:0\"\n\n[mtconnect]\nlisten = \"127.0.0.1:0\"\n\n[rt]\nlock_memory = false\n";

impl Cncd {
    /// Starts `cncd --config cncd.toml` in `cwd` (writing `toml` there first).
    pub fn start(cwd: &Path, toml: &str) -> Cncd {
        std::fs::write(cwd.join("cncd.toml"), toml).unwrap();
        Self::spawn(cwd, &["--config", "cncd.toml"], &cwd.join("data"))
    }

    /// Starts `cncd ARGS` in `cwd`, its data dir being `data`, publishing into `cwd/run`.
    pub fn spawn(cwd: &Path, args: &[&str], data: &Path) -> Cncd {
        let runtime = cwd.join("run");
        std::fs::create_dir_all(&runtime).unwrap();
        let log = std::fs::File::create(cwd.join("cncd.log")).unwrap();
        let child = Command::new(bin("cncd"))
            .args(args)
            .current_dir(cwd)
            .env("CNCD_RUNTIME_DIR", &runtime)
            .env("RUST_LOG", "info")
            .stdin(Stdio::null())
            .stdout(log.try_clone().unwrap())
            .stderr(log)
            .spawn()
            .unwrap();
        let d = Cncd {
            child,
            cwd: cwd.to_owned(),
            data: data.to_owned(),
            runtime,
        };
        d.wait_idle();
        d
    }

    /// `unix:<data>/cncd.sock`.
    pub fn addr(&self) -> String {
        format!("unix:{}", self.data.join("cncd.sock").display())
    }

    /// Waits until the daemon answers and is idle.
    pub fn wait_idle(&self) {
        wait_for("cncd idle", || {
            let (ok, out) = cncctl_at(&self.cwd, &["--addr", &self.addr(), "--json", "status"]);
            ok && out.contains("\"state\":\"idle\"")
        });
    }

    /// `cncctl --addr <socket> ARGS` from this daemon's directory.
    pub fn cncctl(&self, args: &[&str]) -> (bool, String) {
        let mut all = vec!["--addr".to_string(), self.addr()];
        all.extend(args.iter().map(|s| s.to_string()));
        let all: Vec<&str> = all.iter().map(String::as_str).collect();
        cncctl_at(&self.cwd, &all)
    }

    /// `cncctl --json ARGS`, which must succeed: its one JSON object.
    pub fn json(&self, args: &[&str]) -> serde_json::Value {
        let mut all = vec!["--json"];
        all.extend_from_slice(args);
        let (ok, out) = self.cncctl(&all);
        assert!(ok, "cncctl {args:?}: {out}\n{}", self.log());
        serde_json::from_str(out.trim()).expect("one JSON object")
    }

    /// `cncctl jog AXIS --step STEP`, then waits until the step is done: idle with the axis at
    /// the jog's target (not only idle, which the machine was before the step too). Returns the
    /// target, mm.
    pub fn jog_step(&self, axis: &str, step_mm: f64) -> f64 {
        let r = self.json(&["jog", axis, "--step", &format!("{step_mm}")]);
        let target = r["target_mm"].as_f64().expect("the jog's target");
        wait_for("the jog step done", || {
            let s = self.json(&["status"]);
            let at = s["axes"]
                .as_array()
                .unwrap()
                .iter()
                .find(|a| a["name"] == axis)
                .and_then(|a| a["commanded_mm"].as_f64());
            s["state"] == "idle" && at.is_some_and(|mm| (mm - target).abs() < 1e-9)
        });
        target
    }

    /// SIGKILL, as a power cut or the OOM killer would.
    pub fn kill9(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }

    /// The daemon's log so far (for failure messages).
    pub fn log(&self) -> String {
        std::fs::read_to_string(self.cwd.join("cncd.log")).unwrap_or_default()
    }
}

impl Drop for Cncd {
    fn drop(&mut self) {
        self.kill9();
    }
}

/// Runs `cncctl ARGS` in `cwd` with `CNCD_RUNTIME_DIR` pointing at `cwd/run` and no
/// `$CNCCTL_ADDR`: success and standard output + error.
pub fn cncctl_at(cwd: &Path, args: &[&str]) -> (bool, String) {
    let mut cmd = Command::new(bin("cncctl"));
    cmd.args(args)
        .current_dir(cwd)
        .env_remove("CNCCTL_ADDR")
        .env("CNCD_RUNTIME_DIR", cwd.join("run"));
    vcan_support::run_with_timeout(&mut cmd, Duration::from_secs(60))
}

/// Waits until `f` holds; fails after [`PATIENCE`].
pub fn wait_for(what: &str, mut f: impl FnMut() -> bool) {
    let t0 = Instant::now();
    while !f() {
        assert!(t0.elapsed() < PATIENCE, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Saves `text` as an editor that writes a new file and renames it over the old one does.
pub fn save_by_rename(path: &Path, text: &str) {
    let tmp = path.with_extension("swp");
    std::fs::write(&tmp, text).unwrap();
    std::fs::rename(&tmp, path).unwrap();
}
