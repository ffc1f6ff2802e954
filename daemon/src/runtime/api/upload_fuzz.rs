//! Fuzzing entry of the unary upload sessions (`fuzz/`, issue #50): bytes become a sequence of
//! `UploadBegin`, `UploadPart`, `UploadFinish` and idle sweeps, called through the functions
//! the gRPC handlers call ([`super::upload_session`]) on an API state built once per process
//! (simulated machine, a library in a temporary directory), by two operator callers, with
//! right, wrong, other callers' and unknown session ids. A model of the open sessions follows
//! along. Checks: no panic; a stored program is exactly the bytes sent, in order; a refused
//! begin or part leaves every session as it was; a finish ends its session, stored or not;
//! at most [`MAX_SESSIONS`] are open; every refusal has the status code its cause calls for.

use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

use proto::v1 as pb;
use tonic::Code;

use super::ApiState;
use super::auth::Caller;
use super::fuzz_rig::Rig;
use super::upload_session::{self, IDLE, MAX_SESSIONS};
use crate::runtime::config::Role;

/// Program names a begin picks from: valid ones (two dialects by extension) and refused ones.
const NAMES: &[&str] = &["fuzz-a.nc", "fuzz-b.ngc", "", "bad\nname", "Ü.nc"];
const DIALECTS: &[&str] = &["", "iso", "cnc836", "klingon"];
/// How far ahead an idle sweep looks.
const SWEEP_STEPS_S: &[u64] = &[0, 30, IDLE.as_secs(), 10 * IDLE.as_secs()];

/// One open session as the model sees it.
struct Open {
    id: String,
    owner: usize,
    name: String,
    bytes: Vec<u8>,
}

/// The open sessions, and every id handed out (finished and dropped ones are used again).
#[derive(Default)]
struct Model {
    open: Vec<Open>,
    ids: Vec<String>,
}

/// Reads the operations' parameters off the input.
struct Input<'a>(&'a [u8]);

impl Input<'_> {
    fn byte(&mut self) -> Option<u8> {
        let (&b, rest) = self.0.split_first()?;
        self.0 = rest;
        Some(b)
    }

    /// A chunk: a piece of a valid program (so that finishes store something) or raw bytes.
    fn data(&mut self) -> Vec<u8> {
        let n = self.byte().unwrap_or(0);
        if n & 0x80 != 0 {
            let first = u32::from(self.byte().unwrap_or(0));
            return (first..first + u32::from(n & 7))
                .map(|k| format!("N{} G1 X{} F100\n", k + 1, k % 50))
                .collect::<String>()
                .into_bytes();
        }
        let (d, rest) = self.0.split_at(usize::from(n).min(self.0.len()));
        self.0 = rest;
        d.to_vec()
    }
}

fn rig() -> &'static Rig {
    static RIG: OnceLock<Rig> = OnceLock::new();
    RIG.get_or_init(|| Rig::start("upload"))
}

fn callers() -> [Caller; 2] {
    let c = |who: &str| Caller {
        role: Role::Operator,
        who: who.into(),
        peer: "fuzz".into(),
    };
    [c("fuzz-op-a"), c("fuzz-op-b")]
}

pub fn fuzz_entry(data: &[u8]) {
    let rig = rig();
    super::fuzz_rig::set_inline_blocking(true);
    rig.rt.block_on(run(&rig.st, Input(data)));
}

async fn run(st: &Arc<ApiState>, mut input: Input<'_>) {
    assert!(
        st.uploads.is_empty(),
        "a session left from the input before"
    );
    let mut m = Model::default();
    while let Some(op) = input.byte() {
        let caller = usize::from(op >> 7);
        match op % 4 {
            0 => begin(st, &mut m, caller, &mut input).await,
            1 => part(st, &mut m, caller, &mut input).await,
            2 => finish(st, &mut m, caller, &mut input).await,
            _ => sweep(st, &mut m, input.byte().unwrap_or(0)),
        }
        assert_eq!(st.uploads.len(), m.open.len(), "sessions open");
        assert!(m.open.len() <= MAX_SESSIONS);
    }
    // The next input starts without sessions.
    st.uploads.drop_idle(Instant::now() + IDLE);
    assert!(st.uploads.is_empty());
}

/// The id a byte picks: one handed out before (open or not), or one never handed out.
fn pick_id(m: &Model, b: u8) -> String {
    match m.ids.get(usize::from(b) % (m.ids.len() + 2)) {
        Some(id) => id.clone(),
        None if b & 1 == 0 => "0123456789abcdef0123456789abcdef".into(),
        None => String::new(),
    }
}

/// The open session `id` when `caller` owns it (another caller's is NOT_FOUND for him).
fn owned(m: &Model, id: &str, caller: usize) -> Option<usize> {
    m.open.iter().position(|o| o.id == id && o.owner == caller)
}

async fn begin(st: &Arc<ApiState>, m: &mut Model, caller: usize, input: &mut Input<'_>) {
    let b = input.byte().unwrap_or(0);
    let name = NAMES[usize::from(b) % NAMES.len()];
    let dialect = DIALECTS[usize::from(b >> 4) % DIALECTS.len()];
    let data = input.data();
    let first = pb::ProgramChunk {
        name: name.into(),
        data: data.clone(),
        dialect: dialect.into(),
        ..Default::default()
    };
    let valid_name = !name.is_empty() && !name.chars().any(char::is_control);
    let valid_dialect =
        dialect.is_empty() || kernel::program::Dialect::from_name(dialect).is_some();
    let r = upload_session::begin(st, callers()[caller].clone(), first).await;
    match r {
        Ok(s) => {
            assert!(valid_name && valid_dialect, "begun: {name:?} {dialect:?}");
            assert!(m.open.len() < MAX_SESSIONS, "a session beyond the limit");
            m.ids.push(s.id.clone());
            m.open.push(Open {
                id: s.id,
                owner: caller,
                name: name.into(),
                bytes: data,
            });
        }
        Err(e) => {
            let want = if !valid_name || !valid_dialect {
                Code::InvalidArgument
            } else {
                assert_eq!(m.open.len(), MAX_SESSIONS, "refused: {e:?}");
                Code::ResourceExhausted
            };
            assert_eq!(e.code(), want, "{e:?}");
        }
    }
}

async fn part(st: &Arc<ApiState>, m: &mut Model, caller: usize, input: &mut Input<'_>) {
    let id = pick_id(m, input.byte().unwrap_or(0));
    let shift = input.byte().unwrap_or(0);
    let data = input.data();
    let at = owned(m, &id, caller);
    let have = at.map_or(0, |i| m.open[i].bytes.len() as u64);
    // Mostly the right offset; else one off either way, or far off.
    let offset = match shift % 8 {
        0 => have + 1,
        1 => have.wrapping_sub(1),
        2 => u64::MAX - u64::from(shift),
        _ => have,
    };
    let req = pb::UploadPartRequest {
        id: id.clone(),
        offset,
        data: data.clone(),
    };
    let r = upload_session::part(st, &callers()[caller], req).await;
    match (at, r) {
        (Some(i), Ok(p)) => {
            assert_eq!(offset, have, "a part at the wrong offset was taken");
            m.open[i].bytes.extend_from_slice(&data);
            assert_eq!(p.bytes_stored, m.open[i].bytes.len() as u64);
        }
        (Some(i), Err(e)) if e.code() == Code::ResourceExhausted => {
            // The library is full: the upload cannot complete and ends.
            m.open.remove(i);
        }
        (Some(_), Err(e)) => {
            assert_ne!(offset, have, "a part at the right offset refused: {e:?}");
            assert_eq!(e.code(), Code::FailedPrecondition, "{e:?}");
        }
        (None, r) => assert_eq!(r.map(|_| ()).unwrap_err().code(), Code::NotFound),
    }
}

async fn finish(st: &Arc<ApiState>, m: &mut Model, caller: usize, input: &mut Input<'_>) {
    let id = pick_id(m, input.byte().unwrap_or(0));
    let r = upload_session::finish(st, &callers()[caller], &id).await;
    let Some(i) = owned(m, &id, caller) else {
        assert_eq!(r.map(|_| ()).unwrap_err().code(), Code::NotFound);
        return;
    };
    // Stored or refused, the session is over.
    let o = m.open.remove(i);
    match r {
        Ok(done) => {
            let p = done.program.expect("the stored program");
            assert_eq!(
                (p.name.as_str(), p.size_bytes),
                (&*o.name, o.bytes.len() as u64)
            );
            let (file, _) = st.library.open_program(&o.name).expect("stored");
            let mut stored = Vec::new();
            std::io::Read::read_to_end(&mut &*file, &mut stored).expect("readable");
            assert!(stored == o.bytes, "stored bytes differ from the bytes sent");
        }
        Err(e) => assert!(
            matches!(
                e.code(),
                Code::InvalidArgument | Code::ResourceExhausted | Code::FailedPrecondition
            ),
            "{e:?}"
        ),
    }
}

/// An idle sweep `SWEEP_STEPS_S[b]` seconds from now: from [`IDLE`] on, every session goes.
fn sweep(st: &Arc<ApiState>, m: &mut Model, b: u8) {
    let step_s = SWEEP_STEPS_S[usize::from(b) % SWEEP_STEPS_S.len()];
    st.uploads
        .drop_idle(Instant::now() + Duration::from_secs(step_s));
    if step_s >= IDLE.as_secs() {
        m.open.clear();
    }
}
