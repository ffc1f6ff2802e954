//! Fuzzing entry of the HMI port's grpc-web door (`fuzz/`, issue #50): bytes become one HTTP
//! request (content type, method path, headers, body in binary or base64 text framing) sent
//! straight to the service the HMI listener serves (`server::hmi_routes`:
//! tonic-web, the auth interceptor, the message-size refusal, the static files), built once
//! per process on the simulated machine. The requests carry no valid token: the caller is a
//! loopback observer, who may call the read methods only, so the fuzz cannot start motion or
//! write files. Checks: no panic; the answer comes within `CALL_LIMIT`; a gRPC answer carries
//! a `grpc-status` (header, trailers, or grpc-web trailer frame) in well-formed framing; no
//! program is selected, no upload open, the machine not in motion afterwards.

use std::sync::{Arc, OnceLock};
use std::time::Duration;

use axum::body::Body;
use http::{HeaderMap, HeaderValue, Method, Request, Uri, header};
use http_body_util::BodyExt;
use tonic::service::Routes;
use tower::ServiceExt;

use super::Assets;
use crate::runtime::api::ApiState;
use crate::runtime::api::auth::{Auth, Trust};
use crate::runtime::api::fuzz_rig::Rig;

/// Longer is a hang: every method an observer reaches answers within milliseconds.
const CALL_LIMIT: Duration = Duration::from_secs(2);

/// Every method the HMI port serves (a byte of the input picks one).
const METHODS: &[&str] = &[
    "/cnc.v1.Machine/LoadProgram",
    "/cnc.v1.Machine/ValidateProgram",
    "/cnc.v1.Machine/UploadProgram",
    "/cnc.v1.Machine/SelectProgram",
    "/cnc.v1.Machine/ListPrograms",
    "/cnc.v1.Machine/Start",
    "/cnc.v1.Machine/Stop",
    "/cnc.v1.Machine/Hold",
    "/cnc.v1.Machine/Resume",
    "/cnc.v1.Machine/SetOverride",
    "/cnc.v1.Machine/Reset",
    "/cnc.v1.Machine/SetSingleBlock",
    "/cnc.v1.Machine/Mdi",
    "/cnc.v1.Machine/StreamStatus",
    "/cnc.v1.Machine/StreamAlarms",
    "/cnc.v1.Machine/GetRefinedProgram",
    "/cnc.v1.Machine/SetOptionalStop",
    "/cnc.v1.Machine/SetBlockDelete",
    "/cnc.v1.Machine/Jog",
    "/cnc.v1.Machine/JogStep",
    "/cnc.v1.Machine/Home",
    "/cnc.v1.Machine/SetSpindleOverride",
    "/cnc.v1.Machine/SetRapidOverride",
    "/cnc.v1.Machine/WhoAmI",
    "/cnc.v1.Machine/JogLease",
    "/cnc.v1.Machine/JogStop",
    "/cnc.v1.Machine/ListIo",
    "/cnc.v1.Machine/ForceOutput",
    "/cnc.v1.Machine/SimSetInput",
    "/cnc.v1.Machine/Probe",
    "/cnc.v1.Offsets/GetOffsets",
    "/cnc.v1.Offsets/SetOffset",
    "/cnc.v1.Offsets/GetOffsetsFile",
    "/cnc.v1.Offsets/ReplaceOffsetsFile",
    "/cnc.v1.Offsets/ReloadOffsets",
    "/cnc.v1.Offsets/ListWorkOffsets",
    "/cnc.v1.Offsets/SetWorkOffset",
    "/cnc.v1.Offsets/TouchOff",
    "/cnc.v1.Offsets/ProbeWorkflow",
    "/cnc.v1.Plc/ListCells",
    "/cnc.v1.Plc/ReadCells",
    "/cnc.v1.Plc/WriteCell",
    "/cnc.v1.Constants/GetConstants",
    "/cnc.v1.Constants/SetConstants",
    "/cnc.v1.Preview/GetPreviewData",
    "/cnc.v1.Preview/GetPreview",
    "/cnc.v1.Preview/GetPreviewOutline",
    "/cnc.v1.Trajectory/GetTrajectory",
    "/cnc.v1.Programs/Upload",
    "/cnc.v1.Programs/Download",
    "/cnc.v1.Programs/Validate",
    "/cnc.v1.Programs/List",
    "/cnc.v1.Programs/Delete",
    "/cnc.v1.Programs/Rename",
    "/cnc.v1.Programs/UploadBegin",
    "/cnc.v1.Programs/UploadPart",
    "/cnc.v1.Programs/UploadFinish",
    "/cnc.v1.Programs/Interpret",
    "/grpc.health.v1.Health/Check",
    "/grpc.health.v1.Health/Watch",
    "/grpc.reflection.v1.ServerReflection/ServerReflectionInfo",
    "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo",
];

/// Server-streaming methods that do not end on their own, or only after as long as the
/// program's motion (GetTrajectory: a few bytes of `G0 X74029` are minutes of ticks, up to its
/// 24 h bound; the stream goes at the client's pace): only their headers are checked.
const ENDLESS: &[&str] = &[
    "/cnc.v1.Machine/StreamStatus",
    "/cnc.v1.Machine/StreamAlarms",
    "/grpc.health.v1.Health/Watch",
    "/cnc.v1.Trajectory/GetTrajectory",
];

const CONTENT_TYPES: &[&str] = &[
    "application/grpc-web+proto",
    "application/grpc-web-text",
    "application/grpc-web-text+proto",
    "application/grpc-web",
    "application/grpc",
    "text/plain",
];

/// In the first input byte (the content type's): ask for a base64 text answer (tonic-web
/// answers in the encoding `accept` names).
const ACCEPT_TEXT: u8 = 1 << 7;

// The second input byte: which optional parts the request has.
const X_GRPC_WEB: u8 = 1;
const AUTHORIZATION: u8 = 1 << 1;
/// The body is one message frame (5-byte header) around the rest of the input.
const FRAME: u8 = 1 << 2;
const FUZZED_PATH: u8 = 1 << 3;
const GET: u8 = 1 << 4;
const TIMEOUT: u8 = 1 << 5;
const GZIP: u8 = 1 << 6;
/// A text content type with the body not base64-encoded.
const RAW_TEXT: u8 = 1 << 7;

struct Web {
    rig: Rig,
    app: Routes,
}

fn web() -> &'static Web {
    static WEB: OnceLock<Web> = OnceLock::new();
    WEB.get_or_init(|| {
        let rig = Rig::start("grpc-web");
        let _in_rt = rig.rt.enter();
        let auth = Auth::from_config(&rig.st.ctl.config().api);
        let (_, health) = tonic_health::server::health_reporter();
        let assets = Arc::new(Assets::embedded());
        let app =
            crate::runtime::server::hmi_routes(&rig.st, &auth, Trust::Loopback, &health, assets)
                .expect("fuzz rig: the HMI's routes");
        Web { rig, app }
    })
}

pub fn fuzz_entry(data: &[u8]) {
    let Some((req, endless)) = request(data) else {
        return;
    };
    let w = web();
    w.rig.rt.block_on(check(w.app.clone(), req, endless));
    unchanged(&w.rig.st);
}

/// What an observer must not be able to do: select or upload a program, move the machine.
fn unchanged(st: &ApiState) {
    use crate::runtime::rt::MachineState::{Hold, Homing, Jog, Running, Stopping};
    assert!(st.ctl.program().is_none(), "a program was selected");
    assert!(st.uploads.is_empty(), "an upload session was opened");
    let state = st.ctl.snapshot().state;
    assert!(
        !matches!(state, Running | Hold | Stopping | Jog | Homing),
        "{state:?}"
    );
}

/// Splits `n` bytes (at most `max`, by the first byte) off `data`.
fn take(data: &[u8], max: u8) -> (&[u8], &[u8]) {
    let Some((&n, rest)) = data.split_first() else {
        return (&[], &[]);
    };
    rest.split_at(((n % (max + 1)) as usize).min(rest.len()))
}

/// The request the bytes describe, and whether its method's stream never ends.
fn request(data: &[u8]) -> Option<(Request<Body>, bool)> {
    let (&[ct, flags, pick], mut rest) = data.split_first_chunk::<3>()?;
    let content_type = CONTENT_TYPES[(ct & !ACCEPT_TEXT) as usize % CONTENT_TYPES.len()];
    let uri: Uri = if flags & FUZZED_PATH != 0 {
        let (p, r) = take(rest, 64);
        rest = r;
        Uri::try_from(p).ok()?
    } else {
        Uri::from_static(METHODS[pick as usize % METHODS.len()])
    };
    let endless = ENDLESS.contains(&uri.path());
    let method = if flags & GET != 0 {
        Method::GET
    } else {
        Method::POST
    };
    let mut b = Request::builder().method(method).uri(uri);
    b = b.header(header::CONTENT_TYPE, content_type);
    if ct & ACCEPT_TEXT != 0 {
        b = b.header(header::ACCEPT, "application/grpc-web-text");
    }
    if flags & X_GRPC_WEB != 0 {
        b = b.header("x-grpc-web", "1");
    }
    if flags & GZIP != 0 {
        b = b.header("grpc-encoding", "gzip");
    }
    for (flag, name) in [(AUTHORIZATION, "authorization"), (TIMEOUT, "grpc-timeout")] {
        if flags & flag != 0 {
            let (v, r) = take(rest, 40);
            rest = r;
            if let Ok(v) = HeaderValue::from_bytes(v) {
                b = b.header(name, v);
            }
        }
    }
    let mut body = rest.to_vec();
    if flags & FRAME != 0 {
        body = frame(0, rest);
    }
    if content_type.starts_with("application/grpc-web-text") && flags & RAW_TEXT == 0 {
        body = base64(&body);
    }
    Some((b.body(Body::from(body)).ok()?, endless))
}

/// One grpc-web frame: flags, the length (big-endian), the payload.
fn frame(flags: u8, payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(5 + payload.len());
    out.push(flags);
    out.extend_from_slice(&(payload.len() as u32).to_be_bytes());
    out.extend_from_slice(payload);
    out
}

async fn check(app: Routes, req: Request<Body>, endless: bool) {
    let what = format!("{} {}", req.method(), req.uri());
    let resp = tokio::time::timeout(CALL_LIMIT, app.oneshot(req))
        .await
        .unwrap_or_else(|_| panic!("{what}: no answer within {CALL_LIMIT:?}"))
        .unwrap_or_else(|e| match e {});
    let grpc = content_type(resp.headers()).starts_with(b"application/grpc");
    if !grpc || endless || has_status(resp.headers()) {
        return;
    }
    let text = content_type(resp.headers()).starts_with(b"application/grpc-web-text");
    let body = tokio::time::timeout(CALL_LIMIT, resp.into_body().collect())
        .await
        .unwrap_or_else(|_| panic!("{what}: the answer did not end within {CALL_LIMIT:?}"))
        .unwrap_or_else(|e| panic!("{what}: the answer's body failed: {e}"));
    if body.trailers().is_some_and(has_status) {
        return;
    }
    let bytes = body.to_bytes();
    let framed = if text {
        unbase64(&bytes).unwrap_or_else(|| panic!("{what}: the text answer is not base64"))
    } else {
        bytes.to_vec()
    };
    assert!(
        trailer_has_status(&framed),
        "{what}: no grpc-status in the answer {framed:?}"
    );
}

fn content_type(h: &HeaderMap) -> &[u8] {
    h.get(header::CONTENT_TYPE).map_or(&[], |v| v.as_bytes())
}

fn has_status(h: &HeaderMap) -> bool {
    h.contains_key("grpc-status")
}

/// Whether well-formed grpc-web frames end in a trailer frame naming a `grpc-status`.
fn trailer_has_status(mut framed: &[u8]) -> bool {
    while let Some((&[flags, a, b, c, d], rest)) = framed.split_first_chunk::<5>() {
        let len = u32::from_be_bytes([a, b, c, d]) as usize;
        assert!(len <= rest.len(), "a frame longer than the answer");
        let (payload, after) = rest.split_at(len);
        if flags & 0x80 != 0 {
            assert!(after.is_empty(), "data after the trailer frame");
            return String::from_utf8_lossy(payload)
                .to_ascii_lowercase()
                .contains("grpc-status:");
        }
        framed = after;
    }
    assert!(framed.is_empty(), "a cut frame header at the answer's end");
    false
}

const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

/// Standard base64 with padding (grpc-web-text's request encoding).
fn base64(data: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(data.len().div_ceil(3) * 4);
    for c in data.chunks(3) {
        let at = |i: usize| c.get(i).copied().unwrap_or(0) as u32;
        let n = at(0) << 16 | at(1) << 8 | at(2);
        for i in 0..4 {
            out.push(if i <= c.len() {
                ALPHABET[(n >> (18 - 6 * i) & 63) as usize]
            } else {
                b'='
            });
        }
    }
    out
}

/// Decodes base64 quantum by quantum: tonic-web encodes each chunk of an answer on its own,
/// so padding may stand in the middle of the text.
fn unbase64(text: &[u8]) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(text.len() / 4 * 3);
    for q in text.chunks(4) {
        if q.len() != 4 {
            return None;
        }
        let (mut n, mut pad) = (0u32, 0usize);
        for &c in q {
            let v = match c {
                b'=' => {
                    pad += 1;
                    0
                }
                _ if pad > 0 => return None,
                _ => ALPHABET.iter().position(|&a| a == c)? as u32,
            };
            n = n << 6 | v;
        }
        if pad > 2 {
            return None;
        }
        out.extend_from_slice(&n.to_be_bytes()[1..4 - pad]);
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_round_trips_every_length() {
        let data: Vec<u8> = (0..=255).collect();
        for n in 0..10 {
            assert_eq!(unbase64(&base64(&data[..n])).unwrap(), &data[..n]);
        }
        let two = [base64(b"ab"), base64(b"cde")].concat();
        assert_eq!(unbase64(&two).unwrap(), b"abcde");
    }
}
