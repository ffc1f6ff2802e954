//! Load benchmark of the MTConnect agent (issue #33) — prints figures, asserts nothing.
//!
//! While a program runs on the simulated machine: 100 dashboard clients poll `/current` at
//! 10 Hz (each on its own keep-alive connection) and 10 clients read `/sample` streams
//! (`interval=100`), for `BENCH_SECS` seconds (default 30). `cyclictest` runs alongside as in
//! the API bench. Prints the RT thread's tick lateness beside cyclictest's, the `/current`
//! latency and rate, and for every stream whether it kept up: its sequences contiguous (every
//! part starts where the last ended) and how far it was behind the agent at the end.
//!
//! Run: `cargo bench -p daemon --bench mtconnect_load` (as root, or with CAP_SYS_NICE, for
//! SCHED_FIFO). Goal: RT p99 within 1.2x of cyclictest's, every stream keeps up.

mod bench_common;

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use bench_common::cyclic::{finish_cyclictest, percentile, spawn_cyclictest};
use bytes::Bytes;
use daemon::runtime::config::Config;
use daemon::runtime::controller::{ClockKind, Controller};
use daemon::runtime::mtconnect::{self, MtconnectConfig};
use daemon::runtime::rt::MachineState;
use http_body_util::{BodyExt, Empty};

const POLLERS: usize = 100;
const POLL_HZ: f64 = 10.0;
const STREAMS: usize = 10;

type Sender = hyper::client::conn::http1::SendRequest<Empty<Bytes>>;

async fn connect(addr: &str) -> Sender {
    let tcp = tokio::net::TcpStream::connect(addr).await.unwrap();
    tcp.set_nodelay(true).unwrap();
    let (s, conn) = hyper::client::conn::http1::handshake(hyper_util::rt::TokioIo::new(tcp))
        .await
        .unwrap();
    tokio::spawn(conn);
    s
}

fn get(addr: &str, path: &str) -> hyper::Request<Empty<Bytes>> {
    hyper::Request::builder()
        .uri(path)
        .header("host", addr)
        .body(Empty::new())
        .unwrap()
}

/// The number after `attr="` in `doc`.
fn attr_u64(doc: &str, attr: &str) -> Option<u64> {
    let k = format!(" {attr}=\"");
    let i = doc.find(&k)? + k.len();
    doc[i..].split('"').next()?.parse().ok()
}

/// One `/current` poller: requests at 10 Hz on one connection; latencies in µs.
async fn poller(
    addr: String,
    deadline: Instant,
    lat: Arc<std::sync::Mutex<Vec<f64>>>,
    errors: Arc<AtomicU64>,
) {
    let mut s = connect(&addr).await;
    let mut every = tokio::time::interval(Duration::from_secs_f64(1.0 / POLL_HZ));
    every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    while Instant::now() < deadline {
        every.tick().await;
        let t = Instant::now();
        let ok = match s.send_request(get(&addr, "/current")).await {
            Ok(r) => r.status() == 200 && r.into_body().collect().await.is_ok(),
            Err(_) => false,
        };
        lat.lock().unwrap().push(t.elapsed().as_secs_f64() * 1e6);
        if !ok {
            errors.fetch_add(1, Ordering::Relaxed);
            s = connect(&addr).await;
        }
    }
}

/// What one `/sample` stream saw.
struct StreamResult {
    parts: u64,
    observations: u64,
    /// Every part's observations were exactly the sequences from the previous part's
    /// `nextSequence` on.
    contiguous: bool,
    /// The stream's `nextSequence` when the load ended.
    next: u64,
    error: Option<String>,
}

/// Reads a `/sample` stream from `from` until `deadline`, checking contiguity per part.
async fn stream(addr: String, from: u64, deadline: Instant) -> StreamResult {
    let mut s = connect(&addr).await;
    let path = format!("/sample?from={from}&interval=100&count=10000");
    let mut body = s.send_request(get(&addr, &path)).await.unwrap().into_body();
    let mut r = StreamResult {
        parts: 0,
        observations: 0,
        contiguous: true,
        next: from,
        error: None,
    };
    let mut buf: Vec<u8> = Vec::new();
    while Instant::now() < deadline {
        let frame = tokio::time::timeout(
            deadline.saturating_duration_since(Instant::now()),
            body.frame(),
        )
        .await;
        let Ok(Some(Ok(f))) = frame else { break };
        let Ok(d) = f.into_data() else { continue };
        buf.extend_from_slice(&d);
        // Parts end with the root's closing tag (then CRLF).
        while let Some(end) =
            find(&buf, b"</MTConnectStreams>").or_else(|| find(&buf, b"</MTConnectError>"))
        {
            let close = if buf[end..].starts_with(b"</MTConnectError>") {
                17
            } else {
                19
            };
            let part = String::from_utf8_lossy(&buf[..end + close]).into_owned();
            buf.drain(..end + close);
            if part.contains("<MTConnectError") {
                r.error = Some(
                    part.lines()
                        .find(|l| l.contains("errorCode"))
                        .unwrap_or("")
                        .trim()
                        .to_string(),
                );
                return r;
            }
            let n = part.matches(" sequence=\"").count() as u64;
            let next = attr_u64(&part, "nextSequence").unwrap_or(r.next);
            if next - r.next != n {
                r.contiguous = false;
            }
            r.parts += 1;
            r.observations += n;
            r.next = next;
        }
    }
    r
}

fn find(h: &[u8], n: &[u8]) -> Option<usize> {
    h.windows(n.len()).position(|w| w == n)
}

fn main() {
    bench_common::run(bench(bench_common::env_number("BENCH_SECS", 30)));
}

async fn bench(secs: u64) {
    let mut cfg = Config::default();
    cfg.storage.dir = std::env::temp_dir().join(format!("cnc-bench-mtc-{}", std::process::id()));
    let ctl = Controller::start(cfg, ClockKind::Monotonic).expect("controller");
    let ch = tonic::transport::Endpoint::from_shared(bench_common::serve_unix(&ctl).await)
        .unwrap()
        .connect()
        .await
        .unwrap();
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap().to_string();
    tokio::spawn(mtconnect::serve(
        ctl.clone(),
        MtconnectConfig::default(),
        listener,
        None,
        std::future::pending(),
    ));

    // A program that keeps the machine moving for the whole run (100 mm strokes at 50 mm/s).
    bench_common::start_strokes(ch, (secs / 2 + 10) as usize, true).await;
    let before = ctl.snapshot().tick.stats;
    let cyclic = spawn_cyclictest(secs);

    let mut s = connect(&addr).await;
    let cur = s
        .send_request(get(&addr, "/current"))
        .await
        .unwrap()
        .into_body()
        .collect()
        .await
        .unwrap()
        .to_bytes();
    let from = attr_u64(&String::from_utf8_lossy(&cur), "nextSequence").unwrap();
    let started = Instant::now();
    let deadline = started + Duration::from_secs(secs);
    let lat: Arc<std::sync::Mutex<Vec<f64>>> = Arc::default();
    let errors = Arc::new(AtomicU64::new(0));
    let mut tasks = Vec::new();
    for _ in 0..POLLERS {
        tasks.push(tokio::spawn(poller(
            addr.clone(),
            deadline,
            lat.clone(),
            errors.clone(),
        )));
    }
    let streams: Vec<_> = (0..STREAMS)
        .map(|_| {
            tokio::spawn(stream(
                addr.clone(),
                from,
                deadline + Duration::from_millis(300),
            ))
        })
        .collect();
    for t in tasks {
        t.await.unwrap();
    }
    let mut results = Vec::new();
    for t in streams {
        results.push(t.await.unwrap());
    }
    let end = s
        .send_request(get(&addr, "/current"))
        .await
        .unwrap()
        .into_body()
        .collect()
        .await
        .unwrap()
        .to_bytes();
    let agent_next = attr_u64(&String::from_utf8_lossy(&end), "nextSequence").unwrap();
    let snap = ctl.snapshot();
    let after = snap.tick.stats;
    let cyc = finish_cyclictest(cyclic);
    report(
        secs, &snap, before, after, cyc, &lat, &errors, &results, from, agent_next,
    );
    let c = ctl.clone();
    tokio::task::spawn_blocking(move || c.shutdown()).await.ok();
}

#[allow(clippy::too_many_arguments)] // one table from every measurement
fn report(
    secs: u64,
    snap: &daemon::runtime::rt::Snapshot,
    before: daemon::runtime::stats::TickSummary,
    after: daemon::runtime::stats::TickSummary,
    cyc: Option<bench_common::cyclic::Cyclic>,
    lat: &std::sync::Mutex<Vec<f64>>,
    errors: &AtomicU64,
    results: &[StreamResult],
    from: u64,
    agent_next: u64,
) {
    let running = matches!(snap.state, MachineState::Running);
    let mut l = lat.lock().unwrap().clone();
    println!();
    println!(
        "MTConnect load: {POLLERS} clients polling /current at {POLL_HZ} Hz + {STREAMS} /sample streams for {secs} s while a program runs (machine still running at the end: {running})"
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
    let n = l.len();
    println!(
        "/current: {n} requests = {:.0}/s (asked {:.0}/s), {} errors; latency p50 {:.0} us, p99 {:.0} us, max {:.0} us",
        n as f64 / secs as f64,
        POLLERS as f64 * POLL_HZ,
        errors.load(Ordering::Relaxed),
        percentile(&mut l, 0.5),
        percentile(&mut l, 0.99),
        percentile(&mut l, 1.0)
    );
    println!(
        "agent: {} observations in the run ({:.0}/s)",
        agent_next - from,
        (agent_next - from) as f64 / secs as f64
    );
    let mut kept_up = 0;
    for (i, r) in results.iter().enumerate() {
        let behind = agent_next.saturating_sub(r.next);
        let ok = r.contiguous && r.error.is_none() && behind < 2_000;
        kept_up += usize::from(ok);
        println!(
            "stream {i}: {} parts, {} observations, contiguous {}, {} observations behind the agent at the end{}",
            r.parts,
            r.observations,
            r.contiguous,
            behind,
            r.error
                .as_deref()
                .map(|e| format!(", ended by {e}"))
                .unwrap_or_default()
        );
    }
    if let Some(c) = &cyc {
        let ratio = after.lateness_p99_us as f64 / c.p99_us.max(1) as f64;
        println!(
            "goal: RT p99 / cyclictest p99 = {ratio:.2} (goal <= 1.2): {}; streams keeping up: {kept_up} of {STREAMS}",
            if ratio <= 1.2 { "met" } else { "NOT met" }
        );
    }
    println!(
        "note: the RT percentiles are cumulative since the daemon started (about 1 s of idle before the load)"
    );
}
