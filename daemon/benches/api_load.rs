//! Load benchmark of the gRPC API (issue #8) — prints figures, asserts nothing.
//!
//! While a program runs on the simulated machine: 32 status streams at 250 Hz and 200 unary
//! calls per second (a mix of reads and override writes), for `BENCH_SECS` seconds (default
//! 30). At the same time `cyclictest` (rt-tests; 4 ms interval, clock_nanosleep, SCHED_FIFO 80, mlockall, one thread)
//! measures this machine's own timer floor, so the RT thread's tick lateness can be read
//! against it. Prints: tick lateness p50/p99/max and overruns of the RT thread and of
//! cyclictest side by side, the delivery rate of every stream, and the unary call latency.
//!
//! Run: `cargo bench -p daemon --bench api_load` (as root, or with CAP_SYS_NICE, for
//! SCHED_FIFO). Goal: RT p99 within 1.5x of cyclictest's, overruns no more than cyclictest's,
//! every stream at 250 Hz.

mod bench_common;

use bench_common::cyclic::{finish_cyclictest, percentile, spawn_cyclictest};

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use daemon::runtime::config::Config;
use daemon::runtime::controller::{ClockKind, Controller};
use daemon::runtime::rt::MachineState;
use proto::v1 as pb;
use proto::v1::machine_client::MachineClient;

const STREAMS: usize = 32;
const STREAM_HZ: u32 = 250;
const UNARY_PER_S: u32 = 200;

fn main() {
    bench_common::run(bench(bench_common::env_number("BENCH_SECS", 30)));
}

async fn bench(secs: u64) {
    let mut cfg = Config::default();
    cfg.storage.dir = std::env::temp_dir().join(format!("cnc-bench-{}", std::process::id()));
    cfg.api.max_streams = 64;
    let ctl = Controller::start(cfg, ClockKind::Monotonic).expect("controller");
    // The Unix socket, as the shop's HMI reaches cncd (loopback TCP is observer-only).
    let addr = bench_common::serve_unix(&ctl).await;
    let ch = tonic::transport::Endpoint::from_shared(addr)
        .unwrap()
        .connect()
        .await
        .unwrap();

    // A program that keeps the machine moving for the whole run (100 mm strokes at 50 mm/s).
    bench_common::start_strokes(ch.clone(), (secs / 2 + 10) as usize, false).await;
    let before = ctl.snapshot().tick.stats;

    // cyclictest alongside.
    let cyclic = spawn_cyclictest(secs);

    // 32 status streams at 250 Hz.
    let deadline = Instant::now() + Duration::from_secs(secs);
    let mut streams = Vec::new();
    for _ in 0..STREAMS {
        let mut c = MachineClient::new(ch.clone());
        streams.push(tokio::spawn(async move {
            let mut s = c
                .stream_status(pb::StatusRequest { rate_hz: STREAM_HZ })
                .await
                .unwrap()
                .into_inner();
            let start = Instant::now();
            let mut n = 0u64;
            while Instant::now() < deadline {
                match s.message().await {
                    Ok(Some(_)) => n += 1,
                    _ => break,
                }
            }
            n as f64 / start.elapsed().as_secs_f64()
        }));
    }

    // 200 unary calls per second: reads of every service and override writes.
    let calls = Arc::new(AtomicU64::new(0));
    let errors = Arc::new(AtomicU64::new(0));
    let lat: Arc<std::sync::Mutex<Vec<f64>>> = Arc::default();
    let unary = {
        let (calls, errors, lat) = (calls.clone(), errors.clone(), lat.clone());
        let ch = ch.clone();
        tokio::spawn(async move {
            let mut every =
                tokio::time::interval(Duration::from_secs_f64(1.0 / UNARY_PER_S as f64));
            every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Burst);
            let mut i = 0u64;
            while Instant::now() < deadline {
                every.tick().await;
                let (calls, errors, lat) = (calls.clone(), errors.clone(), lat.clone());
                let ch = ch.clone();
                i += 1;
                tokio::spawn(async move {
                    let t = Instant::now();
                    let ok = match i % 4 {
                        k @ 0..=2 => bench_common::unary_read(ch, k).await,
                        _ => MachineClient::new(ch)
                            .set_override(pb::SetOverrideRequest {
                                percent: 100.0 - (i % 3) as f64,
                            })
                            .await
                            .is_ok(),
                    };
                    lat.lock().unwrap().push(t.elapsed().as_secs_f64() * 1e6);
                    calls.fetch_add(1, Ordering::Relaxed);
                    if !ok {
                        errors.fetch_add(1, Ordering::Relaxed);
                    }
                });
            }
        })
    };

    let mut rates = Vec::new();
    for s in streams {
        rates.push(s.await.unwrap());
    }
    unary.await.unwrap();
    tokio::time::sleep(Duration::from_millis(200)).await;
    let snap = ctl.snapshot();
    let after = snap.tick.stats;
    let still_running = matches!(snap.state, MachineState::Running);
    let cyc = finish_cyclictest(cyclic);

    let mut r = rates.clone();
    let rmin = percentile(&mut r, 0.0);
    let rmed = percentile(&mut r, 0.5);
    let rmax = percentile(&mut r, 1.0);
    let mut l = lat.lock().unwrap().clone();
    let n_calls = calls.load(Ordering::Relaxed);

    println!();
    println!(
        "API load: {STREAMS} status streams at {STREAM_HZ} Hz + {UNARY_PER_S} unary calls/s for {secs} s while a program runs (machine still running at the end: {still_running})"
    );
    println!();
    println!(
        "| 4 ms timer            | lateness p50 | p99      | max      | overruns (missed deadlines) | ticks/samples |"
    );
    println!(
        "|-----------------------|--------------|----------|----------|-----------------------------|---------------|"
    );
    println!(
        "| cncd RT thread        | {:>9} us | {:>5} us | {:>5} us | {:>27} | {:>13} |",
        after.lateness_p50_us,
        after.lateness_p99_us,
        after.lateness_max_us,
        after.overruns - before.overruns,
        after.ticks - before.ticks
    );
    match &cyc {
        Some(c) => println!(
            "| cyclictest (FIFO 80)  | {:>9} us | {:>5} us | {:>5} us | {:>27} | {:>13} |",
            c.p50_us, c.p99_us, c.max_us, c.overruns, c.samples
        ),
        None => println!(
            "| cyclictest            | not available (install rt-tests)                         |"
        ),
    }
    println!();
    println!(
        "status streams: {} of {STREAMS} delivered; rate min {rmin:.1} / median {rmed:.1} / max {rmax:.1} Hz (asked {STREAM_HZ} Hz)",
        rates.len()
    );
    println!(
        "unary calls: {n_calls} in {secs} s = {:.1}/s, {} errors; latency p50 {:.0} us, p99 {:.0} us, max {:.0} us",
        n_calls as f64 / secs as f64,
        errors.load(Ordering::Relaxed),
        percentile(&mut l, 0.5),
        percentile(&mut l, 0.99),
        percentile(&mut l, 1.0)
    );
    if let Some(c) = &cyc {
        let ratio = after.lateness_p99_us as f64 / c.p99_us.max(1) as f64;
        println!(
            "goal: RT p99 / cyclictest p99 = {ratio:.2} (goal <= 1.5): {}; RT overruns {} vs cyclictest {}: {}; streams at >= 95% of {STREAM_HZ} Hz: {}",
            if ratio <= 1.5 { "met" } else { "NOT met" },
            after.overruns - before.overruns,
            c.overruns,
            if after.overruns - before.overruns <= c.overruns {
                "met"
            } else {
                "NOT met"
            },
            if rmin >= 0.95 * STREAM_HZ as f64 {
                "met"
            } else {
                "NOT met"
            }
        );
    }
    println!(
        "note: the RT percentiles are cumulative since the daemon started (about 1 s of idle before the load)"
    );
    let c = ctl.clone();
    tokio::task::spawn_blocking(move || c.shutdown()).await.ok();
}
