//! Command of the Trajectory service: the planned per-tick trajectory without moving the
//! machine, as a total time and optionally a CSV of every tick.

use std::io::Write;
use std::path::Path;

use proto::v1 as pb;
use proto::v1::trajectory_client::TrajectoryClient;
use serde_json::{Value, json};

use crate::call::Reply;
use crate::connect::Svc;
use crate::error::CliError;
use crate::render::{Render, read_text, show};

/// The trajectory of `file` (or of the selected program), with the CSV to `out` when given.
pub async fn command(
    t: &mut TrajectoryClient<Svc>,
    file: Option<&Path>,
    out: Option<&Path>,
    j: bool,
) -> Reply {
    let text = match file {
        Some(f) => read_text(f)?,
        None => String::new(),
    };
    show(j, &trajectory(t, text, out).await?)
}

/// Machining time and tick count.
struct Planned {
    total_s: f64,
    ticks: u64,
}

impl Render for Planned {
    fn json(&self) -> Value {
        json!({"total_s": self.total_s, "ticks": self.ticks})
    }
    fn human(&self) -> String {
        format!(
            "machining time {:.3} s ({} ticks of 4 ms)",
            self.total_s, self.ticks
        )
    }
}

/// Streams the trajectory of `text` (the selected program when empty); writes the CSV to
/// `out` when given.
async fn trajectory(
    t: &mut TrajectoryClient<Svc>,
    text: String,
    out: Option<&Path>,
) -> Result<Planned, CliError> {
    let mut stream = t
        .get_trajectory(pb::TrajectoryRequest { text })
        .await?
        .into_inner();
    let mut csv = match out {
        Some(p) => Some(std::io::BufWriter::new(std::fs::File::create(p).map_err(
            |source| CliError::CsvCreate {
                path: p.to_path_buf(),
                source,
            },
        )?)),
        None => None,
    };
    let mut planned = Planned {
        total_s: 0.0,
        ticks: 0,
    };
    while let Some(chunk) = stream.message().await? {
        planned.ticks += chunk.ticks.len() as u64;
        if let Some(w) = csv.as_mut() {
            write_csv(w, &chunk).map_err(CliError::Csv)?;
        }
        if chunk.last {
            planned.total_s = chunk.total_s;
        }
    }
    if let Some(mut w) = csv {
        w.flush().map_err(CliError::Csv)?;
    }
    Ok(planned)
}

/// One chunk as CSV rows (the header comes with the chunk that names the axes).
fn write_csv(w: &mut impl Write, chunk: &pb::TrajectoryChunk) -> std::io::Result<()> {
    if !chunk.axes.is_empty() {
        let names: Vec<String> = chunk.axes.iter().map(|a| format!("{a}_mm")).collect();
        writeln!(w, "t_s,{},path_v_mm_s,seq,block", names.join(","))?;
    }
    for k in &chunk.ticks {
        let pos: Vec<String> = k.position_mm.iter().map(|p| format!("{p:.6}")).collect();
        let block = k.block.map(|n| n.to_string()).unwrap_or_default();
        writeln!(
            w,
            "{:.3},{},{:.6},{},{block}",
            k.t_s,
            pos.join(","),
            k.path_v_mm_s,
            k.seq
        )?;
    }
    Ok(())
}
