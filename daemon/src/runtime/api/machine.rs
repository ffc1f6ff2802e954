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
use super::{
    ApiState, DEFAULT_STATUS_HZ, JUNCTION_CLASSIFY_MAX_BLOCKS, MAX_STATUS_HZ, PlanInfo, RunInfo,
    RunMode, Stored, blocking, diagnostic_to_pb, invalid_with_diagnostics, status_of,
};
use crate::runtime::config::Role::{Observer, Operator};
use crate::runtime::controller::LoadedProgram;

/// Largest program text accepted, bytes (the gRPC message limit is 4 MiB by default).
const MAX_STORED_PROGRAMS: usize = 64;

#[derive(Clone)]
pub struct MachineSvc(pub Arc<ApiState>);

type Stream_<T> = Pin<Box<dyn Stream<Item = Result<T, Status>> + Send>>;

impl MachineSvc {
    /// Validates and selects `text` under `name`, then classifies its junctions for status.
    async fn select(&self, name: String, text: Arc<str>) -> Result<pb::LoadProgramReply, Status> {
        let st = self.0.clone();
        let loaded = blocking(move || -> Result<Arc<LoadedProgram>, Status> {
            let loaded = st.ctl.load_program(&name, &text).map_err(status_of)?;
            // Status decoration only: a planner failure (even a panic) must not fail the load.
            let junctions =
                std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| classify(&st, &loaded)))
                    .unwrap_or_default();
            *st.plan_info.lock().unwrap() = Some(PlanInfo {
                program: Arc::as_ptr(&loaded) as *const () as usize,
                junctions,
            });
            Ok(loaded)
        })
        .await??;
        Ok(pb::LoadProgramReply {
            blocks: loaded.block_count,
            diagnostics: loaded.warnings.iter().map(diagnostic_to_pb).collect(),
        })
    }

    fn store(&self, name: &str, text: Arc<str>, blocks: u32) -> Result<(), Status> {
        let mut lib = self.0.library.lock().unwrap();
        if !lib.contains_key(name) && lib.len() >= MAX_STORED_PROGRAMS {
            return Err(Status::resource_exhausted(format!(
                "{MAX_STORED_PROGRAMS} programs are stored; the oldest is not dropped silently"
            )));
        }
        lib.insert(name.to_string(), Stored { text, blocks });
        Ok(())
    }
}

/// Junction class per block index (planning the whole program once); empty for very large
/// programs or when planning fails (status then says UNSPECIFIED).
fn classify(st: &ApiState, p: &LoadedProgram) -> Vec<pb::JunctionClass> {
    if p.block_count as usize > JUNCTION_CLASSIFY_MAX_BLOCKS {
        return Vec::new();
    }
    match super::preview::junctions(&st.ctl, &p.blocks()) {
        Ok(js) => {
            let mut v = vec![pb::JunctionClass::Unspecified; p.block_count as usize];
            for j in js {
                if let Some(slot) = v.get_mut(j.seq as usize) {
                    *slot = j.class();
                }
            }
            v
        }
        Err(_) => Vec::new(),
    }
}

fn check_name(name: &str) -> Result<(), Status> {
    if name.is_empty() || name.len() > 255 || name.chars().any(|c| c.is_control()) {
        return Err(Status::invalid_argument(
            "program name must be 1..255 printable characters",
        ));
    }
    Ok(())
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
        let text: Arc<str> = r.text.into();
        let reply = self.select(name.clone(), text.clone()).await?;
        self.store(&name, text, reply.blocks)?;
        Ok(Response::new(reply))
    }

    async fn validate_program(
        &self,
        req: Request<pb::ValidateProgramRequest>,
    ) -> Result<Response<pb::ValidateProgramReply>, Status> {
        require(&req, Observer, "ValidateProgram")?;
        let text = req.into_inner().text;
        let st = self.0.clone();
        let compiled = blocking(move || st.ctl.compile_text(&text)).await?;
        let valid = !compiled.has_errors();
        Ok(Response::new(pb::ValidateProgramReply {
            valid,
            blocks: compiled.blocks.len() as u32,
            diagnostics: compiled.diagnostics.iter().map(diagnostic_to_pb).collect(),
        }))
    }

    async fn upload_program(
        &self,
        req: Request<pb::LoadProgramRequest>,
    ) -> Result<Response<pb::LoadProgramReply>, Status> {
        require(&req, Operator, "UploadProgram")?;
        let r = req.into_inner();
        check_name(&r.name)?;
        let text: Arc<str> = r.text.into();
        let st = self.0.clone();
        let t = text.clone();
        let compiled = blocking(move || st.ctl.compile_text(&t)).await?;
        if compiled.has_errors() {
            return Err(invalid_with_diagnostics("program", &compiled.diagnostics));
        }
        self.store(&r.name, text, compiled.blocks.len() as u32)?;
        Ok(Response::new(pb::LoadProgramReply {
            blocks: compiled.blocks.len() as u32,
            diagnostics: compiled.diagnostics.iter().map(diagnostic_to_pb).collect(),
        }))
    }

    async fn select_program(
        &self,
        req: Request<pb::SelectProgramRequest>,
    ) -> Result<Response<pb::LoadProgramReply>, Status> {
        require(&req, Operator, "SelectProgram")?;
        let name = req.into_inner().name;
        let text = self
            .0
            .library
            .lock()
            .unwrap()
            .get(&name)
            .map(|s| s.text.clone())
            .ok_or_else(|| Status::not_found(format!("no stored program is called {name:?}")))?;
        Ok(Response::new(self.select(name, text).await?))
    }

    async fn list_programs(
        &self,
        req: Request<pb::ListProgramsRequest>,
    ) -> Result<Response<pb::ListProgramsReply>, Status> {
        require(&req, Observer, "ListPrograms")?;
        let programs = self
            .0
            .library
            .lock()
            .unwrap()
            .iter()
            .map(|(n, s)| pb::StoredProgram {
                name: n.clone(),
                blocks: s.blocks,
                size_bytes: s.text.len() as u64,
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
        let _one_at_a_time = self.0.start_lock.lock().await;
        let st = self.0.clone();
        let job = blocking(move || -> Result<u32, Status> {
            if st.single_block.load(Ordering::Relaxed) {
                // Single block: every block ends at rest so the holds land on block ends.
                let p = st
                    .ctl
                    .program()
                    .ok_or_else(|| Status::failed_precondition("no program is loaded"))?;
                let (job, blocks) = st
                    .ctl
                    .start_text(&p.name, &p.text, true)
                    .map_err(status_of)?;
                *st.run.lock().unwrap() = Some(RunInfo {
                    job,
                    blocks,
                    mode: RunMode::Auto,
                });
                Ok(job)
            } else {
                let job = st.ctl.start_program().map_err(status_of)?;
                *st.run.lock().unwrap() = None;
                Ok(job)
            }
        })
        .await??;
        self.0.wait_started(job).await;
        Ok(Response::new(pb::StartReply { job }))
    }

    async fn stop(&self, req: Request<pb::StopRequest>) -> Result<Response<pb::StopReply>, Status> {
        require(&req, Operator, "Stop")?;
        self.0.ctl.stop().map_err(status_of)?;
        Ok(Response::new(pb::StopReply {}))
    }

    async fn hold(&self, req: Request<pb::HoldRequest>) -> Result<Response<pb::HoldReply>, Status> {
        require(&req, Operator, "Hold")?;
        self.0.ctl.hold().map_err(status_of)?;
        Ok(Response::new(pb::HoldReply {}))
    }

    async fn resume(
        &self,
        req: Request<pb::ResumeRequest>,
    ) -> Result<Response<pb::ResumeReply>, Status> {
        require(&req, Operator, "Resume")?;
        self.0.ctl.resume().map_err(status_of)?;
        Ok(Response::new(pb::ResumeReply {}))
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

    async fn reset(
        &self,
        req: Request<pb::ResetRequest>,
    ) -> Result<Response<pb::ResetReply>, Status> {
        require(&req, Operator, "Reset")?;
        self.0.ctl.reset().map_err(status_of)?;
        Ok(Response::new(pb::ResetReply {}))
    }

    async fn set_single_block(
        &self,
        req: Request<pb::SetSingleBlockRequest>,
    ) -> Result<Response<pb::SetSingleBlockReply>, Status> {
        require(&req, Operator, "SetSingleBlock")?;
        let on = req.into_inner().enabled;
        self.0.ctl.set_single_block(on).map_err(status_of)?;
        self.0.single_block.store(on, Ordering::Relaxed);
        Ok(Response::new(pb::SetSingleBlockReply {}))
    }

    async fn mdi(&self, req: Request<pb::MdiRequest>) -> Result<Response<pb::StartReply>, Status> {
        require(&req, Operator, "Mdi")?;
        let block = req.into_inner().block;
        if block.trim().is_empty() || block.lines().count() > 1 {
            return Err(Status::invalid_argument(
                "MDI takes exactly one block (one line of program text)",
            ));
        }
        let _one_at_a_time = self.0.start_lock.lock().await;
        let st = self.0.clone();
        let job = blocking(move || -> Result<u32, Status> {
            let (job, blocks) = st.ctl.start_text("MDI", &block, false).map_err(status_of)?;
            *st.run.lock().unwrap() = Some(RunInfo {
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
        require(&req, Observer, "StreamStatus")?;
        let hz = match req.into_inner().rate_hz {
            0 => DEFAULT_STATUS_HZ,
            r if r <= MAX_STATUS_HZ => r,
            r => {
                return Err(Status::invalid_argument(format!(
                    "status rate {r} Hz is above the tick rate ({MAX_STATUS_HZ} Hz)"
                )));
            }
        };
        let slot = self.0.stream_slot()?;
        let (tx, rx) = tokio::sync::mpsc::channel(16);
        let st = self.0.clone();
        let watch = st.ctl.subscribe();
        let closing = st.closing();
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
        require(&req, Observer, "StreamAlarms")?;
        let skip_history = req.into_inner().skip_history;
        let slot = self.0.stream_slot()?;
        let (history, mut live) = self.0.alarms.subscribe(!skip_history);
        let (tx, rx) = tokio::sync::mpsc::channel(64);
        let closing = self.0.closing();
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
}
