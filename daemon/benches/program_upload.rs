//! A CAM-size program through the API (issue #19): `BENCH_BLOCKS` blocks (default 5,000,000,
//! about 100 MB) are uploaded in 1 MiB chunks through `Programs.Upload` with `select`,
//! validated as it arrives through the whole pipeline (interpret, compensate, plan),
//! selected, and started; the bench waits until the axes move, then stops.
//!
//! The daemon is the `cncd` binary as it runs on a controller: its default configuration (the
//! simulated machine, the HMI and the MTConnect agent served, memory locked when the process
//! may lock it) and a constants file of defaults (TAB0.REK) in its storage directory, with its
//! listeners on ephemeral ports, in a process of its own; this client
//! reaches it on its Unix socket, as `cncctl` does. So the memory figures are the daemon's
//! alone, read from `/proc/<pid>/status`: RSS idle (drives enabled, before the upload), RSS
//! after the load (the moment the upload is stored and selected), the peak up to then (VmHWM),
//! RSS while the program runs and the peak of the whole bench.
//!
//! Run: `cargo bench -p daemon --bench program_upload` (`BENCH_BLOCKS=1000000` for the
//! figures of docs/api.md; `BENCH_CNCD=path/to/cncd` measures another build of cncd).

mod bench_common;

use std::io::Write;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use proto::v1 as pb;
use proto::v1::machine_client::MachineClient;
use proto::v1::preview_client::PreviewClient;
use proto::v1::programs_client::ProgramsClient;
use tonic::transport::Channel;

/// `VmRSS:`, `VmHWM:` ... of process `pid`, KiB.
fn status_kib(pid: u32, key: &str) -> u64 {
    let s = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
    s.lines()
        .find(|l| l.starts_with(key))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(0)
}

/// CPU time process `pid` has used (user and system, all its threads), s.
fn cpu_s(pid: u32) -> f64 {
    let s = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap_or_default();
    // The fields after the command name (which is in parentheses): utime and stime are the
    // 12th and 13th of them, in clock ticks.
    let rest = s.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<f64> = rest
        .split_whitespace()
        .skip(11)
        .take(2)
        .filter_map(|v| v.parse().ok())
        .collect();
    // SAFETY: sysconf has no preconditions.
    let hz = unsafe { libc::sysconf(libc::_SC_CLK_TCK) } as f64;
    f.iter().sum::<f64>() / hz
}

fn mb(kib: u64) -> f64 {
    kib as f64 / 1024.0
}

/// A finishing-like program: short moves on a small grid, feed once.
fn write_program(path: &Path, blocks: u64) -> u64 {
    let f = std::fs::File::create(path).expect("program file");
    let mut w = std::io::BufWriter::with_capacity(1 << 20, f);
    writeln!(w, "N1 G1 X0 Y0 Z0 F3000").unwrap();
    for i in 1..blocks {
        let x = (i % 2000) as f64 * 0.05;
        let y = ((i / 2000) % 2000) as f64 * 0.05;
        writeln!(w, "G1 X{x:.3} Y{y:.3} Z-{:.3}", (i % 50) as f64 * 0.01).unwrap();
    }
    w.flush().unwrap();
    std::fs::metadata(path).unwrap().len()
}

/// The reference machine's constants file with the defaults (`scripts/planner-reference`).
const MACHINE_REK: &str = include_str!("../../scripts/planner-reference/machine-default.rek");

/// `cncd` in a process of its own; SIGTERM (a clean stop) when the bench ends.
struct Cncd(Child);

impl Cncd {
    /// Starts the binary with the default configuration, its listeners on ephemeral ports and
    /// its data (and the socket it publishes for cncctl) under `dir`.
    fn start(dir: &Path) -> Cncd {
        // The constants file a machine has: the defaults, with the path accelerations
        // (R52 = R236 = R237 = 500 mm/s²) binding (issue #49).
        let data = dir.join("data");
        std::fs::create_dir_all(&data).unwrap();
        std::fs::write(data.join("TAB0.REK"), MACHINE_REK).unwrap();
        let config = dir.join("cncd.toml");
        std::fs::write(
            &config,
            format!(
                "[storage]\ndir = {:?}\n\n[api]\nlisten = \"127.0.0.1:0\"\n\n\
                 [hmi]\nlisten = \"127.0.0.1:0\"\n\n[mtconnect]\nlisten = \"127.0.0.1:0\"\n",
                dir.join("data")
            ),
        )
        .unwrap();
        let log = std::fs::File::create(dir.join("cncd.log")).unwrap();
        // BENCH_CNCD: another build to measure (a commit to compare with).
        let bin = std::env::var_os("BENCH_CNCD").unwrap_or(env!("CARGO_BIN_EXE_cncd").into());
        let child = Command::new(bin)
            .arg("--config")
            .arg(&config)
            .args(["--log", "stderr"])
            .env("CNCD_RUNTIME_DIR", dir)
            .env_remove("NOTIFY_SOCKET")
            .env_remove("WATCHDOG_USEC")
            .current_dir(dir)
            .stdout(Stdio::null())
            .stderr(log)
            .spawn()
            .expect("cncd");
        Cncd(child)
    }

    fn pid(&self) -> u32 {
        self.0.id()
    }
}

impl Drop for Cncd {
    fn drop(&mut self) {
        // SAFETY: kill(2) on the child's own pid.
        unsafe { libc::kill(self.0.id() as i32, libc::SIGTERM) };
        let t0 = Instant::now();
        while t0.elapsed() < Duration::from_secs(20) {
            if let Ok(Some(_)) = self.0.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The channel to cncd's Unix socket once the drives are enabled (a hang bound of 30 s).
async fn connect(cncd: &mut Cncd, sock: &Path) -> Channel {
    let t0 = Instant::now();
    loop {
        if let Ok(Some(status)) = cncd.0.try_wait() {
            panic!("cncd exited with {status} (see its log in the bench's directory)");
        }
        assert!(t0.elapsed() < Duration::from_secs(30), "cncd not ready");
        if sock.exists()
            && let Ok(ch) =
                tonic::transport::Endpoint::from_shared(format!("unix:{}", sock.display()))
                    .unwrap()
                    .connect()
                    .await
        {
            let mut m = MachineClient::new(ch.clone());
            let mut s = m
                .stream_status(pb::StatusRequest { rate_hz: 50 })
                .await
                .unwrap()
                .into_inner();
            while let Some(st) = s.message().await.unwrap() {
                if st.state() == pb::MachineState::Idle {
                    return ch;
                }
            }
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

fn main() {
    bench_common::run(bench(bench_common::env_number("BENCH_BLOCKS", 5_000_000)));
}

async fn bench(blocks: u64) {
    let dir = std::env::temp_dir().join(format!("cnc-bench-upload-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("cam.nc");
    let bytes = write_program(&file, blocks);
    let mut cncd = Cncd::start(&dir);
    let pid = cncd.pid();
    let ch = connect(&mut cncd, &dir.join("data/cncd.sock")).await;
    // Idle: the daemon as it stands after its start, before any program.
    tokio::time::sleep(Duration::from_secs(2)).await;
    let rss_idle = status_kib(pid, "VmRSS:");
    let mut g = ProgramsClient::new(ch.clone());
    let mut preview = PreviewClient::new(ch.clone());
    let mut m = MachineClient::new(ch);

    let (t0, cpu0) = (Instant::now(), cpu_s(pid));
    let (tx, rx) = tokio::sync::mpsc::channel(4);
    let f = file.clone();
    let sender = tokio::task::spawn_blocking(move || {
        use std::io::Read;
        let mut r = std::fs::File::open(f).unwrap();
        let mut first = true;
        loop {
            let mut buf = vec![0u8; 1 << 20];
            let n = r.read(&mut buf).unwrap();
            if n == 0 {
                return;
            }
            buf.truncate(n);
            let msg = pb::ProgramChunk {
                name: if first {
                    "cam.nc".into()
                } else {
                    String::new()
                },
                select: first,
                data: buf,
                total_bytes: 0,
                dialect: String::new(),
            };
            first = false;
            if tx.blocking_send(msg).is_err() {
                return;
            }
        }
    });
    let mut replies = g
        .upload(tokio_stream::wrappers::ReceiverStream::new(rx))
        .await
        .expect("upload")
        .into_inner();
    let mut uploaded_at = None;
    let done = loop {
        let p = replies.message().await.expect("upload").expect("an answer");
        // Validated as it arrives: the upload is over once every byte is stored.
        if p.bytes_stored >= bytes && uploaded_at.is_none() {
            uploaded_at = Some(t0.elapsed());
        }
        if let Some(d) = p.done {
            break d;
        }
    };
    let stored = t0.elapsed();
    let cpu_load = cpu_s(pid) - cpu0;
    let (rss_loaded, hwm_loaded) = (status_kib(pid, "VmRSS:"), status_kib(pid, "VmHWM:"));
    // A screen asks for the selection's outline at once (made beside the load, it answers
    // when its pass has ended), while the operator starts the program.
    let outline = tokio::spawn(async move {
        let r = preview
            .get_preview_outline(pb::PreviewOutlineRequest::default())
            .await
            .expect("outline")
            .into_inner();
        assert_eq!(u64::from(r.blocks), blocks);
        t0.elapsed()
    });
    sender.await.unwrap();
    let upload = uploaded_at.unwrap_or(stored);
    let prog = done.program.expect("program");
    assert_eq!(u64::from(prog.blocks), blocks, "blocks validated");
    let job = m
        .start(pb::StartRequest::default())
        .await
        .expect("start")
        .into_inner()
        .job;
    let mut status = m
        .stream_status(pb::StatusRequest { rate_hz: 250 })
        .await
        .expect("status")
        .into_inner();
    while let Some(s) = status.message().await.expect("status") {
        if s.job == job && s.path_velocity_mm_s > 0.0 {
            break;
        }
    }
    drop(status);
    let moving = t0.elapsed();
    let outline = outline.await.unwrap();
    // Let it run a little: the run streams from the file.
    tokio::time::sleep(Duration::from_secs(2)).await;
    let rss_run = status_kib(pid, "VmRSS:");
    m.stop(pb::StopRequest {}).await.unwrap();
    let hwm = status_kib(pid, "VmHWM:");
    let size = bytes as f64 / 1e6;
    println!("program: {blocks} blocks, {size:.1} MB");
    println!(
        "upload (every byte stored):            {:>7.2} s  {:>7.1} MB/s",
        upload.as_secs_f64(),
        size / upload.as_secs_f64()
    );
    println!(
        "validation's end after the last byte:  {:>7.2} s",
        (stored - upload).as_secs_f64(),
    );
    println!(
        "upload + validation + store + select:  {:>7.2} s  {:>7.0} blocks/s end to end",
        stored.as_secs_f64(),
        blocks as f64 / stored.as_secs_f64()
    );
    println!("cncd's CPU time for it (all threads):  {cpu_load:>7.2} s");
    println!(
        "start → axes moving:                   {:>7.3} s (total {:.2} s)",
        (moving - stored).as_secs_f64(),
        moving.as_secs_f64()
    );
    println!(
        "outline for the screen (asked at the load): {:>5.2} s (total)",
        outline.as_secs_f64()
    );
    println!(
        "cncd RSS: {:.1} MB idle, {:.1} MB after the load (peak {:.1} MB), {:.1} MB while \
         running, peak {:.1} MB",
        mb(rss_idle),
        mb(rss_loaded),
        mb(hwm_loaded),
        mb(rss_run),
        mb(hwm)
    );
    drop(cncd);
    let _ = std::fs::remove_dir_all(&dir);
}
