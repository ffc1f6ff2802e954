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

/// Path of a workspace binary (`sim-can`, `sim-serial`, `cncd`, `cncctl`) of this build
/// ([`tests::workspace_bin`]).
pub fn bin(name: &str) -> PathBuf {
    tests::workspace_bin(name)
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

    /// Sends SIGTERM and waits up to `timeout` for the process to end; its exit status.
    pub fn terminate(&mut self, timeout: Duration) -> std::process::ExitStatus {
        let pid = libc::pid_t::try_from(self.child.id()).unwrap();
        // SAFETY: plain syscall on our own child's pid (not yet reaped, so not reused).
        unsafe { libc::kill(pid, libc::SIGTERM) };
        let end = Instant::now() + timeout;
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                return status;
            }
            assert!(
                Instant::now() < end,
                "{} did not end after SIGTERM",
                self.name
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Sends `signal` (SIGSTOP to freeze the process, SIGCONT to thaw it).
    pub fn signal(&self, signal: libc::c_int) {
        let pid = libc::pid_t::try_from(self.child.id()).unwrap();
        // SAFETY: plain syscall on our own child's pid (not yet reaped, so not reused).
        unsafe { libc::kill(pid, signal) };
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

/// A drive bus cycled on the 4 ms grid as the RT thread would, with the waits the bus suites
/// share (serial link and CANopen master).
pub struct Cycler<B: hal::DriveBus> {
    pub bus: B,
    pub cmd: hal::CycleCommand,
    pub fb: hal::CycleFeedback,
    pub ticker: Ticker,
    /// Cycles run so far.
    pub cycles: u64,
    /// How long enabling may take before the test fails.
    enable_within: Duration,
}

impl<B: hal::DriveBus> Cycler<B> {
    pub fn new(bus: B, enable_within: Duration) -> Self {
        Cycler {
            bus,
            cmd: hal::CycleCommand::default(),
            fb: hal::CycleFeedback::default(),
            ticker: Ticker::default(),
            cycles: 0,
            enable_within,
        }
    }

    pub fn tick(&mut self) -> Result<(), hal::BusFault> {
        self.ticker.wait();
        self.cycles += 1;
        self.bus.cycle(&self.cmd, &mut self.fb)
    }

    pub fn until_operational(&mut self) {
        let t0 = Instant::now();
        while t0.elapsed() < self.enable_within {
            self.tick().expect("no fault while enabling");
            let n = self.bus.axes();
            if self.fb.axes[..n]
                .iter()
                .all(|a| a.state == hal::DriveState::Operational)
            {
                return;
            }
        }
        panic!(
            "drives not operational after {:?}: {:?}",
            self.enable_within, self.fb.axes
        );
    }

    /// Waits until the spindle drive is operational.
    pub fn until_spindle_operational(&mut self) {
        let t0 = Instant::now();
        while self.fb.spindle_state != hal::DriveState::Operational {
            assert!(t0.elapsed() < self.enable_within, "spindle: {:?}", self.fb);
            self.tick().expect("no fault while enabling the spindle");
        }
    }

    /// Runs the spindle at `rpm` until its actual speed (feedback) gets there.
    pub fn spindle_to(&mut self, rpm: f64, within: Duration) {
        self.cmd.spindle_rpm = rpm;
        let t0 = Instant::now();
        while (self.fb.spindle_rpm - rpm).abs() > 1e-9 {
            assert!(
                t0.elapsed() < within,
                "spindle at {} rpm, want {rpm}",
                self.fb.spindle_rpm
            );
            self.tick().expect("no fault while the spindle runs up");
        }
    }

    pub fn until_fault(&mut self, within: Duration) -> hal::BusFault {
        let t0 = Instant::now();
        while t0.elapsed() < within {
            if let Err(e) = self.tick() {
                return e;
            }
        }
        panic!("no fault within {within:?}: {:?}", self.fb.axes);
    }

    /// Moves `axis` to `to_mm` at `v_mm_s`, then holds until it settled.
    pub fn move_to(&mut self, axis: usize, to_mm: f64, v_mm_s: f64) {
        let step = v_mm_s * 0.004;
        while (self.cmd.positions_mm[axis] - to_mm).abs() > 1e-9 {
            let d = (to_mm - self.cmd.positions_mm[axis]).clamp(-step, step);
            self.cmd.positions_mm[axis] += d;
            self.tick().expect("no fault while moving");
        }
        let t0 = Instant::now();
        while (self.fb.axes[axis].position_mm - to_mm).abs() > 0.001 {
            assert!(t0.elapsed() < Duration::from_secs(5), "{:?}", self.fb.axes);
            self.tick().expect("no fault while settling");
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

/// A `cncd` process with a configuration written for the test, and `cncctl` calls to it.
pub struct Daemon {
    pub proc: Proc,
    pub addr: String,
    pub dir: PathBuf,
}

/// Runs a command with a time limit; returns (success, stdout + stderr).
pub fn run_with_timeout(cmd: &mut Command, timeout: Duration) -> (bool, String) {
    let out_path = std::env::temp_dir().join(format!(
        "cnc-cmd-{}-{:?}.txt",
        std::process::id(),
        std::thread::current().id()
    ));
    let out = std::fs::File::create(&out_path).unwrap();
    let mut child = cmd
        .stdout(out.try_clone().unwrap())
        .stderr(out)
        .spawn()
        .unwrap();
    let end = Instant::now() + timeout;
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if Instant::now() > end {
            let _ = child.kill();
            let _ = child.wait();
            let text = std::fs::read_to_string(&out_path).unwrap_or_default();
            panic!("{cmd:?} did not end within {timeout:?}: {text}");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let text = std::fs::read_to_string(&out_path).unwrap_or_default();
    let _ = std::fs::remove_file(&out_path);
    (status.success(), text)
}

/// A directory where a Unix socket can be bound. In the VM the test directory is a host
/// folder shared into it (9p), where binding a socket fails with ENXIO: use the first
/// VM-local tmpfs that takes one.
fn socket_dir(test: &str) -> PathBuf {
    let name = format!("cnc-vcan-{}-{test}", std::process::id());
    for base in ["/run", "/dev/shm", "/tmp"] {
        let d = std::path::Path::new(base).join(&name);
        let probe = d.join("probe.sock");
        if std::fs::create_dir_all(&d).is_ok()
            && std::os::unix::net::UnixListener::bind(&probe).is_ok()
        {
            let _ = std::fs::remove_file(&probe);
            return d;
        }
    }
    temp_dir(&format!("{test}-socket"))
}

impl Daemon {
    /// Starts cncd with `bus_section` (TOML of `[bus]`) and axes X Y Z with `node_ids`.
    pub fn start(test: &str, bus_section: &str, node_ids: [u8; 3]) -> Daemon {
        Self::start_with(test, bus_section, node_ids, ["", "", ""])
    }

    /// As [`Daemon::start`], with more TOML keys for each axis.
    pub fn start_with(
        test: &str,
        bus_section: &str,
        node_ids: [u8; 3],
        axis_keys: [&str; 3],
    ) -> Daemon {
        Self::start_with_files(test, bus_section, node_ids, axis_keys, &[])
    }

    /// As [`Daemon::start_with`], with files (name, text) in the storage dir before cncd
    /// starts (a TAB0.REK, a TAB0.KOR).
    pub fn start_with_files(
        test: &str,
        bus_section: &str,
        node_ids: [u8; 3],
        axis_keys: [&str; 3],
        files: &[(&str, &str)],
    ) -> Daemon {
        let d = Self::spawn(test, bus_section, node_ids, axis_keys, files);
        d.wait_state("idle", Duration::from_secs(90));
        d
    }

    /// As [`Daemon::start_with_files`], returning as soon as cncd is started (its API may not
    /// answer yet, its drives may not be enabled).
    pub fn spawn(
        test: &str,
        bus_section: &str,
        node_ids: [u8; 3],
        axis_keys: [&str; 3],
        files: &[(&str, &str)],
    ) -> Daemon {
        let dir = temp_dir(test);
        let data = dir.join("data");
        std::fs::create_dir_all(&data).unwrap();
        for (name, text) in files {
            std::fs::write(data.join(name), text).unwrap();
        }
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        // Control over the Unix socket: tokenless loopback TCP is observer-only.
        let socket = socket_dir(test).join("cncd.sock");
        let mut cfg = String::new();
        for ((name, id), keys) in ['X', 'Y', 'Z'].iter().zip(node_ids).zip(axis_keys) {
            cfg.push_str(&format!(
                "[[axes]]\nname = '{name}'\nnode_id = {id}\nincrements_per_mm = 10000\n{keys}\n\n"
            ));
        }
        cfg.push_str(bus_section);
        cfg.push_str(&format!(
            "\n[api]\nlisten = '127.0.0.1:{port}'\nunix_socket = '{}'\n\n[hmi]\nlisten = '127.0.0.1:0'\n\n[rt]\nlock_memory = false\n\n\
             [storage]\ndir = '{}'\n",
            socket.display(),
            dir.join("data").display()
        ));
        let path = dir.join("cncd.toml");
        std::fs::write(&path, cfg).unwrap();
        let proc = Proc::spawn("cncd", &["--config", path.to_str().unwrap()]);
        Daemon {
            proc,
            addr: format!("unix:{}", socket.display()),
            dir,
        }
    }

    pub fn cncctl(&self, args: &[&str], timeout: Duration) -> (bool, String) {
        run_with_timeout(
            Command::new(bin("cncctl"))
                .arg("--addr")
                .arg(&self.addr)
                .args(args),
            timeout,
        )
    }

    /// One status line (`cncctl status`): state first, then block, positions, alarm.
    pub fn status(&self) -> String {
        let (ok, out) = self.cncctl(&["status"], Duration::from_secs(60));
        if ok {
            out
        } else {
            format!("unreachable: {out}")
        }
    }

    pub fn wait_state(&self, state: &str, timeout: Duration) -> String {
        let end = Instant::now() + timeout;
        loop {
            let s = self.status();
            if s.starts_with(state) {
                return s;
            }
            assert!(Instant::now() < end, "state {state} not reached: {s}");
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// Writes a program file in the test directory.
    pub fn program(&self, name: &str, text: &str) -> String {
        let p = self.dir.join(name);
        std::fs::write(&p, text).unwrap();
        p.to_str().unwrap().to_owned()
    }
}

/// One status snapshot of the daemon at `addr`, over gRPC.
pub fn status_once(addr: &str) -> proto::v1::Status {
    use proto::v1 as pb;
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async {
        let mut c = pb::machine_client::MachineClient::connect(addr.to_owned())
            .await
            .expect("connect to cncd");
        let mut stream = c
            .stream_status(pb::StatusRequest { rate_hz: 25 })
            .await
            .expect("status stream")
            .into_inner();
        stream.message().await.unwrap().expect("one status")
    })
}

/// Actual spindle speed (rpm, from the spindle drive's feedback) the daemon reports.
pub fn actual_spindle_rpm(addr: &str) -> f64 {
    status_once(addr).spindle_rpm
}

/// Polls the daemon until its actual spindle speed is `rpm` (±0.5); fails after `timeout`.
pub fn wait_spindle_rpm(addr: &str, rpm: f64, timeout: Duration) {
    let end = Instant::now() + timeout;
    loop {
        let actual = actual_spindle_rpm(addr);
        if (actual - rpm).abs() <= 0.5 {
            return;
        }
        assert!(Instant::now() < end, "spindle at {actual} rpm, want {rpm}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// Actual positions (mm) the daemon reports for its axes, from one status snapshot over gRPC.
pub fn actual_positions_mm(addr: &str) -> Vec<f64> {
    status_once(addr).axes.iter().map(|a| a.actual_mm).collect()
}

/// Rows of a `cncctl trajectory` CSV (t, the axes, path v, seq, block).
pub fn trajectory_csv_rows(path: &std::path::Path) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(path).unwrap();
    text.lines()
        .skip(1)
        .map(|l| {
            l.split(',')
                .map(|x| x.parse::<f64>().unwrap_or(f64::NAN))
                .collect()
        })
        .collect()
}
