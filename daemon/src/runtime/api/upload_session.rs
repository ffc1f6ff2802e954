//! Unary program upload for clients without client streaming (browsers over grpc-web, issue
//! #30): `Programs.UploadBegin` opens a session around the library's temporary upload file,
//! `UploadPart` appends in order, `UploadFinish` validates and stores through exactly the path
//! of the streaming `Upload` ([`super::programs::finish_upload`]).
//!
//! Sessions live in the API layer, bounded in count ([`MAX_SESSIONS`]) and idle time
//! ([`IDLE`]): an abandoned session is dropped and its temporary file removed, so a browser
//! that closes mid-upload leaves nothing behind. A session belongs to the caller that opened it
//! (its token name): another caller's id is NOT_FOUND, as if it did not exist.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, Weak};
use std::time::{Duration, Instant};

use proto::v1 as pb;
use tonic::Status;

use super::auth::Caller;
use super::programs::{UploadName, check_name, library_status};
use super::receiving::{Receiving, receiving};
use super::{ApiState, blocking};

/// Open sessions at most (a screen uploads one program at a time; a few spare for retries).
pub const MAX_SESSIONS: usize = 8;
/// A session without a call for this long is dropped (the proto's promise).
pub const IDLE: Duration = Duration::from_secs(60);
/// How often abandoned sessions are looked for.
const SWEEP_EVERY: Duration = Duration::from_secs(5);

/// One upload in progress.
struct Session {
    name: String,
    /// The dialect the first message chose (`None`: by the name).
    dialect: Option<kernel::program::Dialect>,
    select: bool,
    /// Token name of the caller that opened it.
    owner: String,
    last_used: Instant,
    /// `None` while a part is being written on a blocking thread.
    up: Option<Receiving>,
}

/// The open sessions by id.
#[derive(Default)]
pub struct UploadSessions {
    open: Mutex<HashMap<String, Session>>,
}

impl UploadSessions {
    /// The sessions, with a task that drops idle ones (needs a tokio runtime; ends with them).
    pub fn start() -> Arc<UploadSessions> {
        let s = Arc::new(UploadSessions::default());
        let weak = Arc::downgrade(&s);
        tokio::spawn(sweep(weak));
        s
    }

    /// Drops the sessions idle for [`IDLE`] or longer (their temporary files go with them).
    pub fn drop_idle(&self, now: Instant) {
        let mut open = self.open.lock().unwrap();
        open.retain(|id, s| {
            let keep = s.up.is_none() || now.duration_since(s.last_used) < IDLE;
            if !keep {
                tracing::info!(session = %id, program = %s.name, "idle upload session dropped");
            }
            keep
        });
    }

    /// Open sessions now.
    pub fn len(&self) -> usize {
        self.open.lock().unwrap().len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    fn insert(&self, s: Session) -> Result<String, Status> {
        let mut open = self.open.lock().unwrap();
        if open.len() >= MAX_SESSIONS {
            return Err(Status::resource_exhausted(format!(
                "{MAX_SESSIONS} upload sessions are open: finish one, or wait {} s until an \
                 abandoned one is dropped",
                IDLE.as_secs()
            )));
        }
        let id = new_id();
        open.insert(id.clone(), s);
        Ok(id)
    }

    /// Takes the upload of session `id` out for writing (or finishing, with `remove`).
    fn take(
        &self,
        id: &str,
        caller: &Caller,
        remove: bool,
    ) -> Result<(Receiving, UploadName, bool), Status> {
        let mut open = self.open.lock().unwrap();
        let s = match open.get_mut(id) {
            Some(s) if s.owner == caller.who => s,
            _ => {
                return Err(Status::not_found(format!(
                    "no upload session {id:?} (finished, dropped after {} s idle, or another \
                     caller's)",
                    IDLE.as_secs()
                )));
            }
        };
        let Some(up) = s.up.take() else {
            return Err(Status::failed_precondition(
                "the previous part of this upload is still being written: send parts one after \
                 another",
            ));
        };
        s.last_used = Instant::now();
        let (name, select) = ((s.name.clone(), s.dialect), s.select);
        if remove {
            open.remove(id);
        }
        Ok((up, name, select))
    }

    /// Puts the upload back after a part was written.
    fn put_back(&self, id: &str, up: Receiving) {
        if let Some(s) = self.open.lock().unwrap().get_mut(id) {
            s.up = Some(up);
            s.last_used = Instant::now();
        }
    }

    /// Ends session `id` after a failed part: the upload is incomplete, its file removed.
    fn abandon(&self, id: &str) {
        self.open.lock().unwrap().remove(id);
    }
}

async fn sweep(weak: Weak<UploadSessions>) {
    let mut every = tokio::time::interval(SWEEP_EVERY);
    loop {
        every.tick().await;
        match weak.upgrade() {
            Some(s) => s.drop_idle(Instant::now()),
            None => return,
        }
    }
}

/// 128 random bits, hex: a session id nobody guesses.
fn new_id() -> String {
    let mut b = [0u8; 16];
    // SAFETY: getrandom writes at most `b.len()` bytes into the buffer.
    let n = unsafe { libc::getrandom(b.as_mut_ptr().cast(), b.len(), 0) };
    if n != b.len() as isize {
        // The kernel's pool cannot fail after boot; a fallback that is still unique.
        static N: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let t = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap_or_default()
            .as_nanos();
        let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        return format!("{t:032x}{n:x}");
    }
    b.iter().map(|x| format!("{x:02x}")).collect()
}

/// `UploadBegin`: opens the library's temporary upload file, writes the first bytes.
pub async fn begin(
    st: &Arc<ApiState>,
    caller: Caller,
    first: pb::ProgramChunk,
) -> Result<pb::UploadSession, Status> {
    check_name(&first.name)?;
    let dialect = super::dialect_field(&first.dialect)?;
    let lib = st.library.clone();
    let name = first.name.clone();
    let data = first.data;
    let up = blocking(move || {
        let mut up = lib.begin_upload(&name)?;
        up.write(&data)?;
        Ok(up)
    })
    .await?
    .map_err(library_status)?;
    // Validated as its parts arrive (`programs::receiving`).
    let up = receiving(st, (first.name.clone(), dialect), up, |_| {})?;
    let id = st.uploads.insert(Session {
        name: first.name,
        dialect,
        select: first.select,
        owner: caller.who,
        last_used: Instant::now(),
        up: Some(up),
    })?;
    Ok(pb::UploadSession { id })
}

/// `UploadPart`: appends `data` at `offset` (the bytes received so far).
pub async fn part(
    st: &Arc<ApiState>,
    caller: &Caller,
    r: pb::UploadPartRequest,
) -> Result<pb::UploadProgress, Status> {
    let (mut up, _, _) = st.uploads.take(&r.id, caller, false)?;
    if r.offset != up.up.written() {
        let have = up.up.written();
        st.uploads.put_back(&r.id, up);
        return Err(Status::failed_precondition(format!(
            "upload part at offset {} but {have} bytes were received: send the part at {have}",
            r.offset
        )));
    }
    let data = r.data;
    let written = blocking(move || up.up.write(&data).map(|()| up)).await?;
    match written {
        Ok(up) => {
            let bytes_stored = up.up.written();
            st.uploads.put_back(&r.id, up);
            Ok(pb::UploadProgress {
                bytes_stored,
                ..Default::default()
            })
        }
        Err(e) => {
            // The library is full (or the disk failed): the upload cannot complete.
            st.uploads.abandon(&r.id);
            Err(library_status(e))
        }
    }
}

/// `UploadFinish`: validates and stores the upload as the streaming `Upload` does.
pub async fn finish(
    st: &Arc<ApiState>,
    caller: &Caller,
    id: &str,
) -> Result<pb::UploadDone, Status> {
    let (up, _, select) = st.uploads.take(id, caller, true)?;
    super::programs::finish_upload(st, up, select, || false).await
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::runtime::library::Library;

    #[test]
    fn an_idle_session_is_dropped_with_its_temporary_file() {
        let dir = std::env::temp_dir().join(format!("cnc-upload-session-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let lib = Library::open(&dir, 1 << 20).unwrap();
        let mut up = lib.begin_upload("p.nc").unwrap();
        up.write(b"N10 G1 X1 F100\n").unwrap();
        let sessions = UploadSessions::default();
        let t0 = Instant::now();
        let session = |up| Session {
            name: "p.nc".into(),
            dialect: None,
            select: false,
            owner: "hmi-op".into(),
            last_used: t0,
            up: Some(up),
        };
        sessions
            .insert(session(Receiving::without_validation(up)))
            .unwrap();
        let temporary = || {
            std::fs::read_dir(&dir)
                .unwrap()
                .filter(|e| {
                    e.as_ref()
                        .unwrap()
                        .file_name()
                        .to_string_lossy()
                        .contains("upload")
                })
                .count()
        };
        assert_eq!(temporary(), 1);
        sessions.drop_idle(t0 + IDLE / 2);
        assert_eq!(sessions.len(), 1);
        sessions.drop_idle(t0 + IDLE);
        assert!(sessions.is_empty());
        assert_eq!(temporary(), 0);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
