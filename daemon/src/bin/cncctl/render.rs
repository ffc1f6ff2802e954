//! One way to print an answer: every command's result implements [`Render`] (text for people,
//! one JSON value a line with `--json`). Diagnostics are rendered here only.

use std::path::Path;
use std::process::ExitCode;

use prost::Message;
use proto::v1 as pb;
use serde_json::{Value, json};

use crate::error::CliError;

/// A command's answer, as people read it and as JSON.
pub trait Render {
    /// The `--json` form (printed on one line).
    fn json(&self) -> Value;
    /// The form for people; empty prints nothing.
    fn human(&self) -> String;
}

/// Prints `r` in the chosen form.
pub fn emit(json_mode: bool, r: &impl Render) {
    if json_mode {
        print_line(&r.json().to_string());
    } else {
        let h = r.human();
        if !h.is_empty() {
            print_line(&h);
        }
    }
}

/// A time for people: local ISO 8601 with the offset, `2026-11-27T14:05:09+01:00` (the
/// system's time zone; UTC where none is set).
pub fn local_time(unix_ms: u64) -> String {
    match jiff::Timestamp::from_millisecond(unix_ms as i64) {
        Ok(t) => t
            .to_zoned_datetime(jiff::tz::TimeZone::system())
            .strftime("%Y-%m-%dT%H:%M:%S%:z")
            .to_string(),
        Err(_) => format!("{unix_ms} ms after 1970"),
    }
}

/// Writes one line to standard output and flushes it (a reader at the other end of a pipe sees
/// every update as it comes). A reader that went away (`cncctl status --watch | head -1`) ends
/// cncctl quietly with status 0, as `yes | head` does, instead of a panic.
pub fn print_line(line: &str) {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    let r = writeln!(out, "{line}").and_then(|()| out.flush());
    match r {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => std::process::exit(0),
        Err(e) => {
            eprintln!("cncctl: cannot write to standard output: {e}");
            std::process::exit(1);
        }
    }
}

/// Prints `r` and ends the command successfully.
pub fn show(json_mode: bool, r: &impl Render) -> Result<ExitCode, CliError> {
    emit(json_mode, r);
    Ok(ExitCode::SUCCESS)
}

/// A call that answers nothing but success: `{"ok": true}`, silent for people.
pub struct Done;

impl Render for Done {
    fn json(&self) -> Value {
        json!({"ok": true})
    }
    fn human(&self) -> String {
        String::new()
    }
}

/// Renders a gRPC error for a person, with every diagnostic it carries on its own line and
/// the totals when more were found than the details carry.
pub fn explain(s: &tonic::Status) -> String {
    match pb::Diagnostics::decode(s.details()) {
        Ok(d) if !d.items.is_empty() && s.code() == tonic::Code::InvalidArgument => {
            let listed = d.items.len() as u64;
            let all = d.totals.map_or(0, |t| t.errors + t.warnings + t.infos);
            let more = if all > listed {
                format!(
                    "{}\n  (the first {listed} shown; `cncctl validate FILE` lists the first 200)",
                    totals_line(d.totals)
                )
            } else {
                String::new()
            };
            format!("{:?}: rejected{}{more}", s.code(), diag_lines(&d.items))
        }
        // Refused for another reason (e.g. `[storage_file_invalid]`: a file on disk must be
        // fixed first): the reason, then the diagnostics it carries.
        Ok(d) if !d.items.is_empty() => {
            let first = s.message().split(" (").next().unwrap_or_default();
            format!("{:?}: {first}{}", s.code(), diag_lines(&d.items))
        }
        _ => format!("{:?}: {}", s.code(), s.message()),
    }
}

/// `\n  totals: 3 errors, 1 warnings, 0 notes`, or nothing when the daemon sent no totals.
pub fn totals_line(t: Option<pb::DiagnosticCounts>) -> String {
    match t {
        Some(t) if t.errors + t.warnings + t.infos > 0 => format!(
            "\n  totals: {} errors, {} warnings, {} notes",
            t.errors, t.warnings, t.infos
        ),
        _ => String::new(),
    }
}

/// The totals as JSON (`null` when the daemon sent none).
pub fn totals_json(t: Option<pb::DiagnosticCounts>) -> Value {
    t.map_or(
        Value::Null,
        |t| json!({"errors": t.errors, "warnings": t.warnings, "infos": t.infos}),
    )
}

/// One diagnostic for people: `error: line 3:5 block N30: message`.
pub fn diag_line(i: &pb::Diagnostic) -> String {
    let sev = pb::Severity::try_from(i.severity)
        .map(|s| {
            s.as_str_name()
                .trim_start_matches("SEVERITY_")
                .to_lowercase()
        })
        .unwrap_or_default();
    let sev = if i.code.is_empty() {
        sev
    } else {
        format!("{sev} [{}]", i.code)
    };
    let block = i.block.map(|n| format!(" block N{n}")).unwrap_or_default();
    // Line 0: the value did not come from a text (an offset or constant set by its name,
    // which the message names).
    if i.line == 0 {
        return format!("{sev}{block}: {}", i.message);
    }
    format!("{sev}: line {}:{}{block}: {}", i.line, i.column, i.message)
}

/// Every diagnostic on its own indented line, each line starting with a newline.
pub fn diag_lines(items: &[pb::Diagnostic]) -> String {
    items
        .iter()
        .map(|d| format!("\n  {}", diag_line(d)))
        .collect()
}

fn diag_json(i: &pb::Diagnostic) -> Value {
    json!({"severity": pb::Severity::try_from(i.severity).map(|s| s.as_str_name()).unwrap_or("?"),
        "block": i.block, "line": i.line, "column": i.column, "code": i.code, "message": i.message})
}

/// Every diagnostic as a JSON array.
pub fn diags_json(items: &[pb::Diagnostic]) -> Value {
    Value::Array(items.iter().map(diag_json).collect())
}

/// `N30`, or `-` for a block without a number.
pub fn block_name(block: Option<u32>) -> String {
    block.map(|n| format!("N{n}")).unwrap_or_else(|| "-".into())
}

/// A program file's text.
pub fn read_text(file: &Path) -> Result<String, CliError> {
    std::fs::read_to_string(file).map_err(CliError::read(file))
}
