//! Flood benchmark (issue #50, "floods stay held") — prints figures, asserts nothing.
//!
//! Two phases, 30% and 70% of `BENCH_SECS` (default 50), each on a fresh in-process
//! daemon (so the RT thread's tick statistics, which count from its start, are the phase's
//! own): the simulated machine runs a program, the gRPC API, the HMI (grpc-web and its files)
//! and the MTConnect agent listen on loopback ports. "quiet" measures the baseline; "flood"
//! first opens `FLOOD_CONNS` (default 4000) idle TCP connections that sent half a request,
//! split between the HMI's and the MTConnect agent's ports, and `FLOOD_STREAMS` (default 100)
//! gRPC status streams on the API's port that are never read (HTTP/2 flow control fills),
//! from a client process of its own (`flood_client`), then measures while they are held.
//!
//! Measured in each phase: unary API calls at 50/s on one connection (p50/p99/max), HMI loads
//! (a new connection, `GET /` and the first message of a grpc-web status stream) at 1/s,
//! MTConnect `/current` (a new connection) at 10/s, the RT thread's tick lateness p99 against
//! `cyclictest`'s run over the same seconds (rt-tests, 4 ms, SCHED_FIFO 80), overruns, and
//! this process's RSS (the daemon's: the flood is another process). After the flood is closed
//! the daemon is asked once more over each port. Every request has a 5 s bound.
//!
//! Run: `cargo bench -p daemon --bench flood` (as root, or with CAP_SYS_NICE, for SCHED_FIFO).
//! Goal: the API and the HMI answer through the flood, tick p99 within 1.2x of cyclictest's.

mod bench_common;
mod flood_client;

use std::io::{BufRead, BufReader, Write};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use bench_common::cyclic::{Cyclic, finish_cyclictest, percentile, spawn_cyclictest};
use bytes::Bytes;
use daemon::runtime::config::Config;
use daemon::runtime::controller::{ClockKind, Controller};
use daemon::runtime::hmi::Assets;
use daemon::runtime::mtconnect::{self, MtconnectConfig};
use daemon::runtime::rt::MachineState;
use daemon::runtime::server::{self, HmiListener, Listeners};
use daemon::runtime::stats::TickSummary;
use http_body_util::{BodyExt, Full};
use prost::Message;
use proto::v1 as pb;
use tokio::sync::watch;
use tonic::transport::Channel;

const UNARY_HZ: f64 = 50.0;
const HMI_LOAD_HZ: f64 = 1.0;
const CURRENT_HZ: f64 = 10.0;
/// A request that takes longer counts as an error (the daemon did not answer).
const REQUEST_BOUND: Duration = Duration::from_secs(5);

fn main() {
    raise_nofile();
    if let Ok(spec) = std::env::var(flood_client::ENV) {
        flood_client::main(&spec);
        return;
    }
    // As cncd's main does: with memory locked, glibc's default arenas would keep whatever the
    // flood made them hold resident, and the RSS would not be cncd's.
    daemon::runtime::rt::tune_allocator();
    let secs: u64 = bench_common::env_number("BENCH_SECS", 50);
    let conns: usize = bench_common::env_number("FLOOD_CONNS", 4000);
    let streams: usize = bench_common::env_number("FLOOD_STREAMS", 100);
    // The flood is held longer than the listeners' 30 s header read timeout (by default), so
    // that the daemon closing thousands of connections at once is measured too.
    let quiet_secs = (secs * 3 / 10).max(1);
    let flood_secs = secs.saturating_sub(quiet_secs).max(1);
    bench_common::run(bench(quiet_secs, flood_secs, conns, streams));
}

/// RLIMIT_NOFILE up to its hard limit: thousands of sockets on each side.
fn raise_nofile() {
    let mut r = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit/setrlimit with a valid rlimit struct.
    unsafe {
        if libc::getrlimit(libc::RLIMIT_NOFILE, &mut r) == 0 {
            r.rlim_cur = r.rlim_max;
            libc::setrlimit(libc::RLIMIT_NOFILE, &r);
        }
    }
}

/// `VmRSS:` of this process, KiB.
fn rss_kib() -> u64 {
    let s = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    s.lines()
        .find(|l| l.starts_with("VmRSS:"))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(0)
}

/// An in-process daemon with every listener on a loopback port of its own.
struct Daemon {
    ctl: Arc<Controller>,
    api: String,
    hmi: String,
    mtc: String,
    /// The Unix socket (admin): the bench loads and starts its program there.
    admin: Channel,
    stop: watch::Sender<bool>,
}

fn stopped(rx: watch::Receiver<bool>) -> impl Future<Output = ()> + Send {
    let mut rx = rx;
    async move {
        let _ = rx.wait_for(|v| *v).await;
    }
}

async fn loopback() -> (tokio::net::TcpListener, String) {
    let l = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let a = l.local_addr().unwrap().to_string();
    (l, a)
}

async fn start_daemon(tag: &str) -> Daemon {
    let mut cfg = Config::default();
    cfg.storage.dir =
        std::env::temp_dir().join(format!("cnc-bench-flood-{}-{tag}", std::process::id()));
    // Room for the flood's 100 streams and the HMI's own: what is measured here is flow
    // control, not the stream budget (api.max_streams refuses streams beyond it).
    cfg.api.max_streams = 128;
    let ctl = Controller::start(cfg, ClockKind::Monotonic).expect("controller");
    let sock = ctl.config().storage.dir.join("cncd.sock");
    let (api_l, api) = loopback().await;
    let (hmi_l, hmi) = loopback().await;
    let (mtc_l, mtc) = loopback().await;
    let listeners = Listeners {
        local_tcp: vec![api_l],
        unix: Some(server::bind_unix(&sock, 0o600, None).expect("API socket")),
        ..Listeners::default()
    };
    let hmi_listener = HmiListener {
        listener: hmi_l,
        assets: Arc::new(Assets::embedded()),
        tls: None,
    };
    let (stop, rx) = watch::channel(false);
    tokio::spawn(server::serve_with_hmi(
        ctl.clone(),
        listeners,
        None,
        Some(hmi_listener),
        stopped(rx.clone()),
    ));
    tokio::spawn(mtconnect::serve(
        ctl.clone(),
        MtconnectConfig::default(),
        mtc_l,
        None,
        stopped(rx),
    ));
    let t0 = Instant::now();
    while ctl.snapshot().state != MachineState::Idle {
        assert!(t0.elapsed() < Duration::from_secs(10), "drives not enabled");
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    let admin = tonic::transport::Endpoint::from_shared(format!("unix:{}", sock.display()))
        .unwrap()
        .connect()
        .await
        .unwrap();
    Daemon {
        ctl,
        api,
        hmi,
        mtc,
        admin,
        stop,
    }
}

impl Daemon {
    /// Starts a program that keeps the machine moving for `secs` and a minute more (100 mm
    /// strokes at 50 mm/s): the RT thread interpolates through the whole phase.
    async fn run_program(&self, secs: u64) {
        bench_common::start_strokes(self.admin.clone(), (secs / 2 + 30) as usize, false).await;
    }

    async fn shutdown(self) {
        let _ = self.stop.send(true);
        let c = self.ctl.clone();
        tokio::task::spawn_blocking(move || c.shutdown()).await.ok();
        let _ = std::fs::remove_dir_all(&self.ctl.config().storage.dir);
    }
}

/// Latencies (ms) of the requests of one kind, and how many failed or passed the bound.
#[derive(Default)]
struct Samples {
    latency_ms: Vec<f64>,
    errors: u64,
}

impl Samples {
    fn pct_ms(&self, p: f64) -> f64 {
        percentile(&mut self.latency_ms.clone(), p)
    }

    /// `p50 / p99 / max` in ms, with the error count when there were errors.
    fn cell(&self) -> String {
        let errs = if self.errors > 0 {
            format!(", {} failed", self.errors)
        } else {
            String::new()
        };
        format!(
            "{:.1} / {:.1} / {:.1}{errs}",
            self.pct_ms(0.5),
            self.pct_ms(0.99),
            self.pct_ms(1.0)
        )
    }
}

/// Runs `call` `hz` times a second until `until`, each on a task of its own (a slow answer
/// does not delay the next request), each bounded by [`REQUEST_BOUND`].
async fn paced<F, Fut>(hz: f64, until: Instant, call: F) -> Samples
where
    F: Fn(u64) -> Fut,
    Fut: Future<Output = bool> + Send + 'static,
{
    let out: Arc<Mutex<Samples>> = Arc::default();
    let mut tasks = tokio::task::JoinSet::new();
    let mut every = tokio::time::interval(Duration::from_secs_f64(1.0 / hz));
    every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut i = 0;
    while Instant::now() < until {
        every.tick().await;
        let (fut, out) = (call(i), out.clone());
        i += 1;
        tasks.spawn(async move {
            let t = Instant::now();
            let ok = matches!(tokio::time::timeout(REQUEST_BOUND, fut).await, Ok(true));
            let mut o = out.lock().unwrap();
            o.latency_ms.push(t.elapsed().as_secs_f64() * 1e3);
            o.errors += u64::from(!ok);
        });
    }
    while tasks.join_next().await.is_some() {}
    std::mem::take(&mut *out.lock().unwrap())
}

/// One unary read of the API (observer calls, as loopback TCP allows), rotating services.
async fn unary(ch: Channel, i: u64) -> bool {
    bench_common::unary_read(ch, i).await
}

type Http1 = hyper::client::conn::http1::SendRequest<Full<Bytes>>;

async fn http1(addr: &str) -> Option<Http1> {
    let tcp = tokio::net::TcpStream::connect(addr).await.ok()?;
    tcp.set_nodelay(true).ok()?;
    let io = hyper_util::rt::TokioIo::new(tcp);
    let (s, conn) = hyper::client::conn::http1::handshake(io).await.ok()?;
    tokio::spawn(conn);
    Some(s)
}

/// `GET path` on a new connection: whether it answered 200 with a whole body.
async fn get_ok(addr: String, path: &'static str) -> bool {
    let Some(mut s) = http1(&addr).await else {
        return false;
    };
    let req = hyper::Request::get(path)
        .header("host", &addr)
        .body(Full::default())
        .unwrap();
    match s.send_request(req).await {
        Ok(r) => r.status() == 200 && r.into_body().collect().await.is_ok(),
        Err(_) => false,
    }
}

/// What a browser does to show the HMI, on one new connection: the page, then the first
/// status over grpc-web.
async fn hmi_load(addr: String) -> bool {
    let Some(mut s) = http1(&addr).await else {
        return false;
    };
    let page = hyper::Request::get("/")
        .header("host", &addr)
        .body(Full::default())
        .unwrap();
    let ok = match s.send_request(page).await {
        Ok(r) => r.status() == 200 && r.into_body().collect().await.is_ok(),
        Err(_) => false,
    };
    ok && first_status(&mut s, &addr).await
}

/// Opens `StreamStatus` over grpc-web on `s` and reads until its first message is whole.
async fn first_status(s: &mut Http1, addr: &str) -> bool {
    let msg = pb::StatusRequest { rate_hz: 10 }.encode_to_vec();
    let mut body = vec![0u8];
    body.extend_from_slice(&(msg.len() as u32).to_be_bytes());
    body.extend_from_slice(&msg);
    let req = hyper::Request::post("/cnc.v1.Machine/StreamStatus")
        .header("host", addr)
        .header("content-type", "application/grpc-web+proto")
        .header("x-grpc-web", "1")
        .body(Full::new(Bytes::from(body)))
        .unwrap();
    if s.ready().await.is_err() {
        return false;
    }
    let Ok(r) = s.send_request(req).await else {
        return false;
    };
    let mut b = r.into_body();
    let mut got: Vec<u8> = Vec::new();
    while let Some(Ok(f)) = b.frame().await {
        if let Ok(d) = f.into_data() {
            got.extend_from_slice(&d);
        }
        // A data frame: flag 0, a 4-byte length, the message.
        if got.len() >= 5 && got[0] == 0 {
            let len = u32::from_be_bytes([got[1], got[2], got[3], got[4]]) as usize;
            if got.len() >= 5 + len {
                return true;
            }
        }
    }
    false
}

/// The flood's client process (this binary again, see `flood_client`).
struct Flood {
    child: Child,
    out: BufReader<std::process::ChildStdout>,
}

impl Flood {
    /// Starts the flood of `spec` (see [`flood_client::ENV`]) and waits until it is all open;
    /// returns its `ready` line's figures.
    fn open(spec: String) -> (Flood, String) {
        let mut child = Command::new(std::env::current_exe().expect("bench binary"))
            .env(flood_client::ENV, spec)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .expect("flood client");
        let mut out = BufReader::new(child.stdout.take().expect("stdout"));
        let mut line = String::new();
        out.read_line(&mut line).expect("flood client's ready line");
        let ready = line.trim().strip_prefix("ready ").unwrap_or("").to_string();
        (Flood { child, out }, ready)
    }

    /// Ends the flood (every connection closes); returns how many idle connections the
    /// daemon had closed by then.
    fn close(mut self) -> String {
        if let Some(mut i) = self.child.stdin.take() {
            let _ = i.write_all(b"end\n");
        }
        let mut line = String::new();
        let _ = self.out.read_line(&mut line);
        let _ = self.child.wait();
        line.trim()
            .strip_prefix("closed ")
            .unwrap_or("?")
            .to_string()
    }
}

/// What one phase measured.
#[derive(Default)]
struct Phase {
    unary: Samples,
    hmi: Samples,
    current: Samples,
    tick: TickSummary,
    cyclic: Option<Cyclic>,
    /// Before the flood opens, the peak while it is held, after it closed.
    rss_kib: [u64; 3],
    /// The flood client's `ready` figures: idle connections open, failed, streams open,
    /// refused.
    flood_ready: String,
    /// Idle connections the daemon had closed when the flood ended.
    flood_closed: String,
    /// One request of each kind after the flood closed (unary, HMI load, `/current`).
    after: Option<[Samples; 3]>,
}

/// Measures for `secs`: the three kinds of requests, cyclictest beside, the peak RSS.
async fn measure(d: &Daemon, secs: u64, p: &mut Phase) {
    let cyclic = spawn_cyclictest(secs);
    let until = Instant::now() + Duration::from_secs(secs);
    let ch = tonic::transport::Endpoint::from_shared(format!("http://{}", d.api))
        .unwrap()
        .connect()
        .await
        .expect("API port");
    let rss_peak = async {
        let mut peak = 0;
        while Instant::now() < until {
            peak = peak.max(rss_kib());
            tokio::time::sleep(Duration::from_millis(250)).await;
        }
        peak
    };
    let (hmi, mtc) = (d.hmi.clone(), d.mtc.clone());
    let (unary, hmi, current, peak) = tokio::join!(
        paced(UNARY_HZ, until, |i| unary(ch.clone(), i)),
        paced(HMI_LOAD_HZ, until, |_| hmi_load(hmi.clone())),
        paced(CURRENT_HZ, until, |_| get_ok(mtc.clone(), "/current")),
        rss_peak,
    );
    (p.unary, p.hmi, p.current) = (unary, hmi, current);
    p.rss_kib[1] = peak;
    p.tick = d.ctl.snapshot().tick.stats;
    p.cyclic = tokio::task::spawn_blocking(move || finish_cyclictest(cyclic))
        .await
        .unwrap();
}

/// One bounded request, timed.
async fn once(fut: impl Future<Output = bool>) -> Samples {
    let t = Instant::now();
    let ok = matches!(tokio::time::timeout(REQUEST_BOUND, fut).await, Ok(true));
    Samples {
        latency_ms: vec![t.elapsed().as_secs_f64() * 1e3],
        errors: u64::from(!ok),
    }
}

/// Whether the daemon still answers on every port once the flood is gone.
async fn check_after(d: &Daemon) -> [Samples; 3] {
    let ch = tonic::transport::Endpoint::from_shared(format!("http://{}", d.api))
        .unwrap()
        .connect()
        .await;
    let unary = match ch {
        Ok(ch) => once(unary(ch, 0)).await,
        Err(_) => Samples {
            latency_ms: vec![0.0],
            errors: 1,
        },
    };
    [
        unary,
        once(hmi_load(d.hmi.clone())).await,
        once(get_ok(d.mtc.clone(), "/current")).await,
    ]
}

/// One phase on a fresh daemon: quiet when `flood` is None, else with `(connections,
/// streams)` held open while it measures.
async fn run_phase(secs: u64, flood: Option<(usize, usize)>) -> Phase {
    let tag = if flood.is_some() { "flood" } else { "quiet" };
    eprintln!("{tag}: starting the daemon");
    let d = start_daemon(tag).await;
    d.run_program(secs).await;
    let mut p = Phase::default();
    p.rss_kib[0] = rss_kib();
    let held = match flood {
        Some((conns, streams)) => {
            let spec = format!("{},{},{},{conns},{streams}", d.hmi, d.mtc, d.api);
            eprintln!("{tag}: opening the flood");
            let (f, ready) = tokio::task::spawn_blocking(move || Flood::open(spec))
                .await
                .unwrap();
            p.flood_ready = ready;
            Some(f)
        }
        None => None,
    };
    eprintln!("{tag}: measuring for {secs} s");
    measure(&d, secs, &mut p).await;
    if let Some(f) = held {
        eprintln!("{tag}: closing the flood");
        p.flood_closed = tokio::task::spawn_blocking(move || f.close())
            .await
            .unwrap();
        tokio::time::sleep(Duration::from_secs(1)).await;
        p.after = Some(check_after(&d).await);
    }
    p.rss_kib[2] = rss_kib();
    d.shutdown().await;
    p
}

async fn bench(quiet_secs: u64, flood_secs: u64, conns: usize, streams: usize) {
    let quiet = run_phase(quiet_secs, None).await;
    let flood = run_phase(flood_secs, Some((conns, streams))).await;
    report([quiet_secs, flood_secs], conns, streams, &quiet, &flood);
}

fn mb(kib: u64) -> String {
    format!("{:.1}", kib as f64 / 1024.0)
}

/// The RT thread's tick lateness p99 over cyclictest's, as a table cell.
fn ratio_cell(p: &Phase) -> String {
    match &p.cyclic {
        Some(c) => format!(
            "{:.2}",
            p.tick.lateness_p99_us as f64 / c.p99_us.max(1) as f64
        ),
        None => "no cyclictest".into(),
    }
}

fn cyclic_cell(p: &Phase, f: impl Fn(&Cyclic) -> u64) -> String {
    p.cyclic
        .as_ref()
        .map_or("no cyclictest".into(), |c| f(c).to_string())
}

/// The table: quiet against flood for every figure.
fn report(secs: [u64; 2], conns: usize, streams: usize, quiet: &Phase, flood: &Phase) {
    let rows: Vec<(&str, String, String)> = vec![
        (
            "API unary call p50 / p99 / max, ms",
            quiet.unary.cell(),
            flood.unary.cell(),
        ),
        (
            "HMI load (`GET /` + first grpc-web status) p50 / p99 / max, ms",
            quiet.hmi.cell(),
            flood.hmi.cell(),
        ),
        (
            "MTConnect `/current` p50 / p99 / max, ms",
            quiet.current.cell(),
            flood.current.cell(),
        ),
        (
            "RT tick lateness p50 / p99 / max, µs",
            tick_cell(quiet),
            tick_cell(flood),
        ),
        ("cyclictest p50 / p99 / max, µs", cyc3(quiet), cyc3(flood)),
        (
            "RT p99 / cyclictest p99",
            ratio_cell(quiet),
            ratio_cell(flood),
        ),
        (
            "overruns RT / cyclictest",
            overruns_cell(quiet),
            overruns_cell(flood),
        ),
        (
            "RSS before / peak / after, MB",
            rss_cell(quiet),
            rss_cell(flood),
        ),
    ];
    println!();
    println!(
        "Flood: {} s quiet, then {} s with {conns} idle half-request connections (HMI and \
         MTConnect ports) and {streams} unread gRPC status streams, while a program runs",
        secs[0], secs[1]
    );
    println!();
    println!("| figure | quiet | flood |");
    println!("|---|---|---|");
    for (name, q, f) in rows {
        println!("| {name} | {q} | {f} |");
    }
    println!();
    let r: Vec<&str> = flood.flood_ready.split_whitespace().collect();
    if r.len() == 4 {
        println!(
            "flood held: {} idle connections open ({} failed to open), {} streams open ({} \
             refused); the daemon had closed {} idle connections when the flood ended",
            r[0], r[1], r[2], r[3], flood.flood_closed
        );
    }
    if let Some([u, h, c]) = &flood.after {
        println!(
            "after the flood: API call {}, HMI load {}, /current {} (ms)",
            u.cell(),
            h.cell(),
            c.cell()
        );
    }
}

fn tick_cell(p: &Phase) -> String {
    let t = &p.tick;
    format!(
        "{} / {} / {}",
        t.lateness_p50_us, t.lateness_p99_us, t.lateness_max_us
    )
}

fn cyc3(p: &Phase) -> String {
    let c3 = |c: &Cyclic| format!("{} / {} / {}", c.p50_us, c.p99_us, c.max_us);
    p.cyclic.as_ref().map_or("no cyclictest".into(), c3)
}

fn overruns_cell(p: &Phase) -> String {
    format!("{} / {}", p.tick.overruns, cyclic_cell(p, |c| c.overruns))
}

fn rss_cell(p: &Phase) -> String {
    format!(
        "{} / {} / {}",
        mb(p.rss_kib[0]),
        mb(p.rss_kib[1]),
        mb(p.rss_kib[2])
    )
}
