//! `Programs.Validate`: validation of a program of any size sent in chunks (issue #31), the
//! way Upload takes it but without storing anything. The chunks go through a small bounded
//! channel to a blocking reader that feeds the one pipeline line by line, so memory stays
//! bounded whatever the size (a unary ValidateProgram stops at the 4 MiB message limit). An
//! ISO program's loops and calls read lines again, which chunks cannot give: its chunks are
//! spooled to an unnamed temporary file in the storage directory and validated from there.

use std::fs::{File, OpenOptions};
use std::io::{BufReader, Read};
use std::path::Path;
use std::sync::Arc;

use proto::v1 as pb;
use tokio::sync::mpsc;
use tokio_stream::StreamExt;
use tonic::{Status, Streaming};

use kernel::machine::MachineSetup;
use kernel::pipeline::{self, Flow, Options};
use kernel::plan::Segment;
use kernel::program::Dialect;

use super::{ApiState, blocking, counts_pb, diagnostic_to_pb, dialect_field, status_of};
use crate::runtime::library::FileLines;
use crate::runtime::program_text::Reposition;

/// Chunks in flight between the receiving task and the validating thread.
const CHUNKS_IN_FLIGHT: usize = 4;

/// The bytes of the received chunks as one `Read` (blocking: runs on a blocking thread).
struct ChunkReader {
    rx: mpsc::Receiver<Vec<u8>>,
    chunk: Vec<u8>,
    pos: usize,
}

impl Read for ChunkReader {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        while self.pos == self.chunk.len() {
            match self.rx.blocking_recv() {
                Some(c) => {
                    self.chunk = c;
                    self.pos = 0;
                }
                None => return Ok(0),
            }
        }
        let n = buf.len().min(self.chunk.len() - self.pos);
        buf[..n].copy_from_slice(&self.chunk[self.pos..self.pos + n]);
        self.pos += n;
        Ok(n)
    }
}

/// The chunks come once: a validation from them cannot go back (a CNC836 program never does;
/// an ISO program is spooled to a file first, [`validate_chunks`]).
impl Reposition for BufReader<ChunkReader> {
    fn can_reposition(&self) -> bool {
        false
    }

    fn reposition(&mut self, _offset: u64) -> std::io::Result<()> {
        Err(std::io::ErrorKind::Unsupported.into())
    }
}

struct Nothing;

impl pipeline::Observer for Nothing {
    fn segment(&mut self, _s: &Segment) -> Flow {
        Flow::Go
    }
}

/// Validates the chunks of `input` against the machine as it is now, in the dialect the first
/// message names (its `dialect`, else its name, else the machine's).
pub async fn validate_chunks(
    st: &Arc<ApiState>,
    mut input: Streaming<pb::ProgramChunk>,
) -> Result<pb::ValidateProgramReply, Status> {
    let first = input.next().await.transpose()?.unwrap_or_default();
    let dialect = st
        .ctl
        .dialect_of(&first.name, dialect_field(&first.dialect)?);
    let (tx, rx) = mpsc::channel::<Vec<u8>>(CHUNKS_IN_FLIGHT);
    let s = st.clone();
    let pass = blocking(move || -> Result<pipeline::Validation, Status> {
        let setup = s.ctl.machine_setup_in(dialect).map_err(status_of)?;
        s.ctl.count_validation_pass();
        let reader = ChunkReader {
            rx,
            chunk: Vec::new(),
            pos: 0,
        };
        if dialect == Dialect::Iso {
            let spool = spool(reader, &s.ctl.config().storage.dir)
                .map_err(|e| Status::internal(format!("cannot spool the program: {e}")))?;
            return Ok(validate_file(&Arc::new(spool), &setup));
        }
        let lines = FileLines::new(BufReader::with_capacity(64 << 10, reader))
            .with_encoding(setup.program().encoding);
        Ok(pipeline::validate_lines_into(
            lines,
            &setup,
            Options::default(),
            &mut Nothing,
        ))
    });
    // The chunks are forwarded while the pass runs; a failed stream ends the call.
    let forward = async move {
        if !first.data.is_empty() && tx.send(first.data).await.is_err() {
            return Ok(());
        }
        while let Some(m) = input.next().await {
            let data = m?.data;
            if !data.is_empty() && tx.send(data).await.is_err() {
                break;
            }
        }
        Ok::<(), Status>(())
    };
    let (v, sent) = tokio::join!(pass, forward);
    sent?;
    let v = v??;
    Ok(pb::ValidateProgramReply {
        valid: !v.has_errors(),
        blocks: v.blocks,
        diagnostics: v.diagnostics.iter().map(diagnostic_to_pb).collect(),
        totals: Some(counts_pb(&v.diagnostics)),
        refinements: Vec::new(),
    })
}

/// The received bytes in an unnamed temporary file of `dir` (removed from the directory at
/// once: it goes when the pass lets go of it).
fn spool(mut reader: ChunkReader, dir: &Path) -> std::io::Result<File> {
    static N: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let path = dir.join(format!(".validate-{}-{n}.tmp", std::process::id()));
    let mut f = OpenOptions::new()
        .read(true)
        .write(true)
        .create_new(true)
        .open(&path)?;
    let _ = std::fs::remove_file(&path);
    std::io::copy(&mut reader, &mut f)?;
    Ok(f)
}

/// The pipeline's verdict on a spooled program (read from its file: lines can be read again).
fn validate_file(file: &Arc<File>, setup: &MachineSetup) -> pipeline::Validation {
    let lines = FileLines::open(file).with_encoding(setup.program().encoding);
    pipeline::validate_lines_into(lines, setup, Options::default(), &mut Nothing)
}
