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
    (file, dialect): (Option<&Path>, Option<&str>),
    out: Option<&Path>,
    from_block: Option<u32>,
    j: bool,
) -> Reply {
    let (text, dialect) = match file {
        Some(f) => (read_text(f)?, crate::dialect::for_file(f, dialect)?),
        None => (String::new(), crate::dialect::flag(dialect)?),
    };
    show(j, &trajectory(t, (text, dialect), from_block, out).await?)
}

/// Machining time and tick count; for a restart, the approach.
pub struct Planned {
    pub total_s: f64,
    pub ticks: u64,
    pub approach: Option<Approach>,
}

/// The approach of a restart: the ticks before the first of a programmed block (the legs
/// carry no block number).
#[derive(Default)]
pub struct Approach {
    pub axes: Vec<String>,
    /// Where the approach ends: the start of the restart block.
    pub to_mm: Vec<f64>,
    pub time_s: f64,
    /// The approach ended (a programmed block's tick came).
    done: bool,
}

impl Approach {
    fn tick(&mut self, k: &pb::TrajectoryTick) {
        if self.done || k.block.is_some() {
            self.done = true;
            return;
        }
        self.to_mm = k.position_mm.clone();
        self.time_s = k.t_s;
    }

    pub fn describe(&self) -> String {
        if self.to_mm.is_empty() {
            return "no approach (the axes are at the start of the block)".into();
        }
        let to: Vec<String> = self
            .axes
            .iter()
            .zip(&self.to_mm)
            .map(|(a, v)| format!("{a}{v:.3}"))
            .collect();
        format!(
            "approach to {} in {:.3} s (retract, rapid over, down at feed)",
            to.join(" "),
            self.time_s
        )
    }

    fn json(&self) -> Value {
        json!({"to_mm": self.to_mm, "time_s": self.time_s})
    }
}

impl Render for Planned {
    fn json(&self) -> Value {
        json!({"total_s": self.total_s, "ticks": self.ticks,
            "approach": self.approach.as_ref().map(Approach::json)})
    }
    fn human(&self) -> String {
        let a = self
            .approach
            .as_ref()
            .map(|a| format!("\n{}", a.describe()))
            .unwrap_or_default();
        format!(
            "machining time {:.3} s ({} ticks of 4 ms){a}",
            self.total_s, self.ticks
        )
    }
}

/// Streams the trajectory of `text` (the selected program when empty); writes the CSV to
/// `out` when given.
pub async fn trajectory(
    t: &mut TrajectoryClient<Svc>,
    (text, dialect): (String, String),
    from_block: Option<u32>,
    out: Option<&Path>,
) -> Result<Planned, CliError> {
    let req = pb::TrajectoryRequest {
        text,
        from_block,
        dialect,
    };
    let mut stream = t.get_trajectory(req).await?.into_inner();
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
        approach: from_block.map(|_| Approach::default()),
    };
    while let Some(chunk) = stream.message().await? {
        planned.ticks += chunk.ticks.len() as u64;
        if let Some(a) = planned.approach.as_mut() {
            if !chunk.axes.is_empty() {
                a.axes = chunk.axes.clone();
            }
            for k in &chunk.ticks {
                a.tick(k);
            }
        }
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
