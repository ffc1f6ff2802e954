//! The gRPC service (`cnc.v1.Machine`) over the [`Controller`].

use std::pin::Pin;
use std::sync::Arc;
use std::time::Duration;

use prost::Message;
use proto::v1 as pb;
use proto::v1::machine_server::{Machine, MachineServer};
use tokio_stream::Stream;
use tonic::{Code, Request, Response, Status};

use kernel::{Diagnostic, Severity};

use super::controller::{ControlError, Controller};
use super::rt::{MachineState, Snapshot};

/// Highest status stream rate: one snapshot per tick.
pub const MAX_STATUS_HZ: u32 = 250;
const DEFAULT_STATUS_HZ: u32 = 25;

pub struct Api {
    ctl: Arc<Controller>,
}

impl Api {
    pub fn new(ctl: Arc<Controller>) -> Self {
        Api { ctl }
    }

    pub fn into_service(self) -> MachineServer<Api> {
        MachineServer::new(self)
    }
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
    }
}

/// Maps controller errors to gRPC statuses. A bad program is INVALID_ARGUMENT whose message
/// lists the errors and whose details carry them as a `cnc.v1.Diagnostics` message.
fn status_of(e: ControlError) -> Status {
    match e {
        ControlError::InvalidProgram(diags) => {
            let errors: Vec<&Diagnostic> = diags.iter().filter(|d| d.is_error()).collect();
            let mut msg = format!("program rejected, {} error(s): ", errors.len());
            for (i, d) in errors.iter().take(5).enumerate() {
                if i > 0 {
                    msg.push_str("; ");
                }
                msg.push_str(&d.to_string());
            }
            let details = pb::Diagnostics {
                items: diags.iter().map(diagnostic_to_pb).collect(),
            }
            .encode_to_vec();
            Status::with_details(Code::InvalidArgument, msg, details.into())
        }
        ControlError::WrongState(m) => Status::failed_precondition(m),
        ControlError::RtGone => Status::unavailable("the real-time thread has stopped"),
        ControlError::Storage(e) => match e {
            super::storage::StorageError::Invalid { .. } => Status::invalid_argument(e.to_string()),
            _ => Status::internal(e.to_string()),
        },
        ControlError::Plc(e) => Status::invalid_argument(e.to_string()),
        ControlError::Invalid(m) => Status::invalid_argument(m),
    }
}

fn state_to_pb(s: MachineState) -> pb::MachineState {
    match s {
        MachineState::Enabling => pb::MachineState::Enabling,
        MachineState::Idle => pb::MachineState::Idle,
        MachineState::Running => pb::MachineState::Running,
        MachineState::Stopping => pb::MachineState::Stopping,
        MachineState::Hold => pb::MachineState::Hold,
        MachineState::Fault => pb::MachineState::Fault,
        MachineState::Shutdown => pb::MachineState::Shutdown,
    }
}

/// Builds the API status message from a snapshot.
pub fn status_to_pb(ctl: &Controller, s: &Snapshot) -> pb::Status {
    let program = ctl.program();
    let total = program.as_ref().map_or(0, |p| p.blocks.len() as u32);
    let running = matches!(
        s.state,
        MachineState::Running | MachineState::Hold | MachineState::Stopping
    );
    let percent = if s.finished_job == s.job && s.job != 0 && !running {
        100.0
    } else if total > 0 && s.job != 0 {
        (s.block_seq as f64 / total as f64 * 100.0).min(100.0)
    } else {
        0.0
    };
    let names = ctl.config().axis_names();
    let axes = (0..s.axes)
        .map(|i| pb::AxisStatus {
            name: names.get(i).map(|c| c.to_string()).unwrap_or_default(),
            commanded_mm: s.commanded[i],
            actual_mm: s.actual[i],
            following_error_mm: s.commanded[i] - s.actual[i],
        })
        .collect();
    let alarm = match (s.fault, ctl.alarm()) {
        (Some(f), _) => {
            let axis = f
                .axis
                .and_then(|a| names.get(a as usize))
                .map(|c| format!("axis {c}, "))
                .unwrap_or_default();
            let node = f.node.map(|n| format!("node {n}, ")).unwrap_or_default();
            format!("{axis}{node}{}", f.reason)
        }
        (None, Some(a)) => a,
        (None, None) => String::new(),
    };
    pb::Status {
        state: state_to_pb(s.state) as i32,
        program: program.map(|p| p.name.clone()).unwrap_or_default(),
        block: s.block_n,
        line: s.line,
        block_index: s.block_seq,
        blocks_total: total,
        percent,
        axes,
        path_velocity_mm_s: s.path_v_mm_s,
        ticks: Some(pb::TickStats {
            ticks: s.ticks.ticks,
            overruns: s.ticks.overruns,
            lateness_p50_us: s.ticks.lateness_p50_us,
            lateness_p99_us: s.ticks.lateness_p99_us,
            lateness_max_us: s.ticks.lateness_max_us,
        }),
        sequence: s.sequence,
        job: s.job,
        alarm,
        finished_job: s.finished_job,
        aborted_job: s.aborted_job,
        override_percent: s.override_pct,
        spindle_rpm: s.spindle_rpm,
    }
}

type StatusStream = Pin<Box<dyn Stream<Item = Result<pb::Status, Status>> + Send>>;

#[tonic::async_trait]
impl Machine for Api {
    async fn load_program(
        &self,
        req: Request<pb::LoadProgramRequest>,
    ) -> Result<Response<pb::LoadProgramReply>, Status> {
        let r = req.into_inner();
        let ctl = self.ctl.clone();
        // Parsing a large program is CPU work: keep it off the async workers.
        let loaded = tokio::task::spawn_blocking(move || ctl.load_program(&r.name, &r.text))
            .await
            .map_err(|e| Status::internal(e.to_string()))?
            .map_err(status_of)?;
        Ok(Response::new(pb::LoadProgramReply {
            blocks: loaded.blocks.len() as u32,
            diagnostics: loaded.warnings.iter().map(diagnostic_to_pb).collect(),
        }))
    }

    async fn start(
        &self,
        _req: Request<pb::StartRequest>,
    ) -> Result<Response<pb::StartReply>, Status> {
        let ctl = self.ctl.clone();
        let job = tokio::task::spawn_blocking(move || ctl.start_program())
            .await
            .map_err(|e| Status::internal(e.to_string()))?
            .map_err(status_of)?;
        Ok(Response::new(pb::StartReply { job }))
    }

    async fn stop(
        &self,
        _req: Request<pb::StopRequest>,
    ) -> Result<Response<pb::StopReply>, Status> {
        self.ctl.stop().map_err(status_of)?;
        Ok(Response::new(pb::StopReply {}))
    }

    async fn hold(
        &self,
        _req: Request<pb::HoldRequest>,
    ) -> Result<Response<pb::HoldReply>, Status> {
        self.ctl.hold().map_err(status_of)?;
        Ok(Response::new(pb::HoldReply {}))
    }

    async fn resume(
        &self,
        _req: Request<pb::ResumeRequest>,
    ) -> Result<Response<pb::ResumeReply>, Status> {
        self.ctl.resume().map_err(status_of)?;
        Ok(Response::new(pb::ResumeReply {}))
    }

    async fn set_override(
        &self,
        req: Request<pb::SetOverrideRequest>,
    ) -> Result<Response<pb::SetOverrideReply>, Status> {
        let pct = req.into_inner().percent;
        if !(0.0..=150.0).contains(&pct) {
            return Err(Status::invalid_argument(format!(
                "feed override {pct} % is outside 0..150 %"
            )));
        }
        self.ctl.set_override(pct).map_err(status_of)?;
        Ok(Response::new(pb::SetOverrideReply {}))
    }

    async fn reset(
        &self,
        _req: Request<pb::ResetRequest>,
    ) -> Result<Response<pb::ResetReply>, Status> {
        self.ctl.reset().map_err(status_of)?;
        Ok(Response::new(pb::ResetReply {}))
    }

    type StreamStatusStream = StatusStream;

    async fn stream_status(
        &self,
        req: Request<pb::StatusRequest>,
    ) -> Result<Response<Self::StreamStatusStream>, Status> {
        let hz = match req.into_inner().rate_hz {
            0 => DEFAULT_STATUS_HZ,
            r if r <= MAX_STATUS_HZ => r,
            r => {
                return Err(Status::invalid_argument(format!(
                    "status rate {r} Hz is above the tick rate ({MAX_STATUS_HZ} Hz)"
                )));
            }
        };
        let (tx, rx) = tokio::sync::mpsc::channel(16);
        let ctl = self.ctl.clone();
        let watch = ctl.subscribe();
        tokio::spawn(async move {
            let mut every = tokio::time::interval(Duration::from_secs_f64(1.0 / hz as f64));
            every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
            loop {
                every.tick().await;
                let snap = *watch.borrow();
                let msg = status_to_pb(&ctl, &snap);
                if tx.send(Ok(msg)).await.is_err() {
                    break; // client went away
                }
            }
        });
        Ok(Response::new(Box::pin(
            tokio_stream::wrappers::ReceiverStream::new(rx),
        )))
    }
}
