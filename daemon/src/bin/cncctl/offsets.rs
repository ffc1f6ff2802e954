//! Commands of the Offsets service: the offset table (TAB0.KOR) in memory and on file.

use std::path::Path;

use proto::v1 as pb;
use proto::v1::offsets_client::OffsetsClient;
use serde_json::{Value, json};

use crate::args::Cmd;
use crate::call::{Reply, call, call_as};
use crate::connect::Svc;
use crate::error::CliError;
use crate::render::{Render, read_text};

/// `X10`, `Y-2.5` or `X=10`: an axis letter and a value in mm.
fn axis_value(arg: &str) -> Result<pb::AxisValue, CliError> {
    let bad = || CliError::AxisValue(arg.to_string());
    let mut chars = arg.chars();
    let axis = chars
        .next()
        .filter(char::is_ascii_alphabetic)
        .ok_or_else(bad)?;
    let rest = chars.as_str();
    let value_mm = rest
        .strip_prefix('=')
        .unwrap_or(rest)
        .parse()
        .map_err(|_| bad())?;
    Ok(pb::AxisValue {
        axis: axis.to_string(),
        value_mm,
    })
}

/// The work offsets as JSON: axes, and per system its name and offsets.
fn work_json(w: &pb::WorkOffsetTable) -> Value {
    json!({"axes": w.axes, "active_at_start": w.active_at_start, "revision": w.revision,
        "systems": w.systems.iter().map(|s| json!({"name": s.name, "offset_mm": s.offset_mm}))
        .collect::<Vec<_>>()})
}

/// The nine systems for people, the one in force at program start marked.
impl Render for pb::WorkOffsetTable {
    fn json(&self) -> Value {
        work_json(self)
    }
    fn human(&self) -> String {
        let mut s = format!("{:<6}", "");
        for a in &self.axes {
            s.push_str(&format!(" {a:>12}"));
        }
        for sys in &self.systems {
            s.push_str(&format!("\n{:<6}", sys.name));
            for v in &sys.offset_mm {
                s.push_str(&format!(" {v:>12.4}"));
            }
            if sys.name == self.active_at_start {
                s.push_str("  (in force at program start)");
            }
        }
        s
    }
}

/// Runs one Offsets command (main routes only these here).
pub async fn command(o: &mut OffsetsClient<Svc>, cmd: Cmd, j: bool) -> Reply {
    match cmd {
        Cmd::Offsets { all } => {
            call(
                j,
                o.get_offsets(pb::GetOffsetsRequest { include_zero: all }),
            )
            .await
        }
        Cmd::OffsetSet {
            entry,
            radius,
            l1,
            l2,
            l3,
            l4,
        } => {
            let req = pb::SetOffsetRequest {
                entry,
                radius_mm: radius,
                length1_mm: l1,
                length2_mm: l2,
                length3_mm: l3,
                length4_mm: l4,
            };
            call(j, o.set_offset(req)).await
        }
        Cmd::TouchOff {
            entry,
            axis,
            value,
            radius,
            work,
        } => {
            let req = pb::TouchOffRequest {
                entry,
                axis,
                value_mm: value,
                radius_mm: radius,
                work_offset: work.unwrap_or_default(),
            };
            call(j, o.touch_off(req)).await
        }
        Cmd::OffsetsFile => call(j, o.get_offsets_file(pb::GetOffsetsFileRequest {})).await,
        Cmd::OffsetsReplace { file, revision } => replace(o, &file, revision, j).await,
        Cmd::OffsetsReload => {
            let answer = o.reload_offsets(pb::ReloadOffsetsRequest {});
            call_as(j, answer, |r| Entries("reloaded", r.entries)).await
        }
        Cmd::WorkOffsets => call(j, o.list_work_offsets(pb::ListWorkOffsetsRequest {})).await,
        Cmd::WorkOffsetSet { system, values } => {
            let values = values
                .iter()
                .map(|v| axis_value(v))
                .collect::<Result<Vec<_>, _>>()?;
            let req = pb::SetWorkOffsetRequest { system, values };
            call(j, o.set_work_offset(req)).await
        }
        _ => unreachable!("main routes only Offsets service commands here"),
    }
}

async fn replace(
    o: &mut OffsetsClient<Svc>,
    file: &Path,
    revision: Option<String>,
    j: bool,
) -> Reply {
    let text = read_text(file)?;
    // The base: the revision the operator saw, else the one on disk now (never over a save
    // cncctl has not seen, issue #31).
    let revision = match revision {
        Some(r) => r,
        None => {
            o.get_offsets_file(pb::GetOffsetsFileRequest {})
                .await?
                .into_inner()
                .revision
        }
    };
    let answer = o.replace_offsets_file(pb::OffsetsFile { text, revision });
    call_as(j, answer, |r| Entries("TAB0.KOR replaced", r.entries)).await
}

/// The table as people read it: `D`, radius and lengths, G92 changes marked.
impl Render for pb::GetOffsetsReply {
    fn json(&self) -> Value {
        json!({"labels": self.labels, "entries": self.entries.iter().map(|e| json!({"entry": e.entry, "radius_mm": e.radius_mm, "length_mm": e.length_mm, "changed_by_program": e.changed_by_program})).collect::<Vec<_>>(),
            "work_offsets": self.work_offsets.as_ref().map(work_json)})
    }
    fn human(&self) -> String {
        let mut s = format!(
            "{:>3} {:>12}",
            "D",
            self.labels.first().cloned().unwrap_or_default()
        );
        for l in self.labels.iter().skip(1) {
            s.push_str(&format!(" {l:>12}"));
        }
        for e in &self.entries {
            s.push_str(&format!("\n{:>3} {:>12.4}", e.entry, e.radius_mm));
            for l in &e.length_mm {
                s.push_str(&format!(" {l:>12.4}"));
            }
            if e.changed_by_program {
                s.push_str("  (G92, not in file)");
            }
        }
        // The work offsets that are set (`work-offsets` lists all nine).
        if let Some(w) = &self.work_offsets {
            for sys in w
                .systems
                .iter()
                .filter(|s| s.offset_mm.iter().any(|v| *v != 0.0))
            {
                let vals: Vec<String> = (w.axes.iter().zip(&sys.offset_mm))
                    .map(|(a, v)| format!("{a}{v:.4}"))
                    .collect();
                s.push_str(&format!("\n{} {}", sys.name, vals.join(" ")));
            }
        }
        s
    }
}

/// One entry after an operator edit.
impl Render for pb::OffsetEntry {
    fn json(&self) -> Value {
        json!({"entry": self.entry, "radius_mm": self.radius_mm, "length_mm": self.length_mm})
    }
    fn human(&self) -> String {
        format!(
            "D{}: R={} lengths {:?}",
            self.entry, self.radius_mm, self.length_mm
        )
    }
}

impl Render for pb::OffsetsFile {
    fn json(&self) -> Value {
        json!({"text": self.text, "revision": self.revision})
    }
    fn human(&self) -> String {
        self.text.trim_end().to_string()
    }
}

/// The table was replaced or reloaded: what happened, and its non-zero entries.
struct Entries(&'static str, u32);

impl Render for Entries {
    fn json(&self) -> Value {
        json!({"entries": self.1})
    }
    fn human(&self) -> String {
        format!("{}: {} non-zero entries", self.0, self.1)
    }
}

/// A touch-off: the length written, from where, and the entry now.
impl Render for pb::TouchOffReply {
    fn json(&self) -> Value {
        let e = self.entry.clone().unwrap_or_default();
        json!({"entry": e.entry, "radius_mm": e.radius_mm, "length_mm": e.length_mm,
            "written_length_mm": self.length_mm, "machine_mm": self.machine_mm})
    }
    fn human(&self) -> String {
        let e = self.entry.clone().unwrap_or_default();
        let lengths: Vec<String> = e.length_mm.iter().map(|v| format!("{v:.4}")).collect();
        format!(
            "D{:02}: length {:.6} mm written (machine at {:.6} mm); R {:.4}, lengths {}",
            e.entry,
            self.length_mm,
            self.machine_mm,
            e.radius_mm,
            lengths.join(" ")
        )
    }
}
