//! Service `cnc.v1.Machine`: programs, machine control, status and alarm streams.

use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;

use proto::v1 as pb;
use proto::v1::machine_server::Machine;
use tokio_stream::Stream;
use tonic::{Request, Response, Status};

use super::auth::require;
use super::jog;
use ::preview::outline::Outline;
use kernel::pipeline::{self, Flow};
use kernel::plan::Segment;

use super::programs::{check_name, select_stored, store_text};
use super::{
    ApiState, DEFAULT_STATUS_HZ, JUNCTION_CLASSIFY_MAX_BLOCKS, MAX_STATUS_HZ, RunInfo, RunMode,
    blocking, counts_pb, diagnostic_to_pb, dialect_field, status_of,
};
use crate::runtime::config::Role::{Admin, Observer, Operator};
use crate::runtime::controller::{ControlError, Controller};
use kernel::program::Dialect;

/// Largest program run in single-block mode (its blocks are kept in memory), bytes.
const SINGLE_BLOCK_MAX_BYTES: u64 = 16 << 20;

#[derive(Clone)]
pub struct MachineSvc(pub Arc<ApiState>);

type Stream_<T> = Pin<Box<dyn Stream<Item = Result<T, Status>> + Send>>;

impl MachineSvc {
    /// The whole pipeline's verdict on `text` in `dialect` (validate).
    async fn validate(
        &self,
        text: String,
        dialect: Dialect,
    ) -> Result<kernel::pipeline::Validation, Status> {
        let st = self.0.clone();
        blocking(move || st.ctl.validate_text(&text, dialect).map_err(status_of)).await?
    }
}

fn reply_of(done: pb::UploadDone) -> pb::LoadProgramReply {
    pb::LoadProgramReply {
        blocks: done.program.map_or(0, |p| p.blocks),
        diagnostics: done.diagnostics,
        totals: done.totals,
    }
}

/// Junction class per block index, from the validation pass (SPEC §7.5); left empty for very
/// large programs (status then says UNSPECIFIED).
#[derive(Default)]
pub(super) struct Junctions {
    pub(super) classes: Vec<pb::JunctionClass>,
}

impl pipeline::Observer for Junctions {
    fn segment(&mut self, s: &Segment) -> Flow {
        let i = s.seq as usize;
        if i < JUNCTION_CLASSIFY_MAX_BLOCKS {
            if self.classes.len() <= i {
                self.classes.resize(i + 1, pb::JunctionClass::Unspecified);
            }
            self.classes[i] = super::preview::junction_class(s.junction);
        }
        Flow::Go
    }
}

/// A machine command of the operator: the caller's role is checked, the request goes to the
/// controller, and the reply is empty (the controller's refusal is the call's status).
async fn command<Req, Rep: Default>(
    st: &ApiState,
    req: Request<Req>,
    method: &str,
    run: impl FnOnce(&Controller, Req) -> Result<(), ControlError>,
) -> Result<Response<Rep>, Status> {
    require(&req, Operator, method)?;
    run(&st.ctl, req.into_inner()).map_err(status_of)?;
    // The reply says the command is in force: a status read after it shows it.
    st.ctl.wait_commands_taken().await;
    Ok(Response::new(Rep::default()))
}

impl MachineSvc {
    fn io_now(&self) -> pb::IoList {
        let ctl = &self.0.ctl;
        self.0.io.list(&ctl.snapshot(), ctl.simulated())
    }
}

#[tonic::async_trait]
impl Machine for MachineSvc {
    async fn load_program(
        &self,
        req: Request<pb::LoadProgramRequest>,
    ) -> Result<Response<pb::LoadProgramReply>, Status> {
        require(&req, Operator, "LoadProgram")?;
        let r = req.into_inner();
        let name = if r.name.is_empty() {
            "program".to_string()
        } else {
            r.name
        };
        check_name(&name)?;
        let dialect = dialect_field(&r.dialect)?;
        let done = store_text(&self.0, name, r.text, true, dialect).await?;
        Ok(Response::new(reply_of(done)))
    }

    async fn validate_program(
        &self,
        req: Request<pb::ValidateProgramRequest>,
    ) -> Result<Response<pb::ValidateProgramReply>, Status> {
        require(&req, Observer, "ValidateProgram")?;
        let r = req.into_inner();
        let dialect = dialect_field(&r.dialect)?.unwrap_or_else(|| self.0.ctl.default_dialect());
        let text = r.text;
        let v = self.validate(text.clone(), dialect).await?;
        let refined = if v.has_errors() {
            Vec::new()
        } else {
            let st = self.0.clone();
            blocking(move || st.ctl.refinement_listing(&text, dialect).map_err(status_of))
                .await??
                .1
        };
        Ok(Response::new(pb::ValidateProgramReply {
            valid: !v.has_errors(),
            blocks: v.blocks,
            diagnostics: v.diagnostics.iter().map(diagnostic_to_pb).collect(),
            totals: Some(counts_pb(&v.diagnostics)),
            refinements: refined.iter().map(refinement_to_pb).collect(),
        }))
    }

    async fn upload_program(
        &self,
        req: Request<pb::LoadProgramRequest>,
    ) -> Result<Response<pb::LoadProgramReply>, Status> {
        require(&req, Operator, "UploadProgram")?;
        let r = req.into_inner();
        check_name(&r.name)?;
        let dialect = dialect_field(&r.dialect)?;
        let done = store_text(&self.0, r.name, r.text, false, dialect).await?;
        Ok(Response::new(reply_of(done)))
    }

    async fn select_program(
        &self,
        req: Request<pb::SelectProgramRequest>,
    ) -> Result<Response<pb::LoadProgramReply>, Status> {
        require(&req, Operator, "SelectProgram")?;
        let r = req.into_inner();
        let dialect = dialect_field(&r.dialect)?;
        let st = self.0.clone();
        let loaded = blocking(move || select_stored(&st, &r.name, dialect)).await??;
        Ok(Response::new(pb::LoadProgramReply {
            blocks: loaded.block_count,
            diagnostics: loaded.warnings.iter().map(diagnostic_to_pb).collect(),
            totals: Some(counts_pb(&loaded.warnings)),
        }))
    }

    async fn list_programs(
        &self,
        req: Request<pb::ListProgramsRequest>,
    ) -> Result<Response<pb::ListProgramsReply>, Status> {
        require(&req, Observer, "ListPrograms")?;
        let programs = self
            .0
            .library
            .list()
            .iter()
            .map(|e| pb::StoredProgram {
                name: e.name.clone(),
                blocks: e.blocks,
                size_bytes: e.size_bytes,
            })
            .collect();
        Ok(Response::new(pb::ListProgramsReply {
            programs,
            selected: self
                .0
                .ctl
                .program()
                .map(|p| p.name.clone())
                .unwrap_or_default(),
        }))
    }

    async fn start(
        &self,
        req: Request<pb::StartRequest>,
    ) -> Result<Response<pb::StartReply>, Status> {
        require(&req, Operator, "Start")?;
        super::diagnostics::ready_for_motion(self.0.ctl.snapshot().state)?;
        let from_block = req.into_inner().from_block;
        let job = start_job(&self.0, from_block).await?;
        Ok(Response::new(pb::StartReply { job }))
    }

    async fn stop(&self, req: Request<pb::StopRequest>) -> Result<Response<pb::StopReply>, Status> {
        command(&self.0, req, "Stop", |c, _| c.stop()).await
    }

    async fn hold(&self, req: Request<pb::HoldRequest>) -> Result<Response<pb::HoldReply>, Status> {
        command(&self.0, req, "Hold", |c, _| c.hold()).await
    }

    async fn resume(
        &self,
        req: Request<pb::ResumeRequest>,
    ) -> Result<Response<pb::ResumeReply>, Status> {
        command(&self.0, req, "Resume", |c, _| c.resume()).await
    }

    async fn set_override(
        &self,
        req: Request<pb::SetOverrideRequest>,
    ) -> Result<Response<pb::SetOverrideReply>, Status> {
        require(&req, Operator, "SetOverride")?;
        let pct = req.into_inner().percent;
        if !(0.0..=150.0).contains(&pct) {
            return Err(Status::invalid_argument(format!(
                "feed override {pct} % is outside 0..150 %"
            )));
        }
        self.0.ctl.set_override(pct).map_err(status_of)?;
        Ok(Response::new(pb::SetOverrideReply {}))
    }

    async fn set_spindle_override(
        &self,
        req: Request<pb::SetSpindleOverrideRequest>,
    ) -> Result<Response<pb::SetOverrideReply>, Status> {
        command(&self.0, req, "SetSpindleOverride", |c, r| {
            c.set_spindle_override(r.percent)
        })
        .await
    }

    async fn set_rapid_override(
        &self,
        req: Request<pb::SetRapidOverrideRequest>,
    ) -> Result<Response<pb::SetOverrideReply>, Status> {
        command(&self.0, req, "SetRapidOverride", |c, r| {
            c.set_rapid_override(r.percent)
        })
        .await
    }

    async fn reset(
        &self,
        req: Request<pb::ResetRequest>,
    ) -> Result<Response<pb::ResetReply>, Status> {
        command(&self.0, req, "Reset", |c, _| c.reset()).await
    }

    async fn set_single_block(
        &self,
        req: Request<pb::SetSingleBlockRequest>,
    ) -> Result<Response<pb::SetSingleBlockReply>, Status> {
        require(&req, Operator, "SetSingleBlock")?;
        let on = req.into_inner().enabled;
        self.0.ctl.set_single_block(on).map_err(status_of)?;
        self.0.job.single_block.store(on, Ordering::Relaxed);
        Ok(Response::new(pb::SetSingleBlockReply {}))
    }

    async fn set_block_delete(
        &self,
        req: Request<pb::SetBlockDeleteRequest>,
    ) -> Result<Response<pb::SetBlockDeleteReply>, Status> {
        require(&req, Operator, "SetBlockDelete")?;
        self.0.ctl.set_block_delete(req.into_inner().on);
        Ok(Response::new(pb::SetBlockDeleteReply {}))
    }

    async fn set_optional_stop(
        &self,
        req: Request<pb::SetOptionalStopRequest>,
    ) -> Result<Response<pb::SetOptionalStopReply>, Status> {
        command(&self.0, req, "SetOptionalStop", |c, r| {
            c.set_optional_stop(r.on)
        })
        .await
    }

    async fn jog(
        &self,
        req: Request<tonic::Streaming<pb::JogRequest>>,
    ) -> Result<Response<pb::JogReply>, Status> {
        require(&req, Operator, "Jog")?;
        super::diagnostics::ready_for_motion(self.0.ctl.snapshot().state)?;
        let target_mm = jog::streamed(&self.0, req.into_inner()).await?;
        Ok(Response::new(pb::JogReply { target_mm }))
    }

    async fn who_am_i(
        &self,
        req: Request<pb::WhoAmIRequest>,
    ) -> Result<Response<pb::WhoAmIReply>, Status> {
        let caller = require(&req, Observer, "WhoAmI")?;
        Ok(Response::new(pb::WhoAmIReply {
            role: caller.role.name().into(),
            who: caller.who,
        }))
    }

    async fn jog_lease(
        &self,
        req: Request<pb::JogLeaseRequest>,
    ) -> Result<Response<pb::JogReply>, Status> {
        require(&req, Operator, "JogLease")?;
        super::diagnostics::ready_for_motion(self.0.ctl.snapshot().state)?;
        let target_mm = jog::lease(&self.0, req.into_inner())?;
        Ok(Response::new(pb::JogReply { target_mm }))
    }

    async fn jog_stop(
        &self,
        req: Request<pb::JogStopRequest>,
    ) -> Result<Response<pb::JogStopReply>, Status> {
        require(&req, Operator, "JogStop")?;
        jog::stop(&self.0)?;
        Ok(Response::new(pb::JogStopReply {}))
    }

    async fn list_io(
        &self,
        req: Request<pb::ListIoRequest>,
    ) -> Result<Response<pb::IoList>, Status> {
        require(&req, Observer, "ListIo")?;
        Ok(Response::new(self.io_now()))
    }

    async fn force_output(
        &self,
        req: Request<pb::ForceOutputRequest>,
    ) -> Result<Response<pb::IoList>, Status> {
        require(&req, Admin, "ForceOutput")?;
        let r = req.into_inner();
        self.0
            .ctl
            .force_output(&r.name, r.value)
            .map_err(status_of)?;
        self.0.ctl.wait_commands_taken().await;
        Ok(Response::new(self.io_now()))
    }

    async fn sim_set_input(
        &self,
        req: Request<pb::SimSetInputRequest>,
    ) -> Result<Response<pb::IoList>, Status> {
        require(&req, Admin, "SimSetInput")?;
        let r = req.into_inner();
        self.0
            .ctl
            .sim_set_input(&r.name, r.value)
            .map_err(status_of)?;
        // The bus reads it in its next cycle: answer with the tick after that.
        self.0.ctl.wait_ticks(2).await;
        Ok(Response::new(self.io_now()))
    }

    async fn home(&self, req: Request<pb::HomeRequest>) -> Result<Response<pb::HomeReply>, Status> {
        require(&req, Operator, "Home")?;
        super::diagnostics::ready_for_motion(self.0.ctl.snapshot().state)?;
        let axes = req.into_inner().axes;
        let homed = self.0.ctl.home(&axes).await.map_err(status_of)?;
        Ok(Response::new(pb::HomeReply { homed }))
    }

    async fn probe(
        &self,
        req: Request<pb::ProbeRequest>,
    ) -> Result<Response<pb::ProbeReply>, Status> {
        require(&req, Operator, "Probe")?;
        super::diagnostics::ready_for_motion(self.0.ctl.snapshot().state)?;
        let reply = super::probe::probe(&self.0, req.into_inner()).await?;
        Ok(Response::new(reply))
    }

    async fn jog_step(
        &self,
        req: Request<pb::JogStepRequest>,
    ) -> Result<Response<pb::JogReply>, Status> {
        require(&req, Operator, "JogStep")?;
        super::diagnostics::ready_for_motion(self.0.ctl.snapshot().state)?;
        let target_mm = jog::step(&self.0, req.into_inner())?;
        self.0.ctl.wait_commands_taken().await;
        Ok(Response::new(pb::JogReply { target_mm }))
    }

    async fn mdi(&self, req: Request<pb::MdiRequest>) -> Result<Response<pb::StartReply>, Status> {
        require(&req, Operator, "Mdi")?;
        super::diagnostics::ready_for_motion(self.0.ctl.snapshot().state)?;
        let r = req.into_inner();
        let dialect = dialect_field(&r.dialect)?.unwrap_or_else(|| self.0.ctl.default_dialect());
        let block = r.block;
        if block.trim().is_empty() || block.lines().count() > 1 {
            return Err(Status::invalid_argument(
                "MDI takes exactly one block (one line of program text)",
            ));
        }
        let _one_at_a_time = self.0.job.start_lock.lock().await;
        let st = self.0.clone();
        let job = blocking(move || -> Result<u32, Status> {
            let (job, blocks) = st
                .ctl
                .start_text("MDI", &block, dialect, false, true)
                .map_err(status_of)?;
            *st.job.run.lock().unwrap() = Some(RunInfo {
                job,
                blocks,
                mode: RunMode::Mdi,
            });
            Ok(job)
        })
        .await??;
        self.0.wait_started(job).await;
        Ok(Response::new(pb::StartReply { job }))
    }

    type StreamStatusStream = Stream_<pb::Status>;

    async fn stream_status(
        &self,
        req: Request<pb::StatusRequest>,
    ) -> Result<Response<Self::StreamStatusStream>, Status> {
        let caller = require(&req, Observer, "StreamStatus")?;
        let hz = match req.into_inner().rate_hz {
            0 => DEFAULT_STATUS_HZ,
            r if r <= MAX_STATUS_HZ => r,
            r => {
                return Err(Status::invalid_argument(format!(
                    "status rate {r} Hz is above the tick rate ({MAX_STATUS_HZ} Hz)"
                )));
            }
        };
        let slot = self.0.streams.slot(caller.role)?;
        let (tx, rx) = tokio::sync::mpsc::channel(16);
        let st = self.0.clone();
        let watch = st.ctl.subscribe();
        let closing = st.streams.closing();
        tokio::spawn(async move {
            let _slot = slot;
            let mut every = tokio::time::interval(Duration::from_secs_f64(1.0 / hz as f64));
            // Stay on the rate's grid: a late wake-up does not shift later messages, and
            // missed slots are skipped rather than sent as a burst of the same snapshot.
            every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
            tokio::pin!(closing);
            loop {
                tokio::select! {
                    _ = every.tick() => {}
                    _ = tx.closed() => break,
                    _ = &mut closing => {
                        // Shutdown: the last status (axes at rest), then the end of the stream.
                        let snap = *watch.borrow();
                        let _ = tx.try_send(Ok(st.status(&snap)));
                        break;
                    }
                }
                let snap = *watch.borrow();
                let msg = st.status(&snap);
                if tx.send(Ok(msg)).await.is_err() {
                    break; // client went away
                }
            }
        });
        Ok(Response::new(Box::pin(
            tokio_stream::wrappers::ReceiverStream::new(rx),
        )))
    }

    type StreamAlarmsStream = Stream_<pb::AlarmEvent>;

    async fn stream_alarms(
        &self,
        req: Request<pb::StreamAlarmsRequest>,
    ) -> Result<Response<Self::StreamAlarmsStream>, Status> {
        let caller = require(&req, Observer, "StreamAlarms")?;
        let skip_history = req.into_inner().skip_history;
        let slot = self.0.streams.slot(caller.role)?;
        let (history, mut live) = self.0.alarms.subscribe(!skip_history);
        let (tx, rx) = tokio::sync::mpsc::channel(64);
        let closing = self.0.streams.closing();
        tokio::spawn(async move {
            let _slot = slot;
            tokio::pin!(closing);
            for e in history {
                if tx.send(Ok(e)).await.is_err() {
                    return;
                }
            }
            loop {
                let e = tokio::select! {
                    e = live.recv() => e,
                    _ = tx.closed() => return,
                    _ = &mut closing => return,
                };
                match e {
                    Ok(e) => {
                        if tx.send(Ok(e)).await.is_err() {
                            return;
                        }
                    }
                    Err(tokio::sync::broadcast::error::RecvError::Lagged(n)) => {
                        let _ = tx
                            .send(Err(Status::data_loss(format!(
                                "{n} alarm events were dropped: the client reads too slowly"
                            ))))
                            .await;
                        return;
                    }
                    Err(tokio::sync::broadcast::error::RecvError::Closed) => return,
                }
            }
        });
        Ok(Response::new(Box::pin(
            tokio_stream::wrappers::ReceiverStream::new(rx),
        )))
    }

    async fn get_refined_program(
        &self,
        req: Request<pb::RefinedProgramRequest>,
    ) -> Result<Response<pb::RefinedProgramReply>, Status> {
        require(&req, Observer, "GetRefinedProgram")?;
        let r = req.into_inner();
        let st = self.0.clone();
        let (text, dialect) = super::text_or_selected(&st.ctl, r.text, &r.dialect)?;
        let (listing, refined, diags) =
            blocking(move || st.ctl.refinement_listing(&text, dialect).map_err(status_of))
                .await??;
        Ok(Response::new(pb::RefinedProgramReply {
            text: listing,
            refinements: refined.iter().map(refinement_to_pb).collect(),
            diagnostics: diags.iter().map(diagnostic_to_pb).collect(),
        }))
    }
}

/// One R325 refinement for the API (SPEC §4.6).
fn refinement_to_pb(r: &kernel::program::arc::Refined) -> pb::Refinement {
    use kernel::program::arc::Corrected;
    pb::Refinement {
        seq: r.seq,
        block: r.n,
        line: r.line,
        coordinate: if r.refinement.which == Corrected::I {
            "I"
        } else {
            "J"
        }
        .into(),
        delta_mm: r.refinement.delta_mm,
        e_word: r
            .word
            .map(|w| format!("E{:.3}", w.encode()))
            .unwrap_or_default(),
    }
}

/// Start (or continue a held job), as the Start call and the cycle start button do: the
/// selected program from its start or from block `from_block`.
pub(super) async fn start_job(
    state: &Arc<ApiState>,
    from_block: Option<u32>,
) -> Result<u32, Status> {
    let _one_at_a_time = state.job.start_lock.lock().await;
    // Start on a held machine (feed hold, M0/M1) continues the job.
    if from_block.is_none()
        && let Some(job) = state.ctl.start_resumes().map_err(status_of)?
    {
        state.ctl.wait_commands_taken().await;
        return Ok(job);
    }
    let st = state.clone();
    let job = blocking(move || -> Result<u32, Status> {
        if st.job.single_block.load(Ordering::Relaxed) {
            // Single block: every block ends at rest so the holds land on block ends
            // (a restart's approach holds at its end too).
            let p = st
                .ctl
                .program()
                .ok_or_else(|| Status::failed_precondition("no program is loaded"))?;
            // Single block keeps every block in memory (the holds need them).
            if p.text.len() > SINGLE_BLOCK_MAX_BYTES {
                return Err(Status::failed_precondition(format!(
                    "single-block runs keep the whole program in memory: programs over \
                         {} MiB run only continuously",
                    SINGLE_BLOCK_MAX_BYTES >> 20
                )));
            }
            let text = p
                .text
                .read_all(st.ctl.program_encoding())
                .map_err(|e| Status::internal(e.to_string()))?;
            // The job's pass (every block ends at rest) is what the preview shows.
            let outline = Outline::new(&st.ctl.config().axis_names());
            let (job, blocks, outline) = st
                .ctl
                .start_program_blocks(&p, &text, from_block, outline)
                .map_err(status_of)?;
            super::preview_outline::job_started(&st, job, Some(outline));
            *st.job.run.lock().unwrap() = Some(RunInfo {
                job,
                blocks,
                mode: RunMode::Auto,
            });
            Ok(job)
        } else {
            // A job that validates again (setup changed, restart): its pass is what
            // the preview shows while it runs.
            let outline = Outline::new(&st.ctl.config().axis_names());
            let (job, pass) = st
                .ctl
                .start_program_observed(from_block, outline)
                .map_err(status_of)?;
            super::preview_outline::job_started(&st, job, pass);
            *st.job.run.lock().unwrap() = None;
            Ok(job)
        }
    })
    .await??;
    state.wait_started(job).await;
    Ok(job)
}
