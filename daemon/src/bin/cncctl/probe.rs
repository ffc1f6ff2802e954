//! `cncctl probe` (docs/setup.md, "Probing"): a probing move (Machine.Probe) and the
//! workflows that write an entry of TAB0.KOR (Offsets.ProbeWorkflow).

use proto::v1 as pb;
use serde_json::{Value, json};

use crate::args::ProbeCmd;
use crate::call::{Reply, call};
use crate::connect::Clients;
use crate::error::CliError;
use crate::render::Render;

fn direction(arg: &str) -> Result<i32, CliError> {
    match arg.trim() {
        "+" | "+1" | "1" => Ok(1),
        "-" | "-1" => Ok(-1),
        _ => Err(CliError::ProbeDirection(arg.to_string())),
    }
}

pub async fn command(c: &mut Clients, cmd: ProbeCmd, j: bool) -> Reply {
    use pb::ProbeWorkflowKind as K;
    let workflow = |kind: K, entry: u32, work: Option<String>| pb::ProbeWorkflowRequest {
        kind: kind.into(),
        entry,
        work_offset: work.unwrap_or_default(),
        ..Default::default()
    };
    let req = match cmd {
        ProbeCmd::Move {
            axis,
            distance,
            feed,
            away,
        } => {
            let req = pb::ProbeRequest {
                axis,
                distance_mm: distance,
                feed_mm_min: feed,
                away,
            };
            return call(j, c.machine.probe(req)).await;
        }
        ProbeCmd::ToolSetter { entry, value, work } => pb::ProbeWorkflowRequest {
            value_mm: value,
            ..workflow(K::ToolSetter, entry, work)
        },
        ProbeCmd::Edge {
            entry,
            axis,
            direction: dir,
            value,
            work,
        } => pb::ProbeWorkflowRequest {
            axis,
            direction: direction(&dir)?,
            value_mm: value,
            ..workflow(K::Edge, entry, work)
        },
        ProbeCmd::Bore { entry, x, y, work } => pb::ProbeWorkflowRequest {
            value_mm: x,
            value2_mm: y,
            ..workflow(K::Bore, entry, work)
        },
    };
    call(j, c.offsets.probe_workflow(req)).await
}

/// The positions at the contact.
impl Render for pb::ProbeReply {
    fn json(&self) -> Value {
        json!({"machine_mm": self.machine_mm})
    }
    fn human(&self) -> String {
        let p: Vec<String> = self.machine_mm.iter().map(|v| format!("{v:.4}")).collect();
        format!("contact at {}", p.join(" "))
    }
}

/// What a workflow found and wrote.
impl Render for pb::ProbeWorkflowReply {
    fn json(&self) -> Value {
        let e = self.entry.clone().unwrap_or_default();
        let written: Vec<Value> = self
            .written
            .iter()
            .map(|w| json!({"axis": w.axis, "machine_mm": w.machine_mm, "length_mm": w.length_mm}))
            .collect();
        json!({"entry": e.entry, "radius_mm": e.radius_mm, "length_mm": e.length_mm,
            "written": written, "diameter_mm": self.diameter_mm})
    }
    fn human(&self) -> String {
        let e = self.entry.clone().unwrap_or_default();
        let mut lines: Vec<String> = self
            .written
            .iter()
            .map(|w| {
                format!(
                    "D{:02} {}: length {:.6} mm written (found at machine {:.4} mm)",
                    e.entry, w.axis, w.length_mm, w.machine_mm
                )
            })
            .collect();
        if self.diameter_mm > 0.0 {
            lines.push(format!("bore: {:.4} mm across", self.diameter_mm));
        }
        lines.join("\n")
    }
}
