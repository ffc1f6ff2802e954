//! The flood's client side, in a process of its own (the bench runs itself again with
//! [`ENV`] set) so that the daemon's RSS and file descriptors are the daemon's alone.
//!
//! It opens idle TCP connections that sent half an HTTP request (the request line and one
//! header, never the blank line that ends the head) alternately to the HMI's and the
//! MTConnect agent's port, and gRPC status streams on the API's port whose client never reads
//! them (HTTP/2 flow control: a 64 KiB window that is never given back). It prints one line
//! `ready <idle conns open> <conns failed> <streams open> <streams refused>` once all are
//! open, holds them until a line (or the end) on stdin, then prints
//! `closed <idle conns the server had closed>` and exits, which closes everything.

use std::io::{BufRead, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use proto::v1 as pb;
use proto::v1::machine_client::MachineClient;
use tokio::io::{AsyncReadExt, AsyncWriteExt};

/// The environment variable that makes the bench binary the flood client:
/// `<hmi addr>,<mtconnect addr>,<api addr>,<connections>,<streams>`.
pub const ENV: &str = "CNC_FLOOD_CLIENT";

/// Connections being opened at once (the listeners' backlog is 1024: more would overflow it
/// and wait for SYN retransmits, measuring the kernel instead of the daemon).
const OPENING_AT_ONCE: usize = 64;
/// Status streams per HTTP/2 connection: several stuck streams share a connection window.
const STREAMS_PER_CONN: usize = 10;
/// The HTTP/2 default window, never released: the server may send 64 KiB, then must wait.
const WINDOW_BYTES: u32 = 65_535;
/// The fastest status rate the API gives, so the windows fill within a second.
const STREAM_HZ: u32 = 250;
/// The most this process lives when nobody tells it to end (a bench that died).
const MAX_LIFE: Duration = Duration::from_secs(600);

struct Spec {
    hmi: String,
    mtc: String,
    api: String,
    conns: usize,
    streams: usize,
}

fn parse(spec: &str) -> Spec {
    let f: Vec<&str> = spec.split(',').collect();
    assert_eq!(f.len(), 5, "{ENV}: hmi,mtconnect,api,connections,streams");
    Spec {
        hmi: f[0].into(),
        mtc: f[1].into(),
        api: f[2].into(),
        conns: f[3].parse().expect("connections"),
        streams: f[4].parse().expect("streams"),
    }
}

/// The flood client's `main`.
pub fn main(spec: &str) {
    let spec = parse(spec);
    crate::bench_common::run(async move {
        let closed = Arc::new(AtomicU64::new(0));
        let (open, failed) = idle_connections(&spec, &closed).await;
        let (streams, refused, _held) = stuck_streams(&spec).await;
        println!("ready {open} {failed} {streams} {refused}");
        std::io::stdout().flush().ok();
        // Hold everything until the bench says so (a line or EOF on stdin).
        let wait = tokio::task::spawn_blocking(|| {
            let mut line = String::new();
            let _ = std::io::stdin().lock().read_line(&mut line);
        });
        let _ = tokio::time::timeout(MAX_LIFE, wait).await;
        println!("closed {}", closed.load(Ordering::Relaxed));
        std::io::stdout().flush().ok();
        // Exiting closes every socket at once.
        std::process::exit(0);
    });
}

/// Opens `spec.conns` idle half-request connections; returns (open, failed). Each connection
/// is held by a task that counts it in `closed` if the server ends it.
async fn idle_connections(spec: &Spec, closed: &Arc<AtomicU64>) -> (u64, u64) {
    let gate = Arc::new(tokio::sync::Semaphore::new(OPENING_AT_ONCE));
    let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel();
    for i in 0..spec.conns {
        let addr = if i % 2 == 0 { &spec.hmi } else { &spec.mtc }.clone();
        let (gate, tx, closed) = (gate.clone(), tx.clone(), closed.clone());
        tokio::spawn(async move {
            let permit = gate.acquire_owned().await.expect("gate");
            let sock = half_request(&addr).await;
            drop(permit);
            let _ = tx.send(sock.is_some());
            if let Some(mut s) = sock {
                // Whatever comes back (an error page, EOF, a reset) means the server let go.
                let mut buf = [0u8; 512];
                let _ = s.read(&mut buf).await;
                closed.fetch_add(1, Ordering::Relaxed);
            }
        });
    }
    drop(tx);
    let (mut open, mut failed) = (0, 0);
    // One result per connection (the senders live on in the tasks that hold them).
    for _ in 0..spec.conns {
        let Some(ok) = rx.recv().await else { break };
        if ok {
            open += 1;
        } else {
            failed += 1;
        }
    }
    (open, failed)
}

/// A connection to `addr` that sent the head of a request without its final blank line.
async fn half_request(addr: &str) -> Option<tokio::net::TcpStream> {
    let connect = tokio::net::TcpStream::connect(addr);
    let mut s = tokio::time::timeout(Duration::from_secs(10), connect)
        .await
        .ok()?
        .ok()?;
    s.write_all(b"GET / HTTP/1.1\r\nHost: x\r\n").await.ok()?;
    Some(s)
}

/// Opens `spec.streams` status streams that are never read; returns (open, refused, the
/// streams, which must stay alive: dropping one resets it).
async fn stuck_streams(spec: &Spec) -> (u64, u64, Vec<tonic::codec::Streaming<pb::Status>>) {
    let mut held = Vec::new();
    let mut refused = 0;
    for chunk in 0..spec.streams.div_ceil(STREAMS_PER_CONN) {
        let n = STREAMS_PER_CONN.min(spec.streams - chunk * STREAMS_PER_CONN);
        let ch = tonic::transport::Endpoint::from_shared(format!("http://{}", spec.api))
            .expect("api address")
            .initial_stream_window_size(WINDOW_BYTES)
            .initial_connection_window_size(WINDOW_BYTES)
            .connect_timeout(Duration::from_secs(10))
            .connect()
            .await;
        let Ok(ch) = ch else {
            refused += n as u64;
            continue;
        };
        for _ in 0..n {
            let mut m = MachineClient::new(ch.clone());
            let call = m.stream_status(pb::StatusRequest { rate_hz: STREAM_HZ });
            match tokio::time::timeout(Duration::from_secs(10), call).await {
                Ok(Ok(r)) => held.push(r.into_inner()),
                _ => refused += 1,
            }
        }
    }
    (held.len() as u64, refused, held)
}
