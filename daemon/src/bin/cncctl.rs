//! `cncctl`: command-line client of the controller's gRPC API.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use prost::Message;
use proto::v1 as pb;
use proto::v1::machine_client::MachineClient;
use tonic::transport::Channel;

#[derive(Parser)]
#[command(name = "cncctl", version, about = "Command-line client of cncd")]
struct Args {
    /// Address of the daemon's gRPC API.
    #[arg(long, global = true, default_value = "http://127.0.0.1:50051")]
    addr: String,
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Load a program, start it, and follow it to its end with a progress bar.
    Run {
        file: PathBuf,
        /// No progress bar (for scripts): print one line at the end.
        #[arg(long)]
        quiet: bool,
    },
    /// Load and validate a program without starting it.
    Load { file: PathBuf },
    /// Start the loaded program.
    Start,
    /// Stop motion (brake on the path) and drop the rest of the program.
    Stop,
    /// Feed hold.
    Hold,
    /// Resume after a feed hold.
    Resume,
    /// Set the feed override, 0..150 %.
    Override { percent: f64 },
    /// Clear a drive or bus fault.
    Reset,
    /// Show the machine status.
    Status {
        /// Refresh in place until interrupted.
        #[arg(long)]
        watch: bool,
        /// Refresh rate for --watch, Hz.
        #[arg(long, default_value_t = 10)]
        rate: u32,
    },
}

#[tokio::main(flavor = "current_thread")]
async fn main() -> ExitCode {
    let args = Args::parse();
    match run(args).await {
        Ok(code) => code,
        Err(e) => {
            eprintln!("cncctl: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Renders a gRPC error for a person, with every program diagnostic on its own line.
fn explain(s: tonic::Status) -> String {
    let mut out = s.message().to_string();
    if let Ok(d) = pb::Diagnostics::decode(s.details())
        && !d.items.is_empty()
    {
        out = format!("{:?}: program rejected", s.code());
        for i in d.items {
            let block = i.block.map(|n| format!(" block N{n}")).unwrap_or_default();
            out.push_str(&format!(
                "\n  line {}:{}{block}: {}",
                i.line, i.column, i.message
            ));
        }
    }
    out
}

async fn connect(addr: &str) -> Result<MachineClient<Channel>, String> {
    MachineClient::connect(addr.to_string())
        .await
        .map_err(|e| format!("cannot reach cncd at {addr}: {e}"))
}

async fn load(c: &mut MachineClient<Channel>, file: &PathBuf) -> Result<u32, String> {
    let text = std::fs::read_to_string(file)
        .map_err(|e| format!("cannot read {}: {e}", file.display()))?;
    let name = file
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let r = c
        .load_program(pb::LoadProgramRequest { name, text })
        .await
        .map_err(explain)?
        .into_inner();
    for d in &r.diagnostics {
        eprintln!("warning: line {}: {}", d.line, d.message);
    }
    Ok(r.blocks)
}

fn state_name(s: i32) -> String {
    pb::MachineState::try_from(s)
        .map(|s| {
            s.as_str_name()
                .trim_start_matches("MACHINE_STATE_")
                .to_lowercase()
        })
        .unwrap_or_else(|_| "unknown".into())
}

fn status_line(s: &pb::Status) -> String {
    let pos: Vec<String> = s
        .axes
        .iter()
        .map(|a| format!("{}{:.3}", a.name, a.commanded_mm))
        .collect();
    let block = s
        .block
        .map(|n| format!("N{n}"))
        .unwrap_or_else(|| "-".into());
    let t = s.ticks.unwrap_or_default();
    let mut line = format!(
        "{:<9} block {block:<6} line {:<5} {:>5.1}%  {}  F {:.1} mm/s  ticks p50/p99/max {}/{}/{} us, overruns {}",
        state_name(s.state),
        s.line,
        s.percent,
        pos.join(" "),
        s.path_velocity_mm_s,
        t.lateness_p50_us,
        t.lateness_p99_us,
        t.lateness_max_us,
        t.overruns
    );
    if !s.alarm.is_empty() {
        line.push_str(&format!("  ALARM: {}", s.alarm));
    }
    line
}

async fn run(args: Args) -> Result<ExitCode, String> {
    let mut c = connect(&args.addr).await?;
    match args.cmd {
        Cmd::Run { file, quiet } => {
            load(&mut c, &file).await?;
            let job = c
                .start(pb::StartRequest {})
                .await
                .map_err(explain)?
                .into_inner()
                .job;
            follow(&mut c, job, quiet).await
        }
        Cmd::Load { file } => {
            let n = load(&mut c, &file).await?;
            println!("loaded {} ({n} blocks)", file.display());
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Start => {
            let job = c
                .start(pb::StartRequest {})
                .await
                .map_err(explain)?
                .into_inner()
                .job;
            println!("started job {job}");
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Stop => {
            c.stop(pb::StopRequest {}).await.map_err(explain)?;
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Hold => {
            c.hold(pb::HoldRequest {}).await.map_err(explain)?;
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Resume => {
            c.resume(pb::ResumeRequest {}).await.map_err(explain)?;
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Override { percent } => {
            c.set_override(pb::SetOverrideRequest { percent })
                .await
                .map_err(explain)?;
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Reset => {
            c.reset(pb::ResetRequest {}).await.map_err(explain)?;
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Status { watch, rate } => {
            let mut stream = c
                .stream_status(pb::StatusRequest {
                    rate_hz: if watch { rate } else { 25 },
                })
                .await
                .map_err(explain)?
                .into_inner();
            if !watch {
                let s = stream
                    .message()
                    .await
                    .map_err(explain)?
                    .ok_or("the daemon closed the status stream")?;
                println!("{}", status_line(&s));
                return Ok(ExitCode::SUCCESS);
            }
            let bar = ProgressBar::new_spinner();
            bar.set_style(ProgressStyle::with_template("{msg}").expect("static template"));
            while let Some(s) = stream.message().await.map_err(explain)? {
                bar.set_message(status_line(&s));
            }
            Ok(ExitCode::SUCCESS)
        }
    }
}

/// Follows job `job` to its end. Exit code 0 when it ran to its end.
async fn follow(c: &mut MachineClient<Channel>, job: u32, quiet: bool) -> Result<ExitCode, String> {
    let mut stream = c
        .stream_status(pb::StatusRequest { rate_hz: 25 })
        .await
        .map_err(explain)?
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
    while let Some(s) = stream.message().await.map_err(explain)? {
        bar.set_position((s.percent * 10.0) as u64);
        let pos: Vec<String> = s
            .axes
            .iter()
            .map(|a| format!("{}{:.3}", a.name, a.commanded_mm))
            .collect();
        let block = s
            .block
            .map(|n| format!("N{n}"))
            .unwrap_or_else(|| "-".into());
        bar.set_message(format!("block {block} line {} {}", s.line, pos.join(" ")));
        if s.finished_job == job {
            bar.finish_and_clear();
            println!("program finished: {}", status_line(&s));
            return Ok(ExitCode::SUCCESS);
        }
        if s.aborted_job == job || (s.job == job && s.state == pb::MachineState::Fault as i32) {
            bar.finish_and_clear();
            eprintln!("program did not finish: {}", status_line(&s));
            return Ok(ExitCode::FAILURE);
        }
    }
    Err("the daemon closed the status stream".into())
}
