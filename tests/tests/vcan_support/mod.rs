//! Helpers for the vcan and serial suites: locating the simulator and daemon binaries,
//! child processes that die with the test, a 4 ms ticker, and the vcan skip rule.
#![allow(dead_code)]

use std::io::{BufRead, BufReader, Write};
use std::path::PathBuf;
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc;
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

pub const IFACE: &str = "vcan0";

/// The vcan tests share one bus, so within a test binary they run one at a time (cargo runs
/// test binaries one after another).
pub fn vcan_lock() -> MutexGuard<'static, ()> {
    static LOCK: Mutex<()> = Mutex::new(());
    LOCK.lock().unwrap_or_else(|e| e.into_inner())
}

/// True when `vcan0` exists. Without it the test is skipped with a message, unless
/// `CNC_REQUIRE_VCAN=1` (set by `tests/vcan/run.sh`), where a missing vcan0 fails.
pub fn vcan_ready(test: &str) -> bool {
    if std::path::Path::new("/sys/class/net").join(IFACE).exists() {
        return true;
    }
    if std::env::var("CNC_REQUIRE_VCAN").is_ok_and(|v| v == "1") {
        panic!("{test}: CNC_REQUIRE_VCAN=1 but there is no {IFACE}");
    }
    println!(
        "SKIPPED {test}: no {IFACE} on this machine (the kernel lacks vcan?); \
         tests/vcan/run.sh runs this suite in a VM"
    );
    false
}

/// Directory of the workspace binaries (`target/debug`), found from the test executable
/// (`target/debug/deps/<test>`).
pub fn bin(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    let dir = exe.parent().and_then(|d| d.parent()).expect("target dir");
    let p = dir.join(name);
    assert!(
        p.exists(),
        "{} is not built: run `cargo build -p sim -p daemon --bins` first \
         (cargo test --workspace builds them)",
        p.display()
    );
    p
}

/// A child process killed when dropped; its stdout lines arrive on a channel.
pub struct Proc {
    pub name: String,
    child: Child,
    stdin: Option<ChildStdin>,
    lines: mpsc::Receiver<String>,
}

impl Proc {
    pub fn spawn(name: &str, args: &[&str]) -> Proc {
        let mut child = Command::new(bin(name))
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {name}: {e}"));
        let stdout = child.stdout.take().unwrap();
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for l in BufReader::new(stdout).lines().map_while(Result::ok) {
                if tx.send(l).is_err() {
                    return;
                }
            }
        });
        Proc {
            name: name.to_owned(),
            stdin: child.stdin.take(),
            child,
            lines,
        }
    }

    /// Waits for a stdout line containing `what`; returns it.
    pub fn expect_line(&mut self, what: &str, timeout: Duration) -> String {
        let end = Instant::now() + timeout;
        loop {
            let left = end.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(l) if l.contains(what) => return l,
                Ok(_) => {}
                Err(_) => panic!("{}: no line with '{what}' within {timeout:?}", self.name),
            }
        }
    }

    /// Sends a fault-injection command line.
    pub fn send(&mut self, line: &str) {
        let s = self.stdin.as_mut().expect("stdin");
        writeln!(s, "{line}").unwrap();
        s.flush().unwrap();
    }

    /// Kills the process (SIGKILL) and reaps it.
    pub fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        self.kill();
    }
}

/// Simulated drives on vcan0, one process for `nodes`; returns once it listens.
pub fn sim_can(nodes: &[u8], extra: &[&str]) -> Proc {
    let mut args = vec!["--iface", IFACE];
    let ids: Vec<String> = nodes.iter().map(u8::to_string).collect();
    for id in &ids {
        args.extend(["--node", id.as_str()]);
    }
    args.extend_from_slice(extra);
    let mut p = Proc::spawn("sim-can", &args);
    p.expect_line("ready", Duration::from_secs(20));
    p
}

/// Absolute 4 ms deadlines, like the daemon's RT loop: a late tick skips missed deadlines.
pub struct Ticker {
    next: Instant,
}

impl Default for Ticker {
    fn default() -> Self {
        Ticker {
            next: Instant::now(),
        }
    }
}

impl Ticker {
    pub fn wait(&mut self) {
        let tick = Duration::from_millis(4);
        self.next += tick;
        let now = Instant::now();
        if self.next > now {
            std::thread::sleep(self.next - now);
        } else {
            while self.next + tick <= now {
                self.next += tick;
            }
        }
    }
}

/// A fresh temporary directory for one test.
pub fn temp_dir(test: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("cnc-{test}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}
