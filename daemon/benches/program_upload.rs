//! A CAM-size program through the API (issue #19): `BENCH_BLOCKS` blocks (default 5,000,000,
//! about 100 MB) are uploaded in 1 MiB chunks through `Programs.Upload` with `select`,
//! validated from the stored file through the whole pipeline (interpret, compensate, plan),
//! selected, and started; the bench waits until the axes move, then stops.
//!
//! The daemon is the one `cncd` builds (`Controller::start` on the simulated machine, the API
//! served on its Unix socket, where `cncctl` reaches it), in this process with its client. Prints the upload,
//! validation and start times, throughput in blocks/s, and the process's peak RSS (VmHWM;
//! client and daemon together, so an upper bound for the daemon).
//!
//! Run: `cargo bench -p daemon --bench program_upload`.

mod bench_common;

use std::io::Write;
use std::time::{Duration, Instant};

use daemon::runtime::config::Config;
use daemon::runtime::controller::{ClockKind, Controller};
use proto::v1 as pb;
use proto::v1::machine_client::MachineClient;
use proto::v1::programs_client::ProgramsClient;

fn rss_kib(key: &str) -> u64 {
    let s = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    s.lines()
        .find(|l| l.starts_with(key))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(0)
}

/// A finishing-like program: short moves on a small grid, feed once.
fn write_program(path: &std::path::Path, blocks: u64) -> u64 {
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

fn main() {
    bench_common::run(bench(bench_common::env_number("BENCH_BLOCKS", 5_000_000)));
}

async fn bench(blocks: u64) {
    let dir = std::env::temp_dir().join(format!("cnc-bench-upload-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("cam.nc");
    let bytes = write_program(&file, blocks);
    let mut cfg = Config::default();
    cfg.storage.dir = dir.join("data");
    cfg.rt.lock_memory = false;
    let ctl = Controller::start(cfg, ClockKind::Monotonic).expect("controller");
    // The Unix socket, as `cncctl` reaches cncd by default (loopback TCP is observer-only).
    let addr = bench_common::serve_unix(&ctl).await;
    let rss0 = rss_kib("VmRSS:");
    let mut g = ProgramsClient::connect(addr.clone()).await.unwrap();
    let mut m = MachineClient::connect(addr).await.unwrap();

    let t0 = Instant::now();
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
        if p.blocks_validated > 0 && uploaded_at.is_none() {
            uploaded_at = Some(t0.elapsed());
        }
        if let Some(d) = p.done {
            break d;
        }
    };
    sender.await.unwrap();
    let stored = t0.elapsed();
    let upload = uploaded_at.unwrap_or(stored);
    let prog = done.program.expect("program");
    assert_eq!(u64::from(prog.blocks), blocks, "blocks validated");
    let job = m
        .start(pb::StartRequest::default())
        .await
        .expect("start")
        .into_inner()
        .job;
    while !(ctl.snapshot().progress.job == job && ctl.snapshot().progress.block_seq > 0) {
        tokio::time::sleep(Duration::from_millis(1)).await;
    }
    let moving = t0.elapsed();
    // Let it run a little: the run streams from the file.
    tokio::time::sleep(Duration::from_secs(2)).await;
    let rss_run = rss_kib("VmRSS:");
    m.stop(pb::StopRequest {}).await.unwrap();
    let hwm = rss_kib("VmHWM:");
    let mb = bytes as f64 / 1e6;
    println!("program: {blocks} blocks, {mb:.1} MB");
    println!(
        "upload (to the temporary file):        {:>7.2} s  {:>7.1} MB/s",
        upload.as_secs_f64(),
        mb / upload.as_secs_f64()
    );
    println!(
        "validation (interpret+comp+plan):      {:>7.2} s  {:>7.0} blocks/s",
        (stored - upload).as_secs_f64(),
        blocks as f64 / (stored - upload).as_secs_f64()
    );
    println!(
        "upload + validation + store + select:  {:>7.2} s  {:>7.0} blocks/s end to end",
        stored.as_secs_f64(),
        blocks as f64 / stored.as_secs_f64()
    );
    println!(
        "start → axes moving:                   {:>7.3} s (total {:.2} s)",
        (moving - stored).as_secs_f64(),
        moving.as_secs_f64()
    );
    println!(
        "RSS: {:.1} MB idle, {:.1} MB while running, peak {:.1} MB (client and daemon)",
        rss0 as f64 / 1024.0,
        rss_run as f64 / 1024.0,
        hwm as f64 / 1024.0
    );
    let _ = std::fs::remove_dir_all(&dir);
}
