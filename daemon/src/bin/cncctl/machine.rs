//! Commands of the Machine service: motion control, overrides, jog, homing, MDI, status,
//! alarms, and the program checks that need the machine's settings (validate, refine).

use std::path::Path;
use std::process::ExitCode;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressStyle};
use proto::v1 as pb;
use proto::v1::machine_client::MachineClient;
use serde_json::{Value, json};

use crate::args::Cmd;
use crate::call::{Reply, call, call_as, call_done};
use crate::connect::Svc;
use crate::dialect;
use crate::error::CliError;
use crate::render::{
    Render, block_name, diags_json, emit, local_time, print_line, read_text, show,
};
use crate::status::{alarm_json, dro, status_json, status_line};

/// Runs one Machine command (main routes only these here).
pub async fn command(m: &mut MachineClient<Svc>, cmd: Cmd, j: bool) -> Reply {
    match cmd {
        Cmd::Refine { file, dialect } => {
            let dialect = dialect::for_file(&file, dialect.as_deref())?;
            refine(m, &file, dialect, j).await
        }
        Cmd::Select { name, dialect } => {
            let dialect = dialect::flag(dialect.as_deref())?;
            let req = pb::SelectProgramRequest {
                name: name.clone(),
                dialect,
            };
            let answer = m.select_program(req);
            call_as(j, answer, |r| Selected {
                name,
                blocks: r.blocks,
            })
            .await
        }
        Cmd::Start { .. } => {
            let answer = m.start(pb::StartRequest::default());
            call_as(j, answer, |r| Started {
                job: r.job,
                mdi: false,
            })
            .await
        }
        Cmd::Mdi { block, dialect } => {
            let dialect = dialect::flag(dialect.as_deref())?;
            let answer = m.mdi(pb::MdiRequest { block, dialect });
            call_as(j, answer, |r| Started {
                job: r.job,
                mdi: true,
            })
            .await
        }
        Cmd::Home { axes } => call(j, m.home(pb::HomeRequest { axes })).await,
        Cmd::Jog { axis, speed, step } => jog(m, j, &axis, speed, step).await,
        Cmd::Status { watch, rate } => status(m, watch, rate, j).await,
        Cmd::Alarms { follow } => alarms(m, follow, j).await,
        other => control(m, other, j).await,
    }
}

/// The commands that answer nothing but success.
async fn control(m: &mut MachineClient<Svc>, cmd: Cmd, j: bool) -> Reply {
    match cmd {
        Cmd::Stop => call_done(j, m.stop(pb::StopRequest {})).await,
        Cmd::Hold => call_done(j, m.hold(pb::HoldRequest {})).await,
        Cmd::Resume => call_done(j, m.resume(pb::ResumeRequest {})).await,
        Cmd::Reset => call_done(j, m.reset(pb::ResetRequest {})).await,
        Cmd::Override { percent } => {
            call_done(j, m.set_override(pb::SetOverrideRequest { percent })).await
        }
        Cmd::SpindleOverride { percent } => {
            let req = pb::SetSpindleOverrideRequest { percent };
            call_done(j, m.set_spindle_override(req)).await
        }
        Cmd::RapidOverride { percent } => {
            let req = pb::SetRapidOverrideRequest { percent };
            call_done(j, m.set_rapid_override(req)).await
        }
        Cmd::SingleBlock { mode } => {
            let req = pb::SetSingleBlockRequest {
                enabled: mode == "on",
            };
            call_done(j, m.set_single_block(req)).await
        }
        Cmd::OptionalStop { mode } => {
            let req = pb::SetOptionalStopRequest { on: mode == "on" };
            call_done(j, m.set_optional_stop(req)).await
        }
        Cmd::BlockDelete { mode } => {
            let req = pb::SetBlockDeleteRequest { on: mode == "on" };
            call_done(j, m.set_block_delete(req)).await
        }
        _ => unreachable!("main routes only Machine service commands here"),
    }
}

struct Selected {
    name: String,
    blocks: u32,
}

impl Render for Selected {
    fn json(&self) -> Value {
        json!({"name": self.name, "blocks": self.blocks})
    }
    fn human(&self) -> String {
        format!("selected {} ({} blocks)", self.name, self.blocks)
    }
}

/// A job started by `start` or `mdi`.
pub struct Started {
    pub job: u32,
    pub mdi: bool,
}

impl Render for Started {
    fn json(&self) -> Value {
        json!({"job": self.job})
    }
    fn human(&self) -> String {
        if self.mdi {
            format!("MDI job {} started", self.job)
        } else {
            format!("started job {}", self.job)
        }
    }
}

impl Render for pb::HomeReply {
    fn json(&self) -> Value {
        json!({"homed": self.homed})
    }
    fn human(&self) -> String {
        format!("homed {}", self.homed)
    }
}

impl Render for pb::RefinedProgramReply {
    fn json(&self) -> Value {
        let refs: Vec<Value> = self
            .refinements
            .iter()
            .map(|x| json!({"seq": x.seq, "block": x.block, "line": x.line, "coordinate": x.coordinate, "delta_mm": x.delta_mm, "e_word": x.e_word}))
            .collect();
        json!({"text": self.text, "refinements": refs, "diagnostics": diags_json(&self.diagnostics)})
    }
    fn human(&self) -> String {
        self.text.trim_end().to_string()
    }
}

async fn refine(m: &mut MachineClient<Svc>, file: &Path, dialect: String, j: bool) -> Reply {
    let text = read_text(file)?;
    let req = pb::RefinedProgramRequest { text, dialect };
    call(j, m.get_refined_program(req)).await
}

/// One status (or, with `watch`, a refreshing status line until the stream ends).
async fn status(m: &mut MachineClient<Svc>, watch: bool, rate: u32, j: bool) -> Reply {
    let rate_hz = if watch { rate } else { 25 };
    let mut stream = m
        .stream_status(pb::StatusRequest { rate_hz })
        .await?
        .into_inner();
    if !watch {
        let s = stream
            .message()
            .await?
            .ok_or(CliError::StatusStreamClosed)?;
        return show(j, &s);
    }
    // In place on a terminal; a line per update into a pipe or a file (NDJSON with --json).
    use std::io::IsTerminal;
    let bar = (!j && std::io::stdout().is_terminal()).then(|| {
        let bar = ProgressBar::new_spinner();
        bar.set_style(ProgressStyle::with_template("{msg}").expect("static template"));
        bar
    });
    while let Some(s) = stream.message().await? {
        match &bar {
            Some(bar) => bar.set_message(status_line(&s)),
            None if j => print_line(&status_json(&s).to_string()),
            None => print_line(&status_line(&s)),
        }
    }
    Ok(ExitCode::SUCCESS)
}

impl Render for pb::AlarmEvent {
    fn json(&self) -> Value {
        let a = self.alarm.clone().unwrap_or_default();
        json!({"active": self.active, "from_history": self.from_history, "event_unix_ms": self.event_unix_ms, "alarm": alarm_json(&a)})
    }
    fn human(&self) -> String {
        let a = self.alarm.clone().unwrap_or_default();
        format!(
            "{} #{:<4} {:<7} {:<8} {}",
            local_time(self.event_unix_ms),
            a.id,
            if self.active { "RAISED" } else { "cleared" },
            a.source,
            a.message
        )
    }
}

/// The alarm history; with `follow`, new alarms as they come.
async fn alarms(m: &mut MachineClient<Svc>, follow: bool, j: bool) -> Reply {
    let mut stream = m
        .stream_alarms(pb::StreamAlarmsRequest {
            skip_history: false,
        })
        .await?
        .into_inner();
    loop {
        let next = if follow {
            stream.message().await?
        } else {
            // History arrives at once; stop when nothing more comes quickly.
            match tokio::time::timeout(Duration::from_millis(300), stream.message()).await {
                Ok(r) => r?,
                Err(_) => None,
            }
        };
        let Some(e) = next else { break };
        emit(j, &e);
    }
    Ok(ExitCode::SUCCESS)
}

/// A jog step's target.
impl Render for pb::JogReply {
    fn json(&self) -> Value {
        json!({"target_mm": self.target_mm})
    }
    fn human(&self) -> String {
        format!("moving to {:.4}", self.target_mm)
    }
}

/// A continuous jog ended (`limit_mm`: where the soft limit would have stopped it).
struct JogStopped(f64);

impl Render for JogStopped {
    fn json(&self) -> Value {
        json!({"stopped": true, "limit_mm": self.0})
    }
    fn human(&self) -> String {
        "jog stopped".to_string()
    }
}

/// `X+`, `X-` or `X` → (letter, direction: +1, -1 or 0).
fn jog_axis(arg: &str) -> Result<(String, i32), CliError> {
    let (name, dir) = match arg.trim() {
        a if a.ends_with('+') => (&a[..a.len() - 1], 1),
        a if a.ends_with('-') => (&a[..a.len() - 1], -1),
        a => (a, 0),
    };
    if name.chars().count() != 1 {
        return Err(CliError::JogAxis {
            arg: arg.to_string(),
        });
    }
    Ok((name.to_string(), dir))
}

/// Continuous jog until Ctrl-C (renewed every 100 ms: the daemon stops the axis when the
/// renewals stop, also if this process is killed), or one step.
async fn jog(
    m: &mut MachineClient<Svc>,
    j: bool,
    arg: &str,
    speed: f64,
    step: Option<f64>,
) -> Reply {
    let (axis, dir) = jog_axis(arg)?;
    if let Some(step) = step {
        let step_mm = if dir < 0 { -step.abs() } else { step };
        let req = pb::JogStepRequest {
            axis,
            step_mm,
            speed_mm_min: speed,
        };
        return call(j, m.jog_step(req)).await;
    }
    if dir == 0 {
        return Err(CliError::JogDirection);
    }
    let (tx, rx) = tokio::sync::mpsc::channel(4);
    let msg = pb::JogRequest {
        axis,
        direction: dir,
        speed_mm_min: speed,
    };
    let feeder = tokio::spawn(async move {
        let mut tick = tokio::time::interval(Duration::from_millis(100));
        let mut interrupted = std::pin::pin!(tokio::signal::ctrl_c());
        loop {
            tokio::select! {
                _ = tick.tick() => {
                    if tx.send(msg.clone()).await.is_err() {
                        return;
                    }
                }
                _ = &mut interrupted => return,
            }
        }
    });
    let call = m.jog(tokio_stream::wrappers::ReceiverStream::new(rx));
    if !j {
        eprintln!("jogging {arg}: Ctrl-C to stop");
    }
    let r = call.await?.into_inner();
    feeder.abort();
    show(j, &JogStopped(r.target_mm))
}

/// Follows job `job` to its end with a progress bar. Exit code 0 when it ran to its end.
pub async fn follow(m: &mut MachineClient<Svc>, job: u32, quiet: bool, j: bool) -> Reply {
    let mut stream = m
        .stream_status(pb::StatusRequest { rate_hz: 25 })
        .await?
        .into_inner();
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(1000)
    };
    bar.set_style(
        ProgressStyle::with_template("[{elapsed_precise}] {bar:30} {percent:>3}% {msg}")
            .expect("static template"),
    );
    bar.enable_steady_tick(Duration::from_millis(200));
    while let Some(s) = stream.message().await? {
        bar.set_position((s.percent * 10.0) as u64);
        let pos: Vec<String> = s.axes.iter().map(dro).collect();
        let block = block_name(s.block);
        bar.set_message(format!("block {block} line {} {}", s.line, pos.join(" ")));
        let finished = s.finished_job == job;
        if finished
            || s.aborted_job == job
            || (s.job == job && s.state == pb::MachineState::Fault as i32)
        {
            bar.finish_and_clear();
            return Ok(job_end(job, finished, &s, j));
        }
    }
    Err(CliError::StatusStreamClosed)
}

/// Prints how job `job` ended (a job that did not finish is reported on standard error).
fn job_end(job: u32, finished: bool, s: &pb::Status, j: bool) -> ExitCode {
    let v = json!({"finished": finished, "job": job, "status": status_json(s)});
    match (finished, j) {
        (_, true) => println!("{v}"),
        (true, false) => println!("program finished: {}", status_line(s)),
        (false, false) => eprintln!("program did not finish: {}", status_line(s)),
    }
    if finished {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jog_axis_takes_a_letter_and_an_optional_direction() {
        assert_eq!(jog_axis("X+").unwrap(), ("X".to_string(), 1));
        assert_eq!(jog_axis(" Z- ").unwrap(), ("Z".to_string(), -1));
        assert_eq!(jog_axis("Y").unwrap(), ("Y".to_string(), 0));
        assert_eq!(jog_axis("XY+").unwrap_err().code(), "cli_jog_axis");
        assert_eq!(jog_axis("+").unwrap_err().code(), "cli_jog_axis");
    }
}
