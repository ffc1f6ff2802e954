//! Diagnostics in API replies and refusals: the kernel's diagnostics as `cnc.v1.Diagnostic`,
//! their totals, and the bounded details a refusal carries (status details travel in a header,
//! so they are cut to fit), and controller errors mapped to gRPC statuses.

use prost::Message;
use proto::v1 as pb;
use tonic::{Code, Status};

use kernel::{Diagnostic, Severity};

use crate::runtime::controller::ControlError;
use crate::runtime::storage::StorageError;

/// A refusal with one coded diagnostic in its details (not tied to a program line).
pub fn refused(code: Code, what: kernel::DiagCode, msg: String) -> Status {
    let d = Diagnostic::error(what, None, 0, 0, msg.clone());
    let details = pb::Diagnostics {
        items: vec![diagnostic_to_pb(&d)],
        totals: Some(counts_pb(std::slice::from_ref(&d))),
    };
    Status::with_details(
        code,
        format!("{what}: {msg}"),
        details.encode_to_vec().into(),
    )
}

pub fn diagnostic_to_pb(d: &Diagnostic) -> pb::Diagnostic {
    pb::Diagnostic {
        severity: match d.severity {
            Severity::Info => pb::Severity::Info,
            Severity::Warning => pb::Severity::Warning,
            Severity::Error => pb::Severity::Error,
        } as i32,
        block: d.block,
        line: d.line,
        column: d.column,
        message: d.message.clone(),
        code: d.code.as_str().to_string(),
        soft_limit: d.limit.map(|h| pb::SoftLimitHit {
            axis: h.axis_name.to_string(),
            position_mm: h.position_mm,
            limit_mm: h.limit_mm,
            upper: h.upper,
        }),
    }
}

/// The totals of a capped list (see `kernel::pipeline::MAX_LISTED`).
pub fn counts_pb(diags: &[Diagnostic]) -> pb::DiagnosticCounts {
    let c = kernel::DiagCounts::of(diags);
    pb::DiagnosticCounts {
        errors: c.errors,
        warnings: c.warnings,
        infos: c.infos,
    }
}

/// Bytes of encoded diagnostics a refusal's details may carry: status details travel in a
/// header (base64, a third larger) and every header of a reply must fit the client's limit
/// (16 KiB in tonic/hyper, 8 KiB in grpcio), so a refusal never becomes a transport error.
pub const DETAILS_MAX_BYTES: usize = 4096;

/// A diagnostic's message in the details is cut to this many characters.
const DETAILS_MESSAGE_CHARS: usize = 200;

/// How many errors the status message names.
const MESSAGE_ERRORS: usize = 5;

/// INVALID_ARGUMENT whose message names the first errors and the totals, and whose details
/// carry a `cnc.v1.Diagnostics`: the first diagnostics that fit [`DETAILS_MAX_BYTES`] (the
/// first error always among them) and the totals.
pub fn invalid_with_diagnostics(what: &str, diags: &[Diagnostic]) -> Status {
    let totals = counts_pb(diags);
    let mut msg = format!(
        "{what} rejected, {} error(s), {} warning(s): ",
        totals.errors, totals.warnings
    );
    for (i, d) in diags
        .iter()
        .filter(|d| d.is_error())
        .take(MESSAGE_ERRORS)
        .enumerate()
    {
        if i > 0 {
            msg.push_str("; ");
        }
        msg.push_str(&cut(&d.to_string(), DETAILS_MESSAGE_CHARS));
    }
    let details = bounded_details(diags);
    Status::with_details(Code::InvalidArgument, msg, details.encode_to_vec().into())
}

/// The details of a refusal: the first diagnostics that fit [`DETAILS_MAX_BYTES`] (the first
/// error always among them, messages cut) and the totals.
pub fn bounded_details(diags: &[Diagnostic]) -> pb::Diagnostics {
    let totals = counts_pb(diags);
    let mut details = pb::Diagnostics {
        items: Vec::new(),
        totals: Some(totals),
    };
    let mut used = details.encoded_len();
    let first_error = diags.iter().position(Diagnostic::is_error);
    for (i, d) in diags.iter().enumerate() {
        let mut item = diagnostic_to_pb(d);
        item.message = cut(&item.message, DETAILS_MESSAGE_CHARS);
        // Room is kept for the first error when it comes later.
        let reserve = match first_error {
            Some(k) if k > i => 512,
            _ => 0,
        };
        let n = item.encoded_len() + 3;
        if used + n + reserve > DETAILS_MAX_BYTES && Some(i) != first_error {
            if first_error.is_some_and(|k| k > i) {
                continue;
            }
            break;
        }
        used += n;
        details.items.push(item);
    }
    details
}

/// `s` cut to `max` characters (an ellipsis marks the cut).
fn cut(s: &str, max: usize) -> String {
    match s.char_indices().nth(max) {
        Some((k, _)) => format!("{}…", &s[..k]),
        None => s.to_owned(),
    }
}

/// Refused while the drives are being enabled (start-up, after Reset): UNAVAILABLE with
/// `machine_not_ready`, so a client retries instead of taking the machine for busy.
pub fn ready_for_motion(state: crate::runtime::rt::MachineState) -> Result<(), Status> {
    if state != crate::runtime::rt::MachineState::Enabling {
        return Ok(());
    }
    Err(refused(
        Code::Unavailable,
        kernel::DiagCode::MachineNotReady,
        "the drives are being enabled (start-up or Reset): try again once the machine is idle"
            .into(),
    ))
}

/// Maps controller errors to gRPC statuses.
pub fn status_of(e: ControlError) -> Status {
    match e {
        ControlError::InvalidProgram(diags) => invalid_with_diagnostics("program", &diags),
        ControlError::WrongState(m) => Status::failed_precondition(m),
        ControlError::RtGone => Status::unavailable("the real-time thread has stopped"),
        ControlError::Storage(e) => match e {
            StorageError::Invalid { diagnostics, .. } => {
                invalid_with_diagnostics("table", &diagnostics)
            }
            // The file on disk (a hand edit) must be fixed first: its lines and codes.
            StorageError::DiskInvalid {
                ref diagnostics, ..
            } => {
                let details = bounded_details(diagnostics).encode_to_vec();
                Status::with_details(
                    Code::FailedPrecondition,
                    format!("[{}] {e}", e.code()),
                    details.into(),
                )
            }
            StorageError::Changed { .. } => Status::aborted(format!("[{}] {e}", e.code())),
            _ => Status::internal(e.to_string()),
        },
        ControlError::Plc(e) => Status::invalid_argument(e.to_string()),
        ControlError::Invalid(m) => Status::invalid_argument(m),
        ControlError::Aborted(m) => Status::aborted(m),
    }
}

#[cfg(test)]
mod ready_tests {
    use super::*;
    use crate::runtime::rt::MachineState;

    #[test]
    fn motion_while_enabling_is_unavailable_with_its_code() {
        let e = ready_for_motion(MachineState::Enabling).unwrap_err();
        assert_eq!(e.code(), Code::Unavailable);
        assert!(
            e.message().starts_with("machine_not_ready"),
            "{}",
            e.message()
        );
        assert!(ready_for_motion(MachineState::Idle).is_ok());
        // Busy is the command's own business (jog_busy, probe_busy, …).
        assert!(ready_for_motion(MachineState::Running).is_ok());
    }
}
