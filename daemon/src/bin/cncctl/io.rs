//! `cncctl io`: the machine's inputs and outputs (docs/io.md): the list, `--watch`, forcing an
//! output, setting a simulated input.

use proto::v1 as pb;
use proto::v1::machine_client::MachineClient;
use serde_json::{Value, json};

use crate::args::IoCmd;
use crate::call::{Reply, call};
use crate::connect::Svc;
use crate::render::{Render, show};

pub async fn command(
    m: &mut MachineClient<Svc>,
    cmd: Option<IoCmd>,
    watch: bool,
    j: bool,
) -> Reply {
    match cmd {
        None | Some(IoCmd::List) if watch => watch_io(m, j).await,
        None | Some(IoCmd::List) => call(j, m.list_io(pb::ListIoRequest {})).await,
        Some(IoCmd::Force { name, value }) => {
            let value = level(&value)?;
            call(j, m.force_output(pb::ForceOutputRequest { name, value })).await
        }
        Some(IoCmd::SimSet { name, value }) => {
            let value = level(&value)?;
            call(j, m.sim_set_input(pb::SimSetInputRequest { name, value })).await
        }
    }
}

/// `0`, `1`, or `release`.
fn level(s: &str) -> Result<Option<bool>, crate::error::CliError> {
    match s {
        "0" | "off" => Ok(Some(false)),
        "1" | "on" => Ok(Some(true)),
        "release" => Ok(None),
        _ => Err(crate::error::CliError::IoLevel(s.to_string())),
    }
}

/// Prints the list from the status stream whenever it changes.
async fn watch_io(m: &mut MachineClient<Svc>, j: bool) -> Reply {
    let mut stream = m
        .stream_status(pb::StatusRequest::default())
        .await?
        .into_inner();
    let mut last: Option<pb::IoList> = None;
    while let Some(s) = stream.message().await? {
        let io = s.io.unwrap_or_default();
        if last.as_ref() != Some(&io) {
            show(j, &io)?;
            last = Some(io);
        }
    }
    Ok(std::process::ExitCode::SUCCESS)
}

impl Render for pb::IoList {
    fn json(&self) -> Value {
        let point = |p: &pb::IoPoint| {
            json!({"name": p.name, "function": p.function, "value": u8::from(p.value),
                "wiring": p.wiring, "forced": p.forced, "waited_for": p.waited_for,
                "wait_timed_out": p.wait_timed_out, "on": p.on, "off": p.off})
        };
        json!({"inputs": self.inputs.iter().map(point).collect::<Vec<_>>(),
            "outputs": self.outputs.iter().map(point).collect::<Vec<_>>(),
            "estop_open": self.estop_open, "door_open": self.door_open,
            "limit_reached": self.limit_reached, "simulated": self.simulated})
    }

    fn human(&self) -> String {
        let mut lines = Vec::new();
        if self.estop_open {
            lines.push("EMERGENCY STOP: the e-stop chain is open".to_string());
        }
        if self.door_open {
            lines.push("the door is open".to_string());
        }
        if self.limit_reached {
            lines.push("a hardware limit switch is reached".to_string());
        }
        lines.push("inputs:".into());
        for p in &self.inputs {
            let mut marks = String::new();
            if p.waited_for {
                marks.push_str(" WAITED FOR");
            }
            if p.wait_timed_out {
                marks.push_str(" TIMED OUT");
            }
            lines.push(format!(
                "  {:<16} {} {:<12} {}{marks}",
                p.name,
                u8::from(p.value),
                p.function,
                p.wiring
            ));
        }
        lines.push("outputs:".into());
        for p in &self.outputs {
            let forced = if p.forced { " FORCED" } else { "" };
            let m = if p.on.is_empty() && p.off.is_empty() {
                String::new()
            } else {
                format!(" on {} off {}", p.on.join(","), p.off.join(","))
            };
            lines.push(format!(
                "  {:<16} {} {:<14} {}{m}{forced}",
                p.name,
                u8::from(p.value),
                p.function,
                p.wiring
            ));
        }
        lines.join("\n")
    }
}
