//! Service `cnc.v1.Trajectory`: the planned per-tick trajectory of a program without moving
//! the machine (issue #16). The program goes through the stages a run uses (interpret →
//! compensate → plan with the machine's settings → the 4 ms interpolator), in virtual time
//! at 100 % override; every tick's setpoints and path speed are streamed in chunks.

use std::sync::Arc;

use proto::v1 as pb;
use proto::v1::trajectory_server::Trajectory;
use tokio::sync::mpsc;
use tonic::{Request, Response, Status};

use kernel::block::Block;
use kernel::comp::compensate_all;
use kernel::interp::{InterpState, Interpolator};
use kernel::plan::{Planner, PlannerConfig, Segment};
use kernel::{AxesMm, TS_S};

use super::auth::require;
use super::{ApiState, invalid_with_diagnostics};
use crate::runtime::config::Role::Observer;

/// Ticks per streamed chunk.
const CHUNK_TICKS: usize = 2000;

/// Longest trajectory, ticks (24 h of machining): a bound for a program that never ends.
const MAX_TICKS: u64 = 24 * 3600 * 250;

#[derive(Clone)]
pub struct TrajectorySvc(pub Arc<ApiState>);

type Chunks =
    std::pin::Pin<Box<dyn tokio_stream::Stream<Item = Result<pb::TrajectoryChunk, Status>> + Send>>;

#[tonic::async_trait]
impl Trajectory for TrajectorySvc {
    type GetTrajectoryStream = Chunks;

    async fn get_trajectory(
        &self,
        req: Request<pb::TrajectoryRequest>,
    ) -> Result<Response<Chunks>, Status> {
        require(&req, Observer, "GetTrajectory")?;
        let text = req.into_inner().text;
        let ctl = self.0.ctl.clone();
        let text = if text.is_empty() {
            let p = ctl.program().ok_or_else(|| {
                Status::failed_precondition("no program is selected and no text was given")
            })?;
            p.text.to_string()
        } else {
            text
        };
        let compiled = ctl.compile_text(&text);
        if compiled.has_errors() {
            return Err(invalid_with_diagnostics("program", &compiled.diagnostics));
        }
        let (comp_cfg, plan_cfg) = ctl.run_configs();
        let (blocks, _) = compensate_all(&compiled.blocks, &comp_cfg);
        let axes: Vec<String> = ctl
            .config()
            .axes
            .iter()
            .map(|a| a.name.to_string())
            .collect();
        let start = ctl.snapshot().commanded;
        let (tx, rx) = mpsc::channel(4);
        tokio::task::spawn_blocking(move || {
            let send = |c: Result<pb::TrajectoryChunk, Status>| tx.blocking_send(c).is_ok();
            if let Err(e) = run(&blocks, plan_cfg, start, axes, send) {
                let _ = tx.blocking_send(Err(e));
            }
        });
        Ok(Response::new(Box::pin(
            tokio_stream::wrappers::ReceiverStream::new(rx),
        )))
    }
}

/// Plans and interpolates `blocks` from `start`, handing chunks of ticks to `send` (which
/// returns false when the client has gone). The planner runs ahead of the interpolator until
/// its buffer is full, as the daemon's planner thread does.
fn run(
    blocks: &[Block],
    cfg: PlannerConfig,
    start: AxesMm,
    axes: Vec<String>,
    mut send: impl FnMut(Result<pb::TrajectoryChunk, Status>) -> bool,
) -> Result<(), Status> {
    let n_axes = cfg.axes;
    let mut planner = Planner::new(cfg, 0);
    let mut ip = Interpolator::new(n_axes, start);
    ip.set_in_position(true);
    ip.set_spindle_ready(true);
    let mut next = 0usize;
    let mut held: Option<Segment> = None;
    let mut chunk = pb::TrajectoryChunk {
        axes,
        ..Default::default()
    };
    let mut tick = 0u64;
    loop {
        // Feed: the planner takes blocks while it wants them, its segments go to the
        // interpolator while it has room.
        loop {
            while planner.wants_input() && next < blocks.len() {
                planner
                    .push(&blocks[next])
                    .map_err(|d| invalid_with_diagnostics("program", &[d]))?;
                next += 1;
            }
            if next == blocks.len() {
                planner.finish();
            }
            let seg = match held.take().or_else(|| planner.poll()) {
                Some(s) => s,
                None => break,
            };
            if let Err(s) = ip.push(seg) {
                held = Some(s);
                break;
            }
        }
        if planner.is_done() && held.is_none() && ip.state() == InterpState::Idle {
            break;
        }
        let out = ip.tick();
        tick += 1;
        chunk.ticks.push(pb::TrajectoryTick {
            t_s: tick as f64 * TS_S,
            position_mm: out.position.0[..n_axes].to_vec(),
            path_v_mm_s: out.path_v_mm_s,
            seq: out.seq,
            block: out.n,
        });
        if chunk.ticks.len() >= CHUNK_TICKS && !send(Ok(std::mem::take(&mut chunk))) {
            return Ok(());
        }
        if tick >= MAX_TICKS {
            return Err(Status::invalid_argument(
                "the program runs longer than 24 hours of machining",
            ));
        }
    }
    chunk.last = true;
    chunk.total_s = tick as f64 * TS_S;
    send(Ok(chunk));
    Ok(())
}
