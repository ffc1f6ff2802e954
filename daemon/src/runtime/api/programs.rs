//! Service `cnc.v1.Programs`: the program library on disk (see `runtime/library.rs`), and the
//! store-validate-select path every program upload takes (also Machine.LoadProgram,
//! UploadProgram and SelectProgram).

use std::fs::File;
use std::pin::Pin;
use std::sync::Arc;

use proto::v1 as pb;
use proto::v1::programs_server::Programs;
use tokio_stream::{Stream, StreamExt};
use tonic::{Request, Response, Status, Streaming};

use kernel::block::Block;
use kernel::machine::MachineSetup;
use kernel::pipeline::{Flow, Observer, Options, Validation};
use kernel::plan::Segment;
use kernel::program::{Dialect, Modal};

use super::auth::require;
use super::machine::Junctions;
use super::preview_outline::SelectionOutline;
use super::receiving::{Receiving, receiving};
use super::upload_session;
use super::{ApiState, PlanInfo, blocking, counts_pb, diagnostic_to_pb, dialect_field, status_of};
use crate::runtime::config::Role;
use crate::runtime::controller::{ControlError, LoadedProgram};
use crate::runtime::library::{Entry, LibraryError, ProgramText, Upload, Verdict};

/// Download chunk size, bytes.
const CHUNK_BYTES: usize = 1 << 20;

/// Upload progress is reported every this many blocks validated.
const PROGRESS_BLOCKS: u32 = 65_536;

#[derive(Clone)]
pub struct ProgramsSvc(pub Arc<ApiState>);

type Stream_<T> = Pin<Box<dyn Stream<Item = Result<T, Status>> + Send>>;

pub fn library_status(e: LibraryError) -> Status {
    match e {
        LibraryError::NotFound(_) => Status::not_found(e.to_string()),
        LibraryError::Exists(_) => Status::already_exists(e.to_string()),
        LibraryError::Full { .. } => Status::resource_exhausted(e.to_string()),
        LibraryError::Io(_) => Status::internal(e.to_string()),
    }
}

/// A stored program for the API; `default`: the machine's dialect (for a program read in the
/// dialect of its name).
pub fn entry_pb(e: &Entry, default: Dialect) -> pb::LibraryProgram {
    let dialect = crate::runtime::dialect::of_program(e.dialect, &e.name, default);
    pb::LibraryProgram {
        dialect: dialect.as_str().into(),
        name: e.name.clone(),
        size_bytes: e.size_bytes,
        blocks: e.blocks,
        modified_unix_ms: e.modified_unix_ms,
        valid: e.verdict.valid,
        errors: e.verdict.errors,
        warnings: e.verdict.warnings,
        first_error: e.verdict.first_error.clone(),
        revision: e.revision.clone(),
    }
}

pub fn check_name(name: &str) -> Result<(), Status> {
    if name.is_empty() || name.len() > 255 || name.chars().any(|c| c.is_control()) {
        return Err(Status::invalid_argument(
            "program name must be 1..255 printable characters",
        ));
    }
    Ok(())
}

fn running(st: &ApiState) -> bool {
    use crate::runtime::rt::MachineState::{Hold, Running, Stopping};
    matches!(st.ctl.snapshot().state, Running | Hold | Stopping)
}

fn selected_name(st: &ApiState) -> Option<String> {
    st.ctl.program().map(|p| p.name.clone())
}

/// The selected program may not be deleted or renamed (a new text under its name may be
/// stored: the selection keeps the version it validated, its open file).
fn refuse_if_selected(st: &ApiState, name: &str, what: &str) -> Result<(), Status> {
    if selected_name(st).as_deref() == Some(name) {
        return Err(Status::failed_precondition(format!(
            "{name:?} is the selected program: {what} it after selecting another one (or \
             load the new text, which selects it)"
        )));
    }
    Ok(())
}

/// What an upload's or a selection's validation pass keeps: the junction classes for status
/// and a progress count of the blocks.
pub(super) struct Pass<F> {
    junctions: Junctions,
    blocks: u32,
    progress: F,
}

impl<F: FnMut(u32)> Observer for Pass<F> {
    fn programmed(&mut self, _b: &Block, _modal: &Modal) {
        self.blocks += 1;
        if self.blocks.is_multiple_of(PROGRESS_BLOCKS) {
            (self.progress)(self.blocks);
        }
    }

    fn segment(&mut self, s: &Segment) -> Flow {
        self.junctions.segment(s)
    }
}

/// Validates `text` in `dialect` through the one pipeline (`Controller::prepare_program`,
/// streaming a file line by line) into a program that may be selected, with its junction
/// classes.
fn prepare(
    st: &ApiState,
    name: &str,
    text: ProgramText,
    dialect: Dialect,
    progress: impl FnMut(u32),
) -> Result<Prepared, ControlError> {
    let read = text.clone();
    prepare_by(st, name, text, dialect, progress, |setup, obs| {
        read.validate_into(setup, Options::default(), obs)
    })
}

/// As [`prepare`], the text read by `pass` (an upload as it arrives).
pub(super) fn prepare_by<F: FnMut(u32)>(
    st: &ApiState,
    name: &str,
    text: ProgramText,
    dialect: Dialect,
    progress: F,
    pass: impl FnOnce(&MachineSetup, &mut LoadObserver<F>) -> Validation,
) -> Result<Prepared, ControlError> {
    let mut obs = (
        Pass {
            junctions: Junctions::default(),
            blocks: 0,
            progress,
        },
        // The same pass records what the previews of the selected program read (instead of
        // making a pass of their own; a large program's stops being recorded at the budget).
        ::preview::pipeline::Recorder::new(super::preview::RECORD_MAX_BYTES),
    );
    let (loaded, setup) = st
        .ctl
        .prepare_program_by(name, text, dialect, |setup| pass(setup, &mut obs))?;
    let (pass, record) = obs;
    let recording = record
        .finish(loaded.block_count, loaded.warnings.clone())
        .map(Arc::new);
    // The outline a screen draws a program of any size from (GetPreviewOutline): the same
    // pass again with the same setup, beside what follows the load.
    let outline = SelectionOutline::start(loaded.text.clone(), setup);
    Ok(Prepared {
        loaded,
        junctions: pass.junctions.classes,
        recording,
        outline,
    })
}

/// What a load's pass feeds: the junction classes and progress, and the previews' recording.
pub(super) type LoadObserver<F> = (Pass<F>, ::preview::pipeline::Recorder);

/// A program validated by one pass, with what that pass left for status and the previews.
pub struct Prepared {
    loaded: Arc<LoadedProgram>,
    junctions: Vec<pb::JunctionClass>,
    recording: Option<Arc<::preview::pipeline::Recording>>,
    outline: Arc<SelectionOutline>,
}

/// An upload validated and not yet stored.
pub struct Validated {
    name: String,
    up: Upload,
    prepared: Prepared,
    /// The dialect the upload chose (`None`: by its name), kept by the library.
    chosen: Option<Dialect>,
}

/// Validates a finished upload from its temporary file through the one pipeline, in the
/// dialect `chosen` (`None`: by its name, else the machine's). Blocking. `progress` sees the
/// blocks validated so far.
pub fn validate_upload(
    st: &ApiState,
    name: &str,
    up: Upload,
    chosen: Option<Dialect>,
    progress: impl FnMut(u32),
) -> Result<Validated, Status> {
    // The temporary file is renamed into place by the commit: this handle stays the program.
    let file = Arc::new(up.reopen().map_err(|e| Status::internal(e.to_string()))?);
    let dialect = st.ctl.dialect_of(name, chosen);
    let prepared =
        prepare(st, name, ProgramText::File(file), dialect, progress).map_err(status_of)?;
    Ok(Validated {
        name: name.to_owned(),
        up,
        prepared,
        chosen,
    })
}

/// Stores a validated upload and selects it when asked. No await point: callers run it after
/// the validation's, so a call cancelled by its deadline while validating stores and selects
/// nothing, and a refusal (RESOURCE_EXHAUSTED, a running program) changes nothing.
pub fn commit_upload(st: &ApiState, v: Validated, select: bool) -> Result<pb::UploadDone, Status> {
    let Validated {
        name,
        up,
        prepared,
        chosen,
    } = v;
    let loaded = prepared.loaded.clone();
    let warnings: Vec<pb::Diagnostic> = loaded.warnings.iter().map(diagnostic_to_pb).collect();
    if select && running(st) {
        return Err(Status::failed_precondition(
            "[program_selected] a program is running: stop it before loading another",
        ));
    }
    // Library = what runs (issue #31): the selected program keeps the text it validated, so a
    // new text under its name without selecting it would list one text and run another.
    if !select && selected_name(st).as_deref() == Some(name.as_str()) {
        return Err(Status::failed_precondition(format!(
            "[program_selected] {name:?} is the selected program: load the new text (upload \
             with select, `cncctl load`), which selects it, or select another program first"
        )));
    }
    let verdict = Verdict::of(&loaded.warnings);
    let (entry, _) = st
        .library
        .commit(&name, up, loaded.block_count, verdict, chosen)
        .map_err(library_status)?;
    if select {
        st.ctl.select(loaded.clone()).map_err(status_of)?;
        after_select(st, prepared);
    }
    Ok(pb::UploadDone {
        program: Some(entry_pb(&entry, st.ctl.default_dialect())),
        diagnostics: warnings,
        totals: Some(counts_pb(&loaded.warnings)),
        selected: select,
    })
}

/// An upload's name and the dialect its first message chose (`None`: by the name).
pub type UploadName = (String, Option<Dialect>);

/// The end of every chunked upload (the streaming `Upload` and `UploadFinish`): every byte
/// has arrived, so its validation reads to the end; then it is stored and selected unless the
/// client went away meanwhile (`cancelled`).
pub async fn finish_upload(
    st: &Arc<ApiState>,
    r: Receiving,
    select: bool,
    cancelled: impl FnOnce() -> bool,
) -> Result<pb::UploadDone, Status> {
    let (up, (name, chosen), prepared) = r.verdict(st).await?;
    let prepared = prepared.map_err(status_of)?;
    // The client left while it validated: nothing is stored or selected.
    if cancelled() {
        return Err(Status::cancelled("the client ended the upload"));
    }
    let v = Validated {
        name,
        up,
        prepared,
        chosen,
    };
    commit_upload(st, v, select)
}

/// Stores `text` (a unary upload: LoadProgram, UploadProgram) in the dialect `chosen`
/// (`None`: by its name) and selects it when asked: written and validated on a blocking
/// thread, stored and selected after that.
pub async fn store_text(
    st: &Arc<ApiState>,
    name: String,
    text: String,
    select: bool,
    chosen: Option<Dialect>,
) -> Result<pb::UploadDone, Status> {
    let s = st.clone();
    let v = blocking(move || {
        let mut up = s.library.begin_upload(&name).map_err(library_status)?;
        up.write(text.as_bytes()).map_err(library_status)?;
        validate_upload(&s, &name, up, chosen, |_| {})
    })
    .await??;
    commit_upload(st, v, select)
}

/// Selects a stored program, validating it again (streaming its file) against the machine
/// as it is now, in the dialect `chosen` (recorded from now on) or the one it was stored
/// with; the verdict is recorded. Blocking.
pub fn select_stored(
    st: &ApiState,
    name: &str,
    chosen: Option<Dialect>,
) -> Result<Arc<LoadedProgram>, Status> {
    let (file, entry) = st.library.open_program(name).map_err(library_status)?;
    if let Some(d) = chosen
        && let Err(e) = st.library.set_dialect(name, d)
    {
        return Err(Status::internal(format!("cannot record the dialect: {e}")));
    }
    let dialect = st.ctl.dialect_of(name, chosen.or(entry.dialect));
    let r = prepare(st, name, ProgramText::File(file), dialect, |_| {});
    let (blocks, verdict) = match &r {
        Ok(p) => (p.loaded.block_count, Verdict::of(&p.loaded.warnings)),
        Err(ControlError::InvalidProgram(d)) => (0, Verdict::of(d)),
        Err(_) => (0, Verdict::default()),
    };
    if matches!(r, Ok(_) | Err(ControlError::InvalidProgram(_)))
        && let Err(e) = st.library.set_verdict(name, blocks, verdict)
    {
        tracing::warn!(program = name, "cannot record the verdict: {e}");
    }
    let prepared = r.map_err(status_of)?;
    let loaded = prepared.loaded.clone();
    st.ctl.select(loaded.clone()).map_err(status_of)?;
    after_select(st, prepared);
    Ok(loaded)
}

/// After a selection: remember it across restarts; junction classes for status and the pass
/// for the previews.
fn after_select(st: &ApiState, p: Prepared) {
    if let Err(e) = st.library.save_selected(&p.loaded.name) {
        tracing::warn!("cannot remember the selected program: {e}");
    }
    *st.job.plan_info.lock().unwrap() = Some(PlanInfo {
        program: Arc::as_ptr(&p.loaded) as *const () as usize,
        junctions: p.junctions,
        pass: p.recording,
        outline: p.outline,
    });
}

/// At start-up: selects the program selected before the restart (not started). A program
/// that no longer validates stays stored, unselected, with its verdict.
pub fn restore_selection(st: &ApiState) {
    let Some(name) = st.library.saved_selected() else {
        return;
    };
    match select_stored(st, &name, None) {
        Ok(p) => tracing::info!(program = %name, blocks = p.block_count, "selected again"),
        Err(e) => tracing::warn!(program = %name, "not selected again: {}", e.message()),
    }
}

/// Receives an upload into its temporary file, validating it as it arrives (progress of both
/// is sent); returns the upload once its last chunk is written.
async fn receive(
    st: &Arc<ApiState>,
    mut input: Streaming<pb::ProgramChunk>,
    first: pb::ProgramChunk,
    name: UploadName,
    tx: &tokio::sync::mpsc::Sender<Result<pb::UploadProgress, Status>>,
) -> Result<Receiving, Status> {
    let lib = st.library.clone();
    let file_name = first.name.clone();
    let up = blocking(move || lib.begin_upload(&file_name))
        .await?
        .map_err(library_status)?;
    let (t, arrival) = (tx.clone(), up.arrival());
    // Progress is news, not a promise: a client that reads slowly misses some rather than
    // holding the validation up.
    let progress = move |n| {
        let _ = t.try_send(Ok(pb::UploadProgress {
            bytes_stored: arrival.bytes(),
            blocks_validated: n,
            done: None,
        }));
    };
    let mut r = receiving(st, name, up, progress)?;
    let mut chunk = first.data;
    let mut last_report = 0u64;
    loop {
        if !chunk.is_empty() {
            let data = std::mem::take(&mut chunk);
            r = blocking(move || r.up.write(&data).map(|()| r))
                .await?
                .map_err(library_status)?;
            let written = r.up.written();
            if written - last_report >= 8 << 20 {
                last_report = written;
                let _ = tx
                    .send(Ok(pb::UploadProgress {
                        bytes_stored: written,
                        ..Default::default()
                    }))
                    .await;
            }
        }
        // A client silent for as long as an idle session is dropped has gone (a stalled
        // stream would hold its upload, and its validation, forever).
        match tokio::time::timeout(upload_session::IDLE, input.next()).await {
            Ok(Some(m)) => chunk = m?.data,
            Ok(None) => return Ok(r),
            Err(_) => {
                return Err(Status::deadline_exceeded(format!(
                    "no chunk of the upload for {} s: abandoned",
                    upload_session::IDLE.as_secs()
                )));
            }
        }
    }
}

#[tonic::async_trait]
impl Programs for ProgramsSvc {
    type UploadStream = Stream_<pb::UploadProgress>;

    async fn upload(
        &self,
        req: Request<Streaming<pb::ProgramChunk>>,
    ) -> Result<Response<Self::UploadStream>, Status> {
        require(&req, Role::Operator, "Upload")?;
        let mut input = req.into_inner();
        let first = input
            .next()
            .await
            .ok_or_else(|| Status::invalid_argument("an upload needs at least one message"))??;
        check_name(&first.name)?;
        let chosen = dialect_field(&first.dialect)?;
        let (tx, rx) = tokio::sync::mpsc::channel(16);
        let st = self.0.clone();
        tokio::spawn(async move {
            let (name, select) = ((first.name.clone(), chosen), first.select);
            let r = match receive(&st, input, first, name, &tx).await {
                Ok(r) => r,
                Err(e) => {
                    let _ = tx.send(Err(e)).await;
                    return;
                }
            };
            let bytes = r.up.written();
            let r = finish_upload(&st, r, select, || tx.is_closed()).await;
            let _ = tx
                .send(r.map(|done| pb::UploadProgress {
                    bytes_stored: bytes,
                    blocks_validated: done.program.as_ref().map_or(0, |p| p.blocks),
                    done: Some(done),
                }))
                .await;
        });
        Ok(Response::new(Box::pin(
            tokio_stream::wrappers::ReceiverStream::new(rx),
        )))
    }

    async fn validate(
        &self,
        req: Request<Streaming<pb::ProgramChunk>>,
    ) -> Result<Response<pb::ValidateProgramReply>, Status> {
        require(&req, Role::Observer, "Validate")?;
        let reply = super::validate_stream::validate_chunks(&self.0, req.into_inner()).await?;
        Ok(Response::new(reply))
    }

    type DownloadStream = Stream_<pb::ProgramChunk>;

    async fn upload_begin(
        &self,
        req: Request<pb::ProgramChunk>,
    ) -> Result<Response<pb::UploadSession>, Status> {
        let caller = require(&req, Role::Operator, "UploadBegin")?;
        let s = upload_session::begin(&self.0, caller, req.into_inner()).await?;
        Ok(Response::new(s))
    }

    async fn upload_part(
        &self,
        req: Request<pb::UploadPartRequest>,
    ) -> Result<Response<pb::UploadProgress>, Status> {
        let caller = require(&req, Role::Operator, "UploadPart")?;
        let p = upload_session::part(&self.0, &caller, req.into_inner()).await?;
        Ok(Response::new(p))
    }

    async fn upload_finish(
        &self,
        req: Request<pb::UploadSession>,
    ) -> Result<Response<pb::UploadDone>, Status> {
        let caller = require(&req, Role::Operator, "UploadFinish")?;
        let id = req.into_inner().id;
        let done = upload_session::finish(&self.0, &caller, &id).await?;
        Ok(Response::new(done))
    }

    type InterpretStream = Stream_<pb::InterpretChunk>;

    async fn interpret(
        &self,
        req: Request<pb::InterpretRequest>,
    ) -> Result<Response<Self::InterpretStream>, Status> {
        require(&req, Role::Observer, "Interpret")?;
        let chunks = super::interpret::chunks(&self.0, req.into_inner()).await?;
        Ok(Response::new(Box::pin(tokio_stream::iter(
            chunks.into_iter().map(Ok),
        ))))
    }

    async fn download(
        &self,
        req: Request<pb::ProgramName>,
    ) -> Result<Response<Self::DownloadStream>, Status> {
        require(&req, Role::Observer, "Download")?;
        let name = req.into_inner().name;
        let (file, _) = self.0.library.open_program(&name).map_err(library_status)?;
        let (tx, rx) = tokio::sync::mpsc::channel(4);
        tokio::task::spawn_blocking(move || send_file(&file, &name, &tx));
        Ok(Response::new(Box::pin(
            tokio_stream::wrappers::ReceiverStream::new(rx),
        )))
    }

    async fn list(
        &self,
        req: Request<pb::LibraryListRequest>,
    ) -> Result<Response<pb::LibraryList>, Status> {
        require(&req, Role::Observer, "List")?;
        let lib = &self.0.library;
        Ok(Response::new(pb::LibraryList {
            programs: (lib.list().iter())
                .map(|e| entry_pb(e, self.0.ctl.default_dialect()))
                .collect(),
            selected: selected_name(&self.0).unwrap_or_default(),
            used_bytes: lib.used_bytes(),
            max_bytes: lib.max_bytes(),
            selected_revision: selected_name(&self.0)
                .and_then(|n| lib.entry(&n))
                .map(|e| e.revision)
                .unwrap_or_default(),
        }))
    }

    async fn delete(
        &self,
        req: Request<pb::ProgramName>,
    ) -> Result<Response<pb::DeleteProgramReply>, Status> {
        require(&req, Role::Operator, "Delete")?;
        let name = req.into_inner().name;
        refuse_if_selected(&self.0, &name, "delete")?;
        let lib = self.0.library.clone();
        blocking(move || lib.delete(&name))
            .await?
            .map_err(library_status)?;
        Ok(Response::new(pb::DeleteProgramReply {}))
    }

    async fn rename(
        &self,
        req: Request<pb::RenameProgramRequest>,
    ) -> Result<Response<pb::LibraryProgram>, Status> {
        require(&req, Role::Operator, "Rename")?;
        let r = req.into_inner();
        check_name(&r.to)?;
        refuse_if_selected(&self.0, &r.from, "rename")?;
        let lib = self.0.library.clone();
        let e = blocking(move || lib.rename(&r.from, &r.to))
            .await?
            .map_err(library_status)?;
        Ok(Response::new(entry_pb(&e, self.0.ctl.default_dialect())))
    }
}

/// Sends a stored file in chunks (blocking thread).
fn send_file(
    file: &File,
    name: &str,
    tx: &tokio::sync::mpsc::Sender<Result<pb::ProgramChunk, Status>>,
) {
    use std::os::unix::fs::FileExt;
    let mut pos = 0u64;
    let mut first = true;
    loop {
        let mut buf = vec![0u8; CHUNK_BYTES];
        let n = match file.read_at(&mut buf, pos) {
            Ok(n) => n,
            Err(e) => {
                let _ = tx.blocking_send(Err(Status::internal(e.to_string())));
                return;
            }
        };
        if n == 0 && !first {
            return;
        }
        buf.truncate(n);
        pos += n as u64;
        let msg = pb::ProgramChunk {
            name: if first { name.into() } else { String::new() },
            data: buf,
            ..Default::default()
        };
        first = false;
        if tx.blocking_send(Ok(msg)).is_err() || n == 0 {
            return;
        }
    }
}
