//! `cncctl`: command-line client of the controller's gRPC API (docs/api.md).
//!
//! Every service is covered, one module each. The connection is made here once; every call
//! that answers once goes through [`call::call`] (await, a refusal to [`error::CliError`],
//! print); every answer implements [`render::Render`]: output is for people by default and
//! JSON with `--json`.

mod args;
mod call;
mod connect;
mod constants;
mod dialect;
mod error;
mod interpret;
mod io;
mod machine;
mod offsets;
mod plc;
mod preview;
mod probe;
mod programs;
mod render;
mod restart;
mod status;
mod trajectory;

use std::process::ExitCode;

use clap::Parser;
use serde_json::{Value, json};
use tonic_health::pb::HealthCheckRequest;
use tonic_health::pb::health_check_response::ServingStatus;

use args::{Args, Cmd};
use call::Reply;
use connect::{Clients, connect};
use render::{Render, emit};

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

/// Runs the commands that need no daemon here, the others on the daemon.
async fn run(args: Args) -> Reply {
    match &args.cmd {
        Cmd::HashToken { token } => {
            println!("{}", daemon::runtime::api::auth::hash_token_hex(token));
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Preview {
            file,
            out,
            plane,
            page,
            velocity,
            remote,
            dialect,
        } => {
            let a = preview::PreviewArgs {
                file,
                out,
                plane,
                page: *page,
                velocity: *velocity,
                dialect: dialect.as_deref(),
            };
            if !*remote {
                return preview::local(&a, args.json);
            }
            let mut c = connect(&args).await?;
            preview::remote(&mut c.preview, &a, args.json).await
        }
        _ => {
            let mut c = connect(&args).await?;
            dispatch(&mut c, args.cmd, args.json).await
        }
    }
}

/// Routes a command to the module of its gRPC service.
async fn dispatch(c: &mut Clients, cmd: Cmd, j: bool) -> Reply {
    match cmd {
        Cmd::Run { .. }
        | Cmd::Load { .. }
        | Cmd::Upload { .. }
        | Cmd::Programs
        | Cmd::Download { .. }
        | Cmd::Delete { .. }
        | Cmd::Rename { .. }
        | Cmd::Validate { .. } => programs::command(c, cmd, j).await,
        Cmd::Offsets { .. }
        | Cmd::OffsetSet { .. }
        | Cmd::TouchOff { .. }
        | Cmd::OffsetsFile
        | Cmd::OffsetsReplace { .. }
        | Cmd::OffsetsReload
        | Cmd::WorkOffsets
        | Cmd::WorkOffsetSet { .. } => offsets::command(&mut c.offsets, cmd, j).await,
        Cmd::Interpret {
            file,
            stored,
            from_position,
            dialect,
        } => {
            let what = interpret::What {
                file,
                stored,
                from_position,
                dialect,
            };
            interpret::command(&mut c.programs, what, j).await
        }
        Cmd::Plc { cmd } => plc::command(&mut c.plc, cmd, j).await,
        Cmd::Probe { cmd } => probe::command(c, cmd, j).await,
        Cmd::Io { cmd, watch } => io::command(&mut c.machine, cmd, watch, j).await,
        Cmd::Constants { cmd } => constants::command(&mut c.constants, cmd, j).await,
        Cmd::PreviewData {
            file,
            junctions,
            dialect,
        } => preview::data(&mut c.preview, &file, junctions, dialect.as_deref(), j).await,
        Cmd::Trajectory {
            file,
            out,
            from_block,
            dialect,
        } => {
            let (f, o) = ((file.as_deref(), dialect.as_deref()), out.as_deref());
            trajectory::command(&mut c.trajectory, f, o, from_block, j).await
        }
        Cmd::Start {
            from_block: Some(n),
            yes,
        } => restart::command(c, n, yes, j).await,
        Cmd::Health => health(c, j).await,
        Cmd::HashToken { .. } | Cmd::Preview { .. } => unreachable!("run answers it"),
        other => machine::command(&mut c.machine, other, j).await,
    }
}

/// The grpc.health.v1 serving status.
struct Health(&'static str);

impl Render for Health {
    fn json(&self) -> Value {
        json!({"status": self.0})
    }
    fn human(&self) -> String {
        self.0.to_string()
    }
}

/// Prints the daemon's health; fails unless it is serving.
async fn health(c: &mut Clients, j: bool) -> Reply {
    let r = c
        .health
        .check(HealthCheckRequest {
            service: String::new(),
        })
        .await?
        .into_inner();
    let name = ServingStatus::try_from(r.status)
        .map(|s| s.as_str_name())
        .unwrap_or("UNKNOWN");
    emit(j, &Health(name));
    Ok(if name == "SERVING" {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}
