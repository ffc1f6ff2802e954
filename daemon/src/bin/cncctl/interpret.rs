//! `interpret`: the dry run (`Programs.Interpret`, docs/language.md "The dry run"). With
//! `--json` one JSON object per move and line, exactly as `kernel::program::dry_run::Move::json`
//! writes it (the daemon sends that line with every move); for people a table. The messages
//! go to standard error; the exit status is 1 when the program has an error.

use std::path::PathBuf;
use std::process::ExitCode;

use proto::v1 as pb;
use proto::v1::programs_client::ProgramsClient;

use crate::call::Reply;
use crate::connect::Svc;
use crate::dialect;
use crate::render::{diag_line, print_line, read_text, totals_line};

/// What to interpret and how (`cncctl interpret` arguments).
pub struct What {
    pub file: Option<PathBuf>,
    pub stored: Option<String>,
    pub from_position: bool,
    pub dialect: Option<String>,
}

/// The request: a file's text with its name (the daemon reads the dialect from it), a stored
/// program by name, or the selected program.
fn request(w: What) -> Result<pb::InterpretRequest, crate::error::CliError> {
    let dialect = dialect::flag(w.dialect.as_deref())?;
    let (text, name) = match (&w.file, w.stored) {
        (Some(f), _) => {
            let name = f.file_name().map(|n| n.to_string_lossy().into_owned());
            (read_text(f)?, name.unwrap_or_default())
        }
        (None, Some(name)) => (String::new(), name),
        (None, None) => (String::new(), String::new()),
    };
    Ok(pb::InterpretRequest {
        text,
        name,
        dialect,
        from_position: w.from_position,
    })
}

/// Prints the moves as they come, then the messages; fails when the program has an error.
pub async fn command(g: &mut ProgramsClient<Svc>, w: What, j: bool) -> Reply {
    let mut stream = g.interpret(request(w)?).await?.into_inner();
    let mut moves = 0u64;
    let mut end = None;
    while let Some(c) = stream.message().await? {
        if !c.axes.is_empty() && !j {
            print_line(&header(&c.axes, &c.dialect));
        }
        for m in &c.moves {
            moves += 1;
            print_line(&if j { m.json.clone() } else { row(m) });
        }
        if c.last {
            end = Some((c.diagnostics, c.totals));
        }
    }
    let (diags, totals) = end.unwrap_or_default();
    for d in &diags {
        eprintln!("{}", diag_line(d));
    }
    let errors = totals.is_some_and(|t| t.errors > 0);
    if !j {
        print_line(&format!("{moves} moves{}", totals_line(totals)));
    }
    Ok(if errors {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    })
}

/// The table's header: line, block, kind, one column per axis, then feed and the rest.
fn header(axes: &[String], dialect: &str) -> String {
    let mut s = format!("{:>6} {:<7} {:<9}", "line", "block", "kind");
    for a in axes {
        s.push_str(&format!(" {a:>11}"));
    }
    s.push_str(&format!("  feed, arc, dwell    ({dialect})"));
    s
}

/// One move for people: `    12 N120    arc cw      10.000  ...  F500 centre X5.000 Y0.000 G17`.
fn row(m: &pb::InterpretedMove) -> String {
    let kind = match pb::MoveKind::try_from(m.kind) {
        Ok(pb::MoveKind::Rapid) => "rapid",
        Ok(pb::MoveKind::Feed) => "feed",
        Ok(pb::MoveKind::Arc) if m.clockwise => "arc cw",
        Ok(pb::MoveKind::Arc) => "arc ccw",
        Ok(pb::MoveKind::Dwell) => "dwell",
        _ => "?",
    };
    let block = m.block.map_or("-".to_string(), |n| format!("N{n}"));
    let mut s = format!("{:>6} {block:<7} {kind:<9}", m.line);
    for v in &m.end_mm {
        s.push_str(&format!(" {v:>11.3}"));
    }
    if let Some(f) = m.feed_mm_min {
        s.push_str(&format!("  F{f}"));
    }
    if let Some(f) = m.feed_mm_rev {
        s.push_str(&format!("  F{f}/rev"));
    }
    if !m.plane.is_empty() {
        s.push_str(&format!("  centre {} {}", centre(m), m.plane));
    }
    if m.kind == pb::MoveKind::Dwell as i32 {
        s.push_str(&format!("  {:.3} s", m.dwell_s));
    }
    s
}

/// The arc centre on its plane, e.g. `X5.000 Y0.000`: the two axes the kernel's JSON names.
fn centre(m: &pb::InterpretedMove) -> String {
    let v: serde_json::Value = serde_json::from_str(&m.json).unwrap_or_default();
    let Some(c) = v["centre"].as_object() else {
        return String::new();
    };
    c.iter()
        .map(|(a, x)| format!("{a}{:.3}", x.as_f64().unwrap_or(f64::NAN)))
        .collect::<Vec<_>>()
        .join(" ")
}
