//! What a program's probing move (G38.2..G38.5, CNC836 G31; docs/language.md, "Probing")
//! tells the interpreter, from what the RT thread saw (`rt_core::ProgramProbe`): LinuxCNC's
//! rules. A move that must find its change (G38.2, G38.4, G31) and ends without one ends
//! the run with `probe_no_contact`; any probing move that would start with the probe already
//! in the state it looks for ends it with `probe_already_triggered` (nothing moved).

use kernel::block::{Block, Path};
use kernel::probe::ProbeResult;
use kernel::{DiagCode, Diagnostic};

use super::rt_core::{ProbeOutcome, ProgramProbe};

/// The result of block `b`'s probing move as `p` reports it, or the error that ends the run.
pub fn result(b: &Block, p: &ProgramProbe) -> Result<ProbeResult, Diagnostic> {
    let must_trip = match b.motion() {
        Some((_, _, Path::Probe(mv))) => mv.must_trip,
        _ => true,
    };
    let fail = |code, message: &str| Err(Diagnostic::error(code, b.n, b.line, 0, message));
    match p.outcome {
        ProbeOutcome::Contact => Ok(ProbeResult {
            tripped: true,
            trip_mm: p.trip_mm,
            stop_mm: p.stop_mm,
        }),
        ProbeOutcome::NoContact if !must_trip => Ok(ProbeResult {
            tripped: false,
            trip_mm: p.stop_mm,
            stop_mm: p.stop_mm,
        }),
        ProbeOutcome::NoContact => fail(
            DiagCode::ProbeNoContact,
            "the probing move reached its end without the probe changing",
        ),
        ProbeOutcome::Refused => fail(
            DiagCode::ProbeUnavailable,
            "the machine has no probe input (function = \"probe\", docs/io.md): nothing moved",
        ),
        ProbeOutcome::AlreadyTriggered => fail(
            DiagCode::ProbeAlreadyTriggered,
            "the probe already read what the probing move looks for: nothing moved",
        ),
        _ => fail(
            DiagCode::ProbeAborted,
            "the probing move ended before its result was known",
        ),
    }
}
