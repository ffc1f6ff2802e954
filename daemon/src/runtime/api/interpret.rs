//! `Programs.Interpret`: the dry run (docs/language.md "The dry run"). A program's interpreted
//! motion (`kernel::program::dry_run`) with the machine's setup (axes, constants, TAB0.KOR, the
//! work offsets of the file), from machine zero unless asked to start where the axes are:
//! one move per motion block or dwell, streamed in chunks, the messages last. Nothing
//! persistent changes: the interpreter works on copies (a `G10 L2` acts within the dry run).
//!
//! **Decided**: machine zero by default, so one file gives the same moves whatever the axes
//! did before (what checking a post-processor needs); `from_position` gives what a Start now
//! would interpret.

use std::sync::Arc;

use proto::v1 as pb;
use tonic::Status;

use kernel::block::ArcDir;
use kernel::program::Dialect;
use kernel::program::dry_run::{Move, MoveKind};

use super::programs::library_status;
use super::{
    ApiState, blocking, counts_pb, diagnostic_to_pb, dialect_field, plane_code, status_of,
};
use crate::runtime::library::ProgramText;

/// Moves per streamed chunk (about 0.6 MB: well below the message limit).
const CHUNK_MOVES: usize = 4096;

/// Largest stored program the dry run reads: its text and moves are held in memory.
pub const INTERPRET_MAX_BYTES: u64 = 16 << 20;

/// The chunks of the dry run of the program `r` names.
pub async fn chunks(
    st: &Arc<ApiState>,
    r: pb::InterpretRequest,
) -> Result<Vec<pb::InterpretChunk>, Status> {
    let field = dialect_field(&r.dialect)?;
    let start = r.from_position.then(|| st.ctl.snapshot().axes.commanded);
    let s = st.clone();
    blocking(move || -> Result<_, Status> {
        // A hand edit of the offsets files saved a moment ago is what the dry run reads.
        s.ctl.sync_files();
        let (text, dialect) = source(&s, r.text, &r.name, field)?;
        let (moves, diags) = s.ctl.interpret(&text, dialect, start).map_err(status_of)?;
        Ok(into_chunks(&s, dialect, &moves, &diags))
    })
    .await?
}

/// The text the request names and its dialect: the text given (dialect by the field, else
/// its name, else the machine's), a stored program, or the selected one (their own dialect
/// unless the field says another).
fn source(
    st: &ApiState,
    text: String,
    name: &str,
    field: Option<Dialect>,
) -> Result<(String, Dialect), Status> {
    if !text.is_empty() {
        return Ok((text, st.ctl.dialect_of(name, field)));
    }
    let (file, dialect) = if name.is_empty() {
        let p = st.ctl.program().ok_or_else(|| {
            Status::failed_precondition("no program is selected and no text or name was given")
        })?;
        (p.text.clone(), field.unwrap_or(p.dialect))
    } else {
        let (file, entry) = st.library.open_program(name).map_err(library_status)?;
        let d = st.ctl.dialect_of(name, field.or(entry.dialect));
        (ProgramText::File(file), d)
    };
    if file.len() > INTERPRET_MAX_BYTES {
        return Err(Status::failed_precondition(format!(
            "the dry run holds the program and its moves in memory: programs over {} MiB are \
             not interpreted (validate them with `cncctl validate`)",
            INTERPRET_MAX_BYTES >> 20
        )));
    }
    let all = file
        .read_all(st.ctl.program_encoding())
        .map_err(|e| Status::internal(format!("cannot read the program: {e}")))?;
    Ok((all.to_string(), dialect))
}

/// The moves in chunks; the first carries the axes and the dialect, the last the messages
/// (the first `kernel::pipeline::MAX_LISTED`) and their totals.
fn into_chunks(
    st: &ApiState,
    dialect: Dialect,
    moves: &[Move],
    diags: &[kernel::Diagnostic],
) -> Vec<pb::InterpretChunk> {
    let names = st.ctl.config().axis_names();
    let mut out: Vec<pb::InterpretChunk> = moves
        .chunks(CHUNK_MOVES)
        .map(|c| pb::InterpretChunk {
            moves: c.iter().map(|m| move_pb(m, &names)).collect(),
            ..Default::default()
        })
        .collect();
    if out.is_empty() {
        out.push(pb::InterpretChunk::default());
    }
    out[0].axes = names.iter().map(char::to_string).collect();
    out[0].dialect = dialect.as_str().into();
    let last = out.last_mut().expect("one chunk at least");
    last.diagnostics = (diags.iter())
        .take(kernel::pipeline::MAX_LISTED)
        .map(diagnostic_to_pb)
        .collect();
    last.totals = Some(counts_pb(diags));
    last.last = true;
    out
}

/// One move for the API, with its JSON line (`Move::json`).
fn move_pb(m: &Move, names: &[char]) -> pb::InterpretedMove {
    let axes = names.len().min(kernel::MAX_AXES);
    let mut out = pb::InterpretedMove {
        end_mm: m.end.0[..axes].to_vec(),
        feed_mm_min: m.feed_mm_min,
        feed_mm_rev: m.feed_mm_rev,
        seq: m.seq,
        block: m.n,
        line: m.line,
        json: m.json(names),
        ..Default::default()
    };
    let kind = match m.kind {
        MoveKind::Rapid => pb::MoveKind::Rapid,
        MoveKind::Feed => pb::MoveKind::Feed,
        MoveKind::Arc { centre, plane, dir } => {
            out.centre_mm = centre.0[..axes].to_vec();
            out.plane = plane_code(plane).into();
            out.clockwise = dir == ArcDir::Cw;
            pb::MoveKind::Arc
        }
        MoveKind::Dwell { seconds } => {
            out.dwell_s = seconds;
            pb::MoveKind::Dwell
        }
    };
    out.kind = kind as i32;
    out
}
