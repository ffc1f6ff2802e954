//! Commands of the Programs service: the program library (upload, list, download, delete,
//! rename) and `load`/`run`, which upload and select a program first.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use indicatif::{ProgressBar, ProgressStyle};
use proto::v1 as pb;
use proto::v1::programs_client::ProgramsClient;
use serde_json::{Value, json};

use crate::args::Cmd;
use crate::call::{Reply, call, call_done};
use crate::connect::{Clients, Svc};
use crate::dialect;
use crate::error::CliError;
use crate::machine::follow;
use crate::render::{
    Render, diag_line, diag_lines, diags_json, emit, local_time, show, totals_json, totals_line,
};

/// Runs one Programs command (main routes only these here).
pub async fn command(c: &mut Clients, cmd: Cmd, j: bool) -> Reply {
    match cmd {
        Cmd::Run {
            file,
            quiet,
            dialect,
        } => run(c, &file, quiet, &dialect::flag(dialect.as_deref())?, j).await,
        Cmd::Validate { file, dialect } => {
            let d = dialect::flag(dialect.as_deref())?;
            validate(&mut c.programs, &file, d, j).await
        }
        other => library(&mut c.programs, other, j).await,
    }
}

/// The commands on the library itself.
async fn library(g: &mut ProgramsClient<Svc>, cmd: Cmd, j: bool) -> Reply {
    match cmd {
        Cmd::Load { file, dialect } => {
            let to = Target::new(&file, None, dialect.as_deref(), true)?;
            let done = upload(g, &file, to, j).await?;
            show(j, &Loaded { file, done })
        }
        Cmd::Upload {
            file,
            name,
            dialect,
        } => {
            let to = Target::new(&file, name, dialect.as_deref(), false)?;
            let done = upload(g, &file, to, j).await?;
            show(j, &Stored(done.program.unwrap_or_default()))
        }
        Cmd::Programs => call(j, g.list(pb::LibraryListRequest {})).await,
        Cmd::Download { name, out } => download(g, name, out.as_deref()).await,
        Cmd::Delete { name } => call_done(j, g.delete(pb::ProgramName { name })).await,
        Cmd::Rename { from, to } => {
            call_done(j, g.rename(pb::RenameProgramRequest { from, to })).await
        }
        _ => unreachable!("main routes only Programs service commands here"),
    }
}

/// `run`: upload and select, start, and follow the job to its end.
async fn run(c: &mut Clients, file: &Path, quiet: bool, dialect: &str, j: bool) -> Reply {
    let to = Target {
        name: file_name(file),
        dialect: dialect.into(),
        select: true,
    };
    let done = upload(&mut c.programs, file, to, quiet || j).await?;
    for d in &done.diagnostics {
        eprintln!("{}", diag_line(d));
    }
    let job = c
        .machine
        .start(pb::StartRequest::default())
        .await?
        .into_inner()
        .job;
    follow(&mut c.machine, job, quiet || j, j).await
}

struct Loaded {
    file: PathBuf,
    done: pb::UploadDone,
}

impl Render for Loaded {
    fn json(&self) -> Value {
        json!({"blocks": self.blocks(), "diagnostics": diags_json(&self.done.diagnostics),
            "totals": totals_json(self.done.totals)})
    }
    fn human(&self) -> String {
        format!("loaded {} ({} blocks)", self.file.display(), self.blocks())
            + &diag_lines(&self.done.diagnostics)
            + &totals_line(self.done.totals)
    }
}

impl Loaded {
    fn blocks(&self) -> u32 {
        self.done.program.as_ref().map_or(0, |p| p.blocks)
    }
}

/// A program stored in the library.
struct Stored(pb::LibraryProgram);

impl Render for Stored {
    fn json(&self) -> Value {
        let p = &self.0;
        json!({"name": p.name, "blocks": p.blocks, "size_bytes": p.size_bytes})
    }
    fn human(&self) -> String {
        let p = &self.0;
        format!(
            "stored {} ({} blocks, {} bytes)",
            p.name, p.blocks, p.size_bytes
        )
    }
}

/// The library listing; for people `*` marks the selected program.
impl Render for pb::LibraryList {
    fn json(&self) -> Value {
        json!({"selected": self.selected, "used_bytes": self.used_bytes, "max_bytes": self.max_bytes,
            "programs": self.programs.iter().map(|p| json!({"name": p.name, "blocks": p.blocks,
            "size_bytes": p.size_bytes, "modified_unix_ms": p.modified_unix_ms, "valid": p.valid,
            "errors": p.errors, "warnings": p.warnings, "first_error": p.first_error,
            "revision": p.revision, "dialect": p.dialect})).collect::<Vec<_>>(),
            "selected_revision": self.selected_revision})
    }
    fn human(&self) -> String {
        let mut out = format!(
            "{} programs, {} of {} bytes",
            self.programs.len(),
            self.used_bytes,
            self.max_bytes
        );
        for p in &self.programs {
            let when = local_time(p.modified_unix_ms);
            let verdict = if p.valid {
                format!("valid, {} warnings", p.warnings)
            } else {
                format!("{} errors: {}", p.errors, p.first_error)
            };
            out.push_str(&format!(
                "\n{} {:<30} {:<6} {:>9} blocks {:>11} bytes  stored {when}  rev {}  {verdict}",
                if p.name == self.selected { "*" } else { " " },
                p.name,
                p.dialect,
                p.blocks,
                p.size_bytes,
                if p.revision.is_empty() {
                    "-"
                } else {
                    &p.revision
                },
            ));
        }
        out
    }
}

/// Writes a stored program to `out` (or standard output).
async fn download(g: &mut ProgramsClient<Svc>, name: String, out: Option<&Path>) -> Reply {
    let mut s = g.download(pb::ProgramName { name }).await?.into_inner();
    let mut sink: Box<dyn Write> = match out {
        Some(p) => Box::new(std::fs::File::create(p).map_err(CliError::write(p))?),
        None => Box::new(std::io::stdout()),
    };
    while let Some(m) = s.message().await? {
        sink.write_all(&m.data).map_err(CliError::Output)?;
    }
    sink.flush().map_err(CliError::Output)?;
    Ok(ExitCode::SUCCESS)
}

struct Validated<'a> {
    file: &'a Path,
    r: pb::ValidateProgramReply,
}

impl Render for Validated<'_> {
    fn json(&self) -> Value {
        json!({"valid": self.r.valid, "blocks": self.r.blocks,
            "diagnostics": diags_json(&self.r.diagnostics), "totals": totals_json(self.r.totals)})
    }
    fn human(&self) -> String {
        let head = if self.r.valid {
            format!("{}: valid, {} blocks", self.file.display(), self.r.blocks)
        } else {
            format!("{}: has errors", self.file.display())
        };
        head + &diag_lines(&self.r.diagnostics) + &totals_line(self.r.totals)
    }
}

/// Validates a program file of any size (Programs.Validate, in chunks as an upload; the name
/// and `dialect` say its language); fails when it has errors.
async fn validate(g: &mut ProgramsClient<Svc>, file: &Path, dialect: String, j: bool) -> Reply {
    let f = std::fs::File::open(file).map_err(CliError::read(file))?;
    let (tx, rx) = tokio::sync::mpsc::channel::<pb::ProgramChunk>(4);
    let bar = ProgressBar::hidden();
    let b = bar.clone();
    let first = pb::ProgramChunk {
        name: file_name(file),
        dialect,
        ..Default::default()
    };
    let reader = tokio::task::spawn_blocking(move || send_chunks(f, first, &b, &tx));
    let r = g
        .validate(tokio_stream::wrappers::ReceiverStream::new(rx))
        .await?
        .into_inner();
    reader
        .await
        .map_err(|e| CliError::UploadReader(e.to_string()))??;
    let valid = r.valid;
    emit(j, &Validated { file, r });
    Ok(if valid {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

/// Upload chunk size: well below the 4 MiB message limit.
const UPLOAD_CHUNK_BYTES: usize = 1 << 20;

/// The file name of `file` (what a program is stored as, and its dialect by extension).
fn file_name(file: &Path) -> String {
    file.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// Where an upload goes: the name, the dialect asked for ("" : by the name), selected or not.
struct Target {
    name: String,
    dialect: String,
    select: bool,
}

impl Target {
    fn new(
        file: &Path,
        name: Option<String>,
        dialect: Option<&str>,
        select: bool,
    ) -> Result<Target, CliError> {
        Ok(Target {
            name: name.unwrap_or_else(|| file_name(file)),
            dialect: dialect::flag(dialect)?,
            select,
        })
    }
}

/// Uploads `file` through Programs.Upload in chunks, read as it is sent (any size), with a
/// progress bar for the upload and then the validation; selects it when `to.select`.
async fn upload(
    g: &mut ProgramsClient<Svc>,
    file: &Path,
    to: Target,
    quiet: bool,
) -> Result<pb::UploadDone, CliError> {
    let f = std::fs::File::open(file).map_err(CliError::read(file))?;
    let total = f.metadata().map(|m| m.len()).unwrap_or(0);
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(total)
    };
    bar.set_style(
        ProgressStyle::with_template("{msg:>10} [{bar:30}] {bytes}/{total_bytes} {bytes_per_sec}")
            .expect("static template"),
    );
    bar.set_message("upload");
    let (tx, rx) = tokio::sync::mpsc::channel::<pb::ProgramChunk>(4);
    let first = pb::ProgramChunk {
        name: to.name,
        select: to.select,
        total_bytes: total,
        dialect: to.dialect,
        ..Default::default()
    };
    let b = bar.clone();
    let reader = tokio::task::spawn_blocking(move || send_chunks(f, first, &b, &tx));
    let replies = g
        .upload(tokio_stream::wrappers::ReceiverStream::new(rx))
        .await?
        .into_inner();
    let done = upload_progress(replies, &bar).await?;
    reader
        .await
        .map_err(|e| CliError::UploadReader(e.to_string()))??;
    Ok(done)
}

/// Reads `f` in chunks and sends them, the first carrying `first`'s name, selection and size.
fn send_chunks(
    mut f: std::fs::File,
    first: pb::ProgramChunk,
    bar: &ProgressBar,
    tx: &tokio::sync::mpsc::Sender<pb::ProgramChunk>,
) -> Result<(), CliError> {
    let mut first = Some(first);
    loop {
        let mut buf = vec![0u8; UPLOAD_CHUNK_BYTES];
        let n = f
            .read(&mut buf)
            .map_err(|e| CliError::UploadReader(e.to_string()))?;
        buf.truncate(n);
        let msg = match first.take() {
            Some(head) => pb::ProgramChunk { data: buf, ..head },
            None if n == 0 => return Ok(()),
            None => pb::ProgramChunk {
                data: buf,
                ..Default::default()
            },
        };
        bar.inc(n as u64);
        if tx.blocking_send(msg).is_err() {
            return Ok(()); // the server ended the call: its status says why
        }
    }
}

/// Follows the daemon's upload replies (bytes stored, then blocks validated) to its answer.
async fn upload_progress(
    mut replies: tonic::Streaming<pb::UploadProgress>,
    bar: &ProgressBar,
) -> Result<pb::UploadDone, CliError> {
    let mut validating = false;
    while let Some(p) = replies.message().await.inspect_err(|_| bar.abandon())? {
        if let Some(done) = p.done {
            bar.finish_and_clear();
            return Ok(done);
        }
        if p.blocks_validated > 0 {
            if !validating {
                validating = true;
                bar.set_style(
                    ProgressStyle::with_template("{msg:>10} {pos} blocks {per_sec}")
                        .expect("static template"),
                );
                bar.set_message("validate");
                bar.set_position(0);
            }
            bar.set_position(p.blocks_validated.into());
        }
    }
    Err(CliError::UploadUnanswered)
}
