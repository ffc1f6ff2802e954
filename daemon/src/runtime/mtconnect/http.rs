//! The agent's HTTP side (hyper, HTTP/1.1): GET requests answered with the documents of the
//! pure agent; `interval=` requests stream `multipart/x-mixed-replace` parts with a heartbeat.

use std::convert::Infallible;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;

use bytes::Bytes;
use http_body_util::combinators::UnsyncBoxBody;
use http_body_util::{BodyExt, Full, StreamBody};
use hyper::body::{Frame, Incoming};
use hyper::{Method, Request as HttpRequest, Response, StatusCode};
use tokio::sync::mpsc;
use tokio_stream::StreamExt;
use tokio_stream::wrappers::ReceiverStream;

use crate::mtconnect::error::{ErrorCode, RequestError};
use crate::mtconnect::request::{self, Request};

use super::feed::{Shared, now_ns};

pub type Body = UnsyncBoxBody<Bytes, Infallible>;

/// The boundary of multipart streams.
const BOUNDARY: &str = "cncd-mtconnect-7c1f3a";
/// Parts a stream may have queued for a slow reader before the stream waits for it.
const STREAM_QUEUE: usize = 4;

fn xml(status: StatusCode, body: Vec<u8>) -> Response<Body> {
    let mut r = Response::new(Full::new(Bytes::from(body)).boxed_unsync());
    *r.status_mut() = status;
    r.headers_mut().insert(
        hyper::header::CONTENT_TYPE,
        hyper::header::HeaderValue::from_static("application/xml"),
    );
    r
}

fn error(shared: &Shared, e: &RequestError) -> Response<Body> {
    let doc = shared.agent().error(e, now_ns());
    let status = StatusCode::from_u16(e.code.http_status()).unwrap_or(StatusCode::BAD_REQUEST);
    xml(status, doc)
}

/// Answers one request.
pub async fn handle(
    shared: Arc<Shared>,
    req: HttpRequest<Incoming>,
) -> Result<Response<Body>, Infallible> {
    if req.method() != Method::GET {
        let e = RequestError::new(
            ErrorCode::Unsupported,
            format!(
                "{} is not served: the agent is read-only (GET)",
                req.method()
            ),
        );
        return Ok(error(&shared, &e));
    }
    let (device, size) = {
        let a = shared.agent();
        (a.model().name.clone(), a.buffer_size())
    };
    let parsed = request::parse(
        req.uri().path(),
        req.uri().query().unwrap_or(""),
        &device,
        size,
    );
    let r = match parsed {
        Ok(r) => r,
        Err(e) => return Ok(error(&shared, &e)),
    };
    Ok(match answer(&shared, &r) {
        Err(e) => error(&shared, &e),
        Ok(doc) => match r.interval_ms() {
            None => xml(StatusCode::OK, doc),
            Some(interval) => stream(shared, r, interval, doc),
        },
    })
}

/// The document of `r` now (for a stream: its first part).
fn answer(shared: &Shared, r: &Request) -> Result<Vec<u8>, RequestError> {
    let a = shared.agent();
    let now = now_ns();
    match r {
        Request::Probe => Ok(a.probe(now)),
        Request::Current { at, path, .. } => {
            let f = a.filter(path.as_deref())?;
            a.current(*at, f.as_deref(), now)
        }
        Request::Sample {
            from, count, path, ..
        } => {
            let f = a.filter(path.as_deref())?;
            a.sample(*from, *count, f.as_deref(), now).map(|s| s.xml)
        }
        Request::Assets { ids } => a.assets(ids.as_deref(), now),
    }
}

fn part(doc: &[u8]) -> Bytes {
    let mut b = format!(
        "--{BOUNDARY}\r\nContent-type: text/xml\r\nContent-length: {}\r\n\r\n",
        doc.len()
    )
    .into_bytes();
    b.extend_from_slice(doc);
    b.extend_from_slice(b"\r\n");
    Bytes::from(b)
}

/// Decrements the open stream count when the stream ends.
struct StreamSlot(Arc<Shared>);

impl Drop for StreamSlot {
    fn drop(&mut self) {
        self.0.streams.fetch_sub(1, Ordering::AcqRel);
    }
}

fn stream(shared: Arc<Shared>, r: Request, interval_ms: u64, first: Vec<u8>) -> Response<Body> {
    if shared.streams.fetch_add(1, Ordering::AcqRel) >= shared.max_streams {
        shared.streams.fetch_sub(1, Ordering::AcqRel);
        let e = RequestError::new(
            ErrorCode::TooMany,
            format!(
                "{} streams are open, the limit (mtconnect.max_streams)",
                shared.max_streams
            ),
        );
        return error(&shared, &e);
    }
    let slot = StreamSlot(shared.clone());
    let (tx, rx) = mpsc::channel::<Bytes>(STREAM_QUEUE);
    tokio::spawn(async move {
        let _slot = slot;
        let interval = Duration::from_millis(interval_ms);
        let _ = match r {
            Request::Sample {
                from,
                count,
                path,
                heartbeat_ms,
                ..
            } => sample_stream(&shared, &tx, from, count, path, interval, heartbeat_ms).await,
            _ => current_stream(&shared, &tx, &r, interval, first).await,
        };
    });
    let body =
        StreamBody::new(ReceiverStream::new(rx).map(|b| Ok::<_, Infallible>(Frame::data(b))));
    let mut resp = Response::new(body.boxed_unsync());
    resp.headers_mut().insert(
        hyper::header::CONTENT_TYPE,
        hyper::header::HeaderValue::from_str(&format!(
            "multipart/x-mixed-replace;boundary={BOUNDARY}"
        ))
        .unwrap_or(hyper::header::HeaderValue::from_static(
            "multipart/x-mixed-replace",
        )),
    );
    resp
}

/// Why a stream ended (the client left, or the agent closes).
struct Ended;

async fn send(tx: &mpsc::Sender<Bytes>, shared: &Shared, doc: &[u8]) -> Result<(), Ended> {
    let mut closing = shared.closing.subscribe();
    tokio::select! {
        r = tx.send(part(doc)) => r.map_err(|_| Ended),
        _ = closing.wait_for(|c| *c) => Err(Ended),
    }
}

/// `/current?interval=`: a current document every interval.
async fn current_stream(
    shared: &Shared,
    tx: &mpsc::Sender<Bytes>,
    r: &Request,
    interval: Duration,
    first: Vec<u8>,
) -> Result<(), Ended> {
    send(tx, shared, &first).await?;
    loop {
        tokio::time::sleep(interval.max(Duration::from_millis(1))).await;
        let doc = answer(shared, r).unwrap_or_else(|e| shared.agent().error(&e, now_ns()));
        send(tx, shared, &doc).await?;
    }
}

/// `/sample?interval=`: every observation from `from` on, in parts of at most `count`, a part
/// at most every interval while observations come, an empty part after `heartbeat_ms` without
/// any. A reader so slow that the buffer overtakes it gets an OUT_OF_RANGE error part.
async fn sample_stream(
    shared: &Shared,
    tx: &mpsc::Sender<Bytes>,
    from: Option<u64>,
    count: u64,
    path: Option<String>,
    interval: Duration,
    heartbeat_ms: u64,
) -> Result<(), Ended> {
    let filter = shared.agent().filter(path.as_deref()).ok().flatten();
    let mut next = from.unwrap_or_else(|| shared.agent().first_sequence());
    let mut seq_rx = shared.next_seq.subscribe();
    let heartbeat = Duration::from_millis(heartbeat_ms);
    let mut last_sent = tokio::time::Instant::now() - heartbeat;
    loop {
        let doc = shared
            .agent()
            .sample(Some(next), count, filter.as_deref(), now_ns());
        let doc = match doc {
            Ok(d) => d,
            Err(e) => {
                let err = shared.agent().error(&e, now_ns());
                send(tx, shared, &err).await?;
                return Err(Ended);
            }
        };
        let full = doc.observations as u64 == count;
        if doc.observations > 0 || last_sent.elapsed() >= heartbeat {
            send(tx, shared, &doc.xml).await?;
            last_sent = tokio::time::Instant::now();
        }
        next = doc.next;
        if full {
            continue; // more are waiting: no pause
        }
        tokio::time::sleep(interval).await;
        let wait = heartbeat.saturating_sub(last_sent.elapsed());
        let _ = tokio::time::timeout(wait, seq_rx.wait_for(|s| *s > next)).await;
    }
}
