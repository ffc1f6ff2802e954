//! Service `cnc.v1.Trajectory`: the planned per-tick trajectory of a program without moving
//! the machine (issue #16). The program goes through the stages a run uses (interpret →
//! compensate → plan with the machine's settings → the 4 ms interpolator), in virtual time
//! at 100 % override, program stops (M0, M6 of ISO programs) resumed at once; every tick's
//! setpoints and path speed are streamed in chunks.

use std::sync::Arc;

use proto::v1 as pb;
use proto::v1::trajectory_server::Trajectory;
use tokio::sync::mpsc;
use tonic::{Request, Response, Status};

use kernel::Diagnostic;
use kernel::TS_S;
use kernel::interp::{InterpState, Interpolator};
use kernel::machine::MachineSetup;
use kernel::pipeline::{self, Flow, Options};
use kernel::plan::Segment;

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
        let r = req.into_inner();
        let (text, opts) = (
            r.text.clone(),
            Options {
                from_block: r.from_block,
                ..Options::default()
            },
        );
        let ctl = self.0.ctl.clone();
        let origin = super::restart_origin(&ctl, &text, opts.from_block);
        let (text, dialect) = super::text_or_selected(&ctl, text, &r.dialect)?;
        // The job's machine setup and the one pipeline a run uses (issue #14): the verdict is
        // validation's, the segments are the run's.
        let setup = ctl
            .machine_setup_in(dialect)
            .map_err(super::status_of)?
            .with_restart_origin(origin);
        let v = pipeline::validate(&text, &setup, opts);
        if v.has_errors() {
            return Err(invalid_with_diagnostics("program", &v.diagnostics));
        }
        let axes: Vec<String> = ctl
            .config()
            .axes
            .iter()
            .map(|a| a.name.to_string())
            .collect();
        let (tx, rx) = mpsc::channel(4);
        tokio::task::spawn_blocking(move || {
            let send = |c: Result<pb::TrajectoryChunk, Status>| tx.blocking_send(c).is_ok();
            if let Err(e) = run(&text, &setup, opts, axes, send) {
                let _ = tx.blocking_send(Err(e));
            }
        });
        Ok(Response::new(Box::pin(
            tokio_stream::wrappers::ReceiverStream::new(rx),
        )))
    }
}

/// Runs `text` through the pipeline and the 4 ms interpolator from the setup's start, handing
/// chunks of ticks to `send` (which returns false when the client has gone). Segments go to
/// the interpolator as it has room, as the daemon's planner thread feeds the RT thread.
fn run(
    text: &str,
    setup: &MachineSetup,
    opts: Options,
    axes: Vec<String>,
    send: impl FnMut(Result<pb::TrajectoryChunk, Status>) -> bool,
) -> Result<(), Status> {
    let n_axes = setup.planner().axes;
    let mut ip = Interpolator::new(n_axes, setup.program().start);
    ip.set_in_position(true);
    ip.set_spindle_ready(true);
    let mut t = Ticker {
        ip,
        n_axes,
        tick: 0,
        chunk: pb::TrajectoryChunk {
            axes,
            ..Default::default()
        },
        send,
        outcome: Ok(true),
    };
    pipeline::run(text, setup, opts, &mut t);
    if !std::mem::replace(&mut t.outcome, Ok(true))? {
        return Ok(()); // the client has gone
    }
    while t.ip.state() != InterpState::Idle {
        if !t.tick()? {
            return Ok(());
        }
    }
    t.chunk.last = true;
    t.chunk.total_s = t.tick as f64 * TS_S;
    let last = std::mem::take(&mut t.chunk);
    (t.send)(Ok(last));
    Ok(())
}

/// The pipeline's observer: each segment into the interpolator, ticking while it is full.
struct Ticker<F> {
    ip: Interpolator,
    n_axes: usize,
    tick: u64,
    chunk: pb::TrajectoryChunk,
    send: F,
    /// `Ok(false)`: the client has gone; `Err`: the pass failed.
    outcome: Result<bool, Status>,
}

impl<F: FnMut(Result<pb::TrajectoryChunk, Status>) -> bool> Ticker<F> {
    /// One interpolator tick into the chunk. False when the client has gone.
    fn tick(&mut self) -> Result<bool, Status> {
        // A program stop (M0, the ISO dialect's M6) is resumed at once: the trajectory is the
        // machining, not the operator's time (the tick at rest is still counted).
        if self.ip.at_program_stop() {
            self.ip.resume();
        }
        let out = self.ip.tick();
        self.tick += 1;
        self.chunk.ticks.push(pb::TrajectoryTick {
            t_s: self.tick as f64 * TS_S,
            position_mm: out.position.0[..self.n_axes].to_vec(),
            path_v_mm_s: out.path_v_mm_s,
            seq: out.seq,
            block: out.n,
        });
        if self.chunk.ticks.len() >= CHUNK_TICKS
            && !(self.send)(Ok(std::mem::take(&mut self.chunk)))
        {
            return Ok(false);
        }
        if self.tick >= MAX_TICKS {
            return Err(Status::invalid_argument(
                "the program runs longer than 24 hours of machining",
            ));
        }
        Ok(true)
    }
}

impl<F: FnMut(Result<pb::TrajectoryChunk, Status>) -> bool> pipeline::Observer for Ticker<F> {
    fn segment(&mut self, s: &Segment) -> Flow {
        let mut seg = *s;
        loop {
            match self.ip.push(seg) {
                Ok(()) => return Flow::Go,
                Err(back) => seg = back,
            }
            match self.tick() {
                Ok(true) => {}
                other => {
                    self.outcome = other;
                    return Flow::Stop;
                }
            }
        }
    }

    fn diagnostic(&mut self, d: Diagnostic) -> Flow {
        if d.is_error() {
            self.outcome = Err(invalid_with_diagnostics("program", &[d]));
            return Flow::Stop;
        }
        Flow::Go
    }
}
