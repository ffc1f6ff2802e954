//! `Programs.Validate`: validation of a program of any size sent in chunks (issue #31), the
//! way Upload takes it but without storing anything. The chunks go through a small bounded
//! channel to a blocking reader that feeds the one pipeline line by line, so memory stays
//! bounded whatever the size (a unary ValidateProgram stops at the 4 MiB message limit).

use std::io::{BufReader, Read};
use std::sync::Arc;

use proto::v1 as pb;
use tokio::sync::mpsc;
use tokio_stream::StreamExt;
use tonic::{Status, Streaming};

use kernel::pipeline::{self, Flow, Options};
use kernel::plan::Segment;

use super::{ApiState, blocking, counts_pb, diagnostic_to_pb, status_of};
use crate::runtime::library::FileLines;

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

struct Nothing;

impl pipeline::Observer for Nothing {
    fn segment(&mut self, _s: Segment) -> Flow {
        Flow::Go
    }
}

/// Validates the chunks of `input` against the machine as it is now.
pub async fn validate_chunks(
    st: &Arc<ApiState>,
    mut input: Streaming<pb::ProgramChunk>,
) -> Result<pb::ValidateProgramReply, Status> {
    let (tx, rx) = mpsc::channel::<Vec<u8>>(CHUNKS_IN_FLIGHT);
    let s = st.clone();
    let pass = blocking(move || -> Result<pipeline::Validation, Status> {
        let setup = s.ctl.machine_setup().map_err(status_of)?;
        s.ctl.count_validation_pass();
        let reader = ChunkReader {
            rx,
            chunk: Vec::new(),
            pos: 0,
        };
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
