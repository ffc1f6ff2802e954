//! Shared harness of the MTConnect tests and benchmark: an in-process daemon on the simulated
//! machine with its gRPC API (Unix socket, local trust) and its MTConnect agent on a loopback
//! port; a plain HTTP/1.1 client (hyper) that reads documents and `multipart/x-mixed-replace`
//! streams; every document it receives is saved for the schema check of
//! `tests/mtconnect/run.sh` (`CNC_MTCONNECT_DOCS`, default `target/mtconnect-docs/`).
#![allow(dead_code)]

use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};

use bytes::{Buf, Bytes, BytesMut};
use daemon::runtime::config::Config;
use daemon::runtime::controller::{ClockKind, Controller};
use daemon::runtime::mtconnect::{self, MtconnectConfig};
use daemon::runtime::rt::MachineState;
use http_body_util::{BodyExt, Empty};
use hyper::body::Incoming;
use quick_xml::events::Event;
use tonic::transport::Channel;

/// An in-process daemon with its agent.
pub struct Daemon {
    pub ctl: Arc<Controller>,
    /// gRPC over the Unix socket (local trust: operator and admin calls work).
    pub grpc: Channel,
    /// The agent's base URL host:port.
    pub agent: String,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    served: Option<tokio::task::JoinHandle<Result<(), mtconnect::MtconnectError>>>,
}

/// Starts the controller on the simulated machine of `cfg`, its gRPC API and the agent.
pub async fn start(cfg: Config, mt: MtconnectConfig) -> Daemon {
    let ctl = Controller::start(cfg, ClockKind::Monotonic).unwrap();
    let socket = tests::serve_unix(&ctl).await;
    let grpc = tonic::transport::Endpoint::from_shared(socket)
        .unwrap()
        .connect()
        .await
        .unwrap();
    tests::wait_state(&ctl, MachineState::Idle).await;
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let agent = listener.local_addr().unwrap().to_string();
    let (tx, rx) = tokio::sync::oneshot::channel();
    let served = tokio::spawn(mtconnect::serve(ctl.clone(), mt, listener, None, async {
        let _ = rx.await;
    }));
    Daemon {
        ctl,
        grpc,
        agent,
        stop: Some(tx),
        served: Some(served),
    }
}

impl Daemon {
    /// Stops the agent and the controller (the drives brake, the RT thread ends).
    pub async fn stop(mut self) {
        if let Some(s) = self.stop.take() {
            let _ = s.send(());
        }
        if let Some(h) = self.served.take() {
            h.await.unwrap().unwrap();
        }
        let c = self.ctl.clone();
        tokio::task::spawn_blocking(move || c.shutdown())
            .await
            .unwrap();
    }

    pub fn client(&self, test: &str) -> Client {
        Client {
            addr: self.agent.clone(),
            test: test.into(),
        }
    }
}

/// Where received documents are saved.
pub fn docs_dir() -> PathBuf {
    std::env::var_os("CNC_MTCONNECT_DOCS")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/mtconnect-docs")
        })
}

fn save(test: &str, doc: &[u8]) {
    static N: AtomicU32 = AtomicU32::new(0);
    let dir = docs_dir().join(test);
    std::fs::create_dir_all(&dir).unwrap();
    let n = N.fetch_add(1, Ordering::Relaxed);
    std::fs::write(dir.join(format!("{n:05}.xml")), doc).unwrap();
}

/// An HTTP/1.1 client of the agent (one connection per request, as simple dashboards do).
#[derive(Clone)]
pub struct Client {
    pub addr: String,
    /// Documents are saved under this name.
    pub test: String,
}

/// A response: status and body.
pub struct Reply {
    pub status: u16,
    pub content_type: String,
    pub body: String,
}

impl Client {
    async fn send(&self, method: &str, path: &str) -> hyper::Response<Incoming> {
        let tcp = tokio::net::TcpStream::connect(&self.addr).await.unwrap();
        let (mut s, conn) =
            hyper::client::conn::http1::handshake(hyper_util::rt::TokioIo::new(tcp))
                .await
                .unwrap();
        tokio::spawn(conn);
        let req = hyper::Request::builder()
            .method(method)
            .uri(path)
            .header("host", &self.addr)
            .body(Empty::<Bytes>::new())
            .unwrap();
        s.send_request(req).await.unwrap()
    }

    /// GET `path` (with its query); the body is saved.
    pub async fn get(&self, path: &str) -> Reply {
        self.request("GET", path).await
    }

    pub async fn request(&self, method: &str, path: &str) -> Reply {
        let r = self.send(method, path).await;
        let status = r.status().as_u16();
        let content_type = header(&r, "content-type");
        let body = r.into_body().collect().await.unwrap().to_bytes();
        save(&self.test, &body);
        Reply {
            status,
            content_type,
            body: String::from_utf8(body.to_vec()).unwrap(),
        }
    }

    /// GET of a streaming request (`interval=`): the parts as they come.
    pub async fn stream(&self, path: &str) -> Parts {
        let r = self.send("GET", path).await;
        assert_eq!(r.status().as_u16(), 200);
        let ct = header(&r, "content-type");
        let boundary = ct
            .split_once("boundary=")
            .map(|(_, b)| b.to_string())
            .unwrap_or_else(|| panic!("not a multipart stream: {ct}"));
        Parts {
            body: r.into_body(),
            buf: BytesMut::new(),
            boundary,
            test: self.test.clone(),
        }
    }
}

fn header(r: &hyper::Response<Incoming>, name: &str) -> String {
    r.headers()
        .get(name)
        .and_then(|v| v.to_str().ok())
        .unwrap_or("")
        .to_string()
}

/// The parts of a `multipart/x-mixed-replace` stream.
pub struct Parts {
    body: Incoming,
    buf: BytesMut,
    boundary: String,
    test: String,
}

impl Parts {
    /// The next part's document (saved), or `None` when the stream ended.
    pub async fn next(&mut self) -> Option<String> {
        loop {
            if let Some(doc) = self.take_part() {
                save(&self.test, &doc);
                return Some(String::from_utf8(doc.to_vec()).unwrap());
            }
            match self.body.frame().await {
                Some(Ok(f)) => {
                    if let Ok(d) = f.into_data() {
                        self.buf.extend_from_slice(&d);
                    }
                }
                _ => return None,
            }
        }
    }

    /// Cuts one complete part out of the buffer: `--boundary`, headers with Content-length,
    /// a blank line, the document.
    fn take_part(&mut self) -> Option<Bytes> {
        let start = format!("--{}\r\n", self.boundary);
        let s = find(&self.buf, start.as_bytes())?;
        let head_end = find(&self.buf[s..], b"\r\n\r\n")? + s;
        let head = String::from_utf8_lossy(&self.buf[s + start.len()..head_end]).to_string();
        let len: usize = head
            .lines()
            .find_map(|l| {
                let (k, v) = l.split_once(':')?;
                k.eq_ignore_ascii_case("content-length")
                    .then(|| v.trim().parse().ok())?
            })
            .expect("a part without Content-length");
        let body_start = head_end + 4;
        if self.buf.len() < body_start + len {
            return None;
        }
        self.buf.advance(body_start);
        let doc = self.buf.split_to(len).freeze();
        Some(doc)
    }
}

fn find(h: &[u8], n: &[u8]) -> Option<usize> {
    h.windows(n.len()).position(|w| w == n)
}

/// One observation of a Streams document.
#[derive(Clone, Debug, PartialEq)]
pub struct Obs {
    /// Element name (`Position`, `Execution`, `Fault`, `Normal`...).
    pub element: String,
    pub attrs: HashMap<String, String>,
    pub text: String,
}

impl Obs {
    pub fn id(&self) -> &str {
        &self.attrs["dataItemId"]
    }
    pub fn sequence(&self) -> u64 {
        self.attrs["sequence"].parse().unwrap()
    }
    pub fn number(&self) -> f64 {
        self.text
            .parse()
            .unwrap_or_else(|_| panic!("not a number: {self:?}"))
    }
}

/// A parsed document: the root element, the header's attributes and the observations
/// (elements with a `dataItemId`), in document order.
#[derive(Clone, Debug)]
pub struct Doc {
    pub root: String,
    pub header: HashMap<String, String>,
    pub obs: Vec<Obs>,
    /// `errorCode` of an MTConnectError.
    pub error_code: Option<String>,
    /// Every element name with its attributes (assets, devices).
    pub elements: Vec<(String, HashMap<String, String>, String)>,
}

impl Doc {
    pub fn header_u64(&self, k: &str) -> u64 {
        self.header[k].parse().unwrap()
    }

    /// The observations of data item `id`.
    pub fn of(&self, id: &str) -> Vec<&Obs> {
        self.obs.iter().filter(|o| o.id() == id).collect()
    }

    /// The only observation of `id` (a `/current` of a sample or event).
    pub fn one(&self, id: &str) -> &Obs {
        let v = self.of(id);
        assert_eq!(v.len(), 1, "{id}: {v:?}");
        v[0]
    }
}

/// Parses `xml` (quick-xml reader).
pub fn parse(xml: &str) -> Doc {
    let mut r = quick_xml::Reader::from_str(xml);
    let mut doc = Doc {
        root: String::new(),
        header: HashMap::new(),
        obs: Vec::new(),
        error_code: None,
        elements: Vec::new(),
    };
    let mut open: Vec<(String, HashMap<String, String>, String)> = Vec::new();
    loop {
        match r.read_event().unwrap() {
            Event::Start(e) => open.push(element(&e)),
            Event::Empty(e) => {
                let el = element(&e);
                finish(&mut doc, el);
            }
            Event::Text(t) => {
                if let Some(top) = open.last_mut() {
                    top.2.push_str(&t.xml_content().unwrap());
                }
            }
            Event::GeneralRef(g) => {
                if let Some(top) = open.last_mut() {
                    let name = String::from_utf8_lossy(&g).to_string();
                    top.2.push_str(match name.as_str() {
                        "lt" => "<",
                        "gt" => ">",
                        "amp" => "&",
                        "quot" => "\"",
                        _ => "'",
                    });
                }
            }
            Event::End(_) => {
                let el = open.pop().unwrap();
                finish(&mut doc, el);
            }
            Event::Eof => break,
            _ => {}
        }
    }
    doc
}

fn element(e: &quick_xml::events::BytesStart) -> (String, HashMap<String, String>, String) {
    let name = String::from_utf8_lossy(e.name().as_ref()).to_string();
    let attrs = e
        .attributes()
        .map(|a| {
            let a = a.unwrap();
            (
                String::from_utf8_lossy(a.key.as_ref()).to_string(),
                a.unescape_value().unwrap().to_string(),
            )
        })
        .collect();
    (name, attrs, String::new())
}

fn finish(doc: &mut Doc, (name, attrs, text): (String, HashMap<String, String>, String)) {
    if name.starts_with("MTConnect") {
        doc.root = name.clone();
    }
    if name == "Header" {
        doc.header = attrs.clone();
    }
    if name == "Error" {
        doc.error_code = attrs.get("errorCode").cloned();
    }
    if attrs.contains_key("dataItemId") {
        doc.obs.push(Obs {
            element: name.clone(),
            attrs: attrs.clone(),
            text: text.trim().to_string(),
        });
    }
    doc.elements.push((name, attrs, text));
}

/// Polls `/current` (parsed) until `f` holds; fails after [`tests::PATIENCE`].
pub async fn wait_current(c: &Client, path: &str, what: &str, f: impl Fn(&Doc) -> bool) -> Doc {
    let t0 = std::time::Instant::now();
    loop {
        let r = c.get(path).await;
        assert_eq!(r.status, 200, "{}", r.body);
        let d = parse(&r.body);
        if f(&d) {
            return d;
        }
        assert!(
            t0.elapsed() < tests::PATIENCE,
            "{what}: never seen; last: {}",
            r.body
        );
        tokio::time::sleep(std::time::Duration::from_millis(20)).await;
    }
}
