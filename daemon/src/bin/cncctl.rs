//! `cncctl`: command-line client of the controller's gRPC API (docs/api.md).
//!
//! Every service is covered; output is for people by default and JSON with `--json`.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use prost::Message;
use proto::v1 as pb;
use proto::v1::constants_client::ConstantsClient;
use proto::v1::machine_client::MachineClient;
use proto::v1::offsets_client::OffsetsClient;
use proto::v1::plc_client::PlcClient;
use proto::v1::preview_client::PreviewClient;
use proto::v1::programs_client::ProgramsClient;
use proto::v1::trajectory_client::TrajectoryClient;
use serde_json::{Value, json};
use tonic::metadata::{Ascii, MetadataValue};
use tonic::service::Interceptor;
use tonic::service::interceptor::InterceptedService;
use tonic::transport::{Certificate, Channel, ClientTlsConfig};

#[derive(Parser)]
#[command(name = "cncctl", version, about = "Command-line client of cncd")]
struct Args {
    /// Address of the daemon: http://HOST:PORT, https://HOST:PORT (TLS) or unix:/PATH
    /// [default: $CNCCTL_ADDR, else the first Unix socket of /run/cncd/cncd.sock,
    /// ./cncd-data/cncd.sock, /var/lib/cncd/cncd.sock this user may open, else
    /// http://127.0.0.1:50051 (observer only unless the daemon allows more)].
    #[arg(long, global = true)]
    addr: Option<String>,
    /// Bearer token (needed on remote listeners, or for a role above api.local_role)
    /// [default: $CNCCTL_TOKEN].
    #[arg(long, global = true)]
    token: Option<String>,
    /// CA certificate (PEM) to check the daemon's TLS certificate with.
    #[arg(long, global = true)]
    ca: Option<PathBuf>,
    /// Server name to check the TLS certificate against (default: the host of --addr).
    #[arg(long, global = true)]
    tls_domain: Option<String>,
    /// Machine-readable JSON output.
    #[arg(long, global = true)]
    json: bool,
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
    /// Upload, validate and select a program without starting it.
    Load { file: PathBuf },
    /// Validate a program only: every error and warning with block and line.
    Validate { file: PathBuf },
    /// The R325 listing: the program with the circle refinements written as address E.
    Refine { file: PathBuf },
    /// Store a program on the daemon without selecting it.
    Upload {
        file: PathBuf,
        /// Name to store it under (default: the file name).
        #[arg(long)]
        name: Option<String>,
    },
    /// Select a stored program.
    Select { name: String },
    /// List the program library: size, blocks, time stored, verdict.
    Programs,
    /// Write a stored program to FILE (or standard output).
    Download {
        name: String,
        #[arg(short = 'o', long)]
        out: Option<PathBuf>,
    },
    /// Delete a stored program.
    Delete { name: String },
    /// Rename a stored program.
    Rename { from: String, to: String },
    /// Start the selected program.
    Start,
    /// Stop motion (brake on the path) and drop the rest of the program.
    Stop,
    /// Feed hold.
    Hold,
    /// Resume after a feed hold (next block in single-block mode).
    Resume,
    /// Set the feed override, 0..150 %.
    Override { percent: f64 },
    /// Set the spindle override, 50..120 % (scales the commanded spindle speed within the
    /// gear range).
    SpindleOverride { percent: f64 },
    /// Set the rapid override, 0..100 % (scales G0 moves).
    RapidOverride { percent: f64 },
    /// Clear a drive or bus fault.
    Reset,
    /// Single-block mode on or off.
    SingleBlock {
        #[arg(value_parser = ["on", "off"])]
        mode: String,
    },
    /// Optional stop on or off: when on, M1 stops the program like M0 (Resume continues).
    OptionalStop {
        #[arg(value_parser = ["on", "off"])]
        mode: String,
    },
    /// Jog an axis: `cncctl jog X+ --speed 1000` moves X in + at 1000 mm/min until Ctrl-C
    /// (the axis brakes to rest when cncctl stops, however it stops); `cncctl jog X --step 0.1`
    /// (or `X- --step 0.1`) moves by one step. Soft limits are never passed.
    Jog {
        /// Axis letter, with `+` or `-` for the direction (required for a continuous jog).
        axis: String,
        /// Speed, mm/min (default: 10 % of the axis's maximum).
        #[arg(long, default_value_t = 0.0)]
        speed: f64,
        /// Move by this many mm instead of jogging continuously.
        #[arg(long, allow_hyphen_values = true)]
        step: Option<f64>,
    },
    /// Reference run (homing): `cncctl home` homes every axis in the configured order,
    /// `cncctl home Z` or `cncctl home XY` only those. Returns when done.
    Home {
        #[arg(default_value = "")]
        axes: String,
    },
    /// Run one block (MDI), e.g. `cncctl mdi "G1 X10 F500"`.
    Mdi { block: String },
    /// Show the machine status.
    Status {
        /// Refresh in place until interrupted.
        #[arg(long)]
        watch: bool,
        /// Refresh rate for --watch, Hz (1..250).
        #[arg(long, default_value_t = 10)]
        rate: u32,
    },
    /// Show the alarm history; with --follow keep printing new alarms.
    Alarms {
        #[arg(long)]
        follow: bool,
    },
    /// The offset table in memory (entries changed by G92 are marked).
    Offsets {
        /// All 99 entries, zero ones included.
        #[arg(long)]
        all: bool,
    },
    /// Operator edit of one offset entry (file and memory); negative values as they are:
    /// `offset-set 6 --radius -5`.
    #[command(allow_negative_numbers = true)]
    OffsetSet {
        entry: u32,
        #[arg(long)]
        radius: Option<f64>,
        #[arg(long)]
        l1: Option<f64>,
        #[arg(long)]
        l2: Option<f64>,
        #[arg(long)]
        l3: Option<f64>,
        #[arg(long)]
        l4: Option<f64>,
    },
    /// Print the TAB0.KOR file.
    OffsetsFile,
    /// Replace TAB0.KOR with a file (validated; a refused file changes nothing).
    OffsetsReplace { file: PathBuf },
    /// Reload the offset table from its file (drops G92 changes).
    OffsetsReload,
    /// PLC memory area 1.
    Plc {
        #[command(subcommand)]
        cmd: PlcCmd,
    },
    /// Machine constants.
    Constants {
        #[command(subcommand)]
        cmd: ConstCmd,
    },
    /// Preview data of a program file (paths and junctions), as a summary or JSON.
    PreviewData {
        file: PathBuf,
        /// Classify junctions (plans the program).
        #[arg(long)]
        junctions: bool,
    },
    /// Render a program preview to FILE.svg or FILE.png: paths, junction dots, red blocks
    /// (local rendering with default machine settings, no daemon; --remote renders on the
    /// daemon with the machine's axes, limits, constants and offsets).
    Preview {
        file: PathBuf,
        /// Output file; .png writes PNG, anything else SVG.
        #[arg(short = 'o', long)]
        out: PathBuf,
        /// View plane.
        #[arg(long, default_value = "xy", value_parser = ["xy", "xz", "yz"])]
        plane: String,
        /// 1-based page (R387 blocks per page).
        #[arg(long, default_value_t = 1)]
        page: u32,
        /// Velocity-over-time plot instead of the path picture.
        #[arg(long)]
        velocity: bool,
        /// Render on the daemon (GetPreview) instead of locally.
        #[arg(long)]
        remote: bool,
    },
    /// The planned per-tick trajectory of a program file (or of the selected program) on the
    /// daemon, without moving the machine: total time, and with -o a CSV of every tick
    /// (time, setpoints, path speed, block) for plotting.
    Trajectory {
        file: Option<PathBuf>,
        /// CSV output file.
        #[arg(short = 'o', long)]
        out: Option<PathBuf>,
    },
    /// grpc.health.v1 status of the daemon.
    Health,
    /// Print the SHA-256 of a token, for `[[api.tokens]] sha256 = ...`.
    HashToken { token: String },
}

#[derive(Subcommand)]
enum PlcCmd {
    /// Every cell with unit, access and value.
    List,
    /// Read cells by name (AKRR_V) or address (0xA19C).
    Read { cells: Vec<String> },
    /// Write one input cell.
    Write { cell: String, value: i64 },
}

#[derive(Subcommand)]
enum ConstCmd {
    /// Read constants (all set or with a default when none are named), decades decoded.
    Get { numbers: Vec<u32> },
    /// Set constants: `R39=45 R384=20.0` (admin role).
    Set { values: Vec<String> },
}

/// Adds the bearer token to every call.
#[derive(Clone)]
struct Token(Option<MetadataValue<Ascii>>);

impl Interceptor for Token {
    fn call(&mut self, mut req: tonic::Request<()>) -> Result<tonic::Request<()>, tonic::Status> {
        if let Some(t) = &self.0 {
            req.metadata_mut().insert("authorization", t.clone());
        }
        Ok(req)
    }
}

type Svc = InterceptedService<Channel, Token>;

struct Clients {
    m: MachineClient<Svc>,
    g: ProgramsClient<Svc>,
    o: OffsetsClient<Svc>,
    p: PlcClient<Svc>,
    k: ConstantsClient<Svc>,
    v: PreviewClient<Svc>,
    t: TrajectoryClient<Svc>,
    ch: Channel,
    token: Token,
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

/// Renders a gRPC error for a person, with every diagnostic on its own line.
fn explain(s: tonic::Status) -> String {
    let mut out = format!("{:?}: {}", s.code(), s.message());
    if let Ok(d) = pb::Diagnostics::decode(s.details())
        && !d.items.is_empty()
    {
        out = format!("{:?}: rejected", s.code());
        for i in d.items {
            out.push_str(&format!("\n  {}", diag_line(&i)));
        }
    }
    out
}

fn diag_line(i: &pb::Diagnostic) -> String {
    let sev = pb::Severity::try_from(i.severity)
        .map(|s| {
            s.as_str_name()
                .trim_start_matches("SEVERITY_")
                .to_lowercase()
        })
        .unwrap_or_default();
    let sev = if i.code.is_empty() {
        sev
    } else {
        format!("{sev} [{}]", i.code)
    };
    let block = i.block.map(|n| format!(" block N{n}")).unwrap_or_default();
    // Line 0: the value did not come from a text (an offset or constant set by its name,
    // which the message names).
    if i.line == 0 {
        return format!("{sev}{block}: {}", i.message);
    }
    format!("{sev}: line {}:{}{block}: {}", i.line, i.column, i.message)
}

fn diag_json(i: &pb::Diagnostic) -> Value {
    json!({"severity": pb::Severity::try_from(i.severity).map(|s| s.as_str_name()).unwrap_or("?"),
        "block": i.block, "line": i.line, "column": i.column, "code": i.code, "message": i.message})
}

async fn connect(args: &Args) -> Result<Clients, String> {
    let addr = args
        .addr
        .clone()
        .or_else(|| std::env::var("CNCCTL_ADDR").ok())
        .unwrap_or_else(default_addr);
    let token_text = args
        .token
        .clone()
        .or_else(|| std::env::var("CNCCTL_TOKEN").ok());
    let mut ep = tonic::transport::Endpoint::from_shared(addr.clone())
        .map_err(|e| format!("bad address {addr}: {e}"))?;
    if addr.starts_with("https://") {
        let mut tls = ClientTlsConfig::new();
        if let Some(ca) = &args.ca {
            let pem =
                std::fs::read(ca).map_err(|e| format!("cannot read {}: {e}", ca.display()))?;
            tls = tls.ca_certificate(Certificate::from_pem(pem));
        }
        if let Some(d) = &args.tls_domain {
            tls = tls.domain_name(d.clone());
        }
        ep = ep.tls_config(tls).map_err(|e| format!("TLS: {e}"))?;
    }
    let ch = ep
        .connect_timeout(Duration::from_secs(5))
        .connect()
        .await
        .map_err(|e| format!("cannot reach cncd at {addr}: {e}"))?;
    let token = Token(match &token_text {
        Some(t) => Some(
            format!("Bearer {t}")
                .parse()
                .map_err(|_| "the token must be printable ASCII".to_string())?,
        ),
        None => None,
    });
    let svc = || InterceptedService::new(ch.clone(), token.clone());
    Ok(Clients {
        m: MachineClient::new(svc()),
        g: ProgramsClient::new(svc()),
        o: OffsetsClient::new(svc()),
        p: PlcClient::new(svc()),
        k: ConstantsClient::new(svc()),
        v: PreviewClient::new(svc()),
        t: TrajectoryClient::new(svc()),
        ch: ch.clone(),
        token: token.clone(),
    })
}

/// Unix sockets tried when no address is given: the systemd unit's, the data directory of a
/// `cncd` started in this directory, the unit's state directory.
const DEFAULT_SOCKETS: [&str; 3] = [
    "/run/cncd/cncd.sock",
    "cncd-data/cncd.sock",
    "/var/lib/cncd/cncd.sock",
];

/// The first default socket this user can connect to (the socket's mode and group grant
/// control), else loopback TCP (where callers without a token are observers by default).
fn default_addr() -> String {
    for p in DEFAULT_SOCKETS {
        let path = std::path::Path::new(p);
        if std::os::unix::net::UnixStream::connect(path).is_ok() {
            let abs = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
            return format!("unix:{}", abs.display());
        }
    }
    "http://127.0.0.1:50051".into()
}

fn read_text(file: &PathBuf) -> Result<(String, String), String> {
    let text = std::fs::read_to_string(file)
        .map_err(|e| format!("cannot read {}: {e}", file.display()))?;
    let name = file
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    Ok((name, text))
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

/// One axis as the DRO shows it: `X12.500`, or `XØ25.000` on a diameter axis (docs/lathe.md).
fn dro(a: &pb::AxisStatus) -> String {
    if a.diameter {
        format!("{}Ø{:.3}", a.name, a.display_mm)
    } else {
        format!("{}{:.3}", a.name, a.commanded_mm)
    }
}

fn status_line(s: &pb::Status) -> String {
    let pos: Vec<String> = s
        .axes
        .iter()
        .map(|a| {
            let unhomed = if a.homed { "" } else { "(not homed)" };
            let limit = match a.at_soft_limit {
                -1 => "(at soft min)",
                1 => "(at soft max)",
                _ => "",
            };
            format!("{}{unhomed}{limit}", dro(a))
        })
        .collect();
    let block = s
        .block
        .map(|n| format!("N{n}"))
        .unwrap_or_else(|| "-".into());
    let t = s.ticks.unwrap_or_default();
    let mut line = format!(
        "{:<9}{} block {block:<6} line {:<5} {:>5.1}%  {}  F {:.1} mm/s ovr {:.0}% spindle {:.0}% rapid {:.0}%  {}  ticks p50/p99/max {}/{}/{} us, overruns {}",
        state_name(s.state),
        if s.single_block { " [SB]" } else { "" },
        s.line,
        s.percent,
        pos.join(" "),
        s.path_velocity_mm_s,
        s.override_percent,
        s.spindle_override_percent,
        s.rapid_override_percent,
        s.modal_g_codes.join(" "),
        t.lateness_p50_us,
        t.lateness_p99_us,
        t.lateness_max_us,
        t.overruns
    );
    if s.axes.iter().any(|a| a.distance_to_go_mm != 0.0) {
        let togo: Vec<String> = s
            .axes
            .iter()
            .map(|a| format!("{}{:.3}", a.name, a.distance_to_go_mm))
            .collect();
        line.push_str(&format!("  to go {}", togo.join(" ")));
    }
    if s.waiting_for_spindle {
        line.push_str("  waiting for the spindle to reach its speed");
    }
    if s.optional_stop {
        line.push_str("  [M1 stops]");
    }
    if s.program_stop {
        line.push_str("  program stop (M0/M1): resume to continue");
    }
    if s.fault_path_deviation_mm > 0.0 {
        line.push_str(&format!(
            "  fault stop left the path by {:.3} mm",
            s.fault_path_deviation_mm
        ));
    }
    if !s.alarm.is_empty() {
        line.push_str(&format!("  ALARM: {}", s.alarm));
    }
    line
}

fn status_json(s: &pb::Status) -> Value {
    let t = s.ticks.unwrap_or_default();
    json!({
        "state": state_name(s.state),
        "mode": pb::Mode::try_from(s.mode).map(|m| m.as_str_name()).unwrap_or("?"),
        "single_block": s.single_block,
        "program": s.program, "job": s.job, "block": s.block, "line": s.line,
        "block_index": s.block_index, "blocks_total": s.blocks_total, "percent": s.percent,
        "axes": s.axes.iter().map(|a| json!({"name": a.name, "commanded_mm": a.commanded_mm,
            "actual_mm": a.actual_mm, "following_error_mm": a.following_error_mm,
            "distance_to_go_mm": a.distance_to_go_mm,
            "soft_min_mm": a.soft_min_mm, "soft_max_mm": a.soft_max_mm,
            "homed": a.homed, "homing_required": a.homing_required,
            "diameter": a.diameter, "display_mm": a.display_mm,
            "at_soft_limit": a.at_soft_limit})).collect::<Vec<_>>(),
        "path_velocity_mm_s": s.path_velocity_mm_s,
        "feed_programmed": s.feed_programmed, "feed_mode": s.feed_mode,
        "override_percent": s.override_percent, "spindle_rpm": s.spindle_rpm,
        "spindle_override_percent": s.spindle_override_percent,
        "rapid_override_percent": s.rapid_override_percent,
        "modal_g_codes": s.modal_g_codes,
        "compensation": s.compensation.as_ref().map(|c| json!({"code": c.code, "entry": c.entry, "radius_mm": c.radius_mm})),
        "junction": pb::JunctionClass::try_from(s.junction).map(|j| j.as_str_name()).unwrap_or("?"),
        "kr": s.kr.as_ref().map(|k| json!({"cutting_speed_m_min": k.cutting_speed_m_min,
            "speed_limit_rpm": k.speed_limit_rpm, "radius_mm": k.radius_mm,
            "spindle_rpm": k.spindle_rpm, "output": k.output, "gear_max_rpm": k.gear_max_rpm})),
        "dynamic_set": s.dynamic_set,
        "waiting_for_spindle": s.waiting_for_spindle,
        "optional_stop": s.optional_stop, "program_stop": s.program_stop,
        "fault_path_deviation_mm": s.fault_path_deviation_mm,
        "ticks": {"ticks": t.ticks, "overruns": t.overruns, "lateness_p50_us": t.lateness_p50_us,
            "lateness_p99_us": t.lateness_p99_us, "lateness_max_us": t.lateness_max_us,
            "cycle_us": t.cycle_us},
        "alarm": s.alarm,
        "active_alarms": s.active_alarms.iter().map(alarm_json).collect::<Vec<_>>(),
        "finished_job": s.finished_job, "aborted_job": s.aborted_job, "sequence": s.sequence,
    })
}

fn alarm_json(a: &pb::Alarm) -> Value {
    json!({"id": a.id, "message": a.message, "source": a.source, "raised_unix_ms": a.raised_unix_ms})
}

fn cell_json(c: &pb::PlcCell) -> Value {
    json!({"name": c.name, "address": format!("{:X}h", c.address), "value": c.value, "unit": c.unit,
        "access": pb::CellAccess::try_from(c.access).map(|a| a.as_str_name()).unwrap_or("?"),
        "min": c.min, "max": c.max, "description": c.description})
}

fn cell_ref(s: &str) -> pb::CellRef {
    let hex = s
        .strip_prefix("0x")
        .or_else(|| s.strip_prefix("0X"))
        .or_else(|| s.strip_suffix('h').or_else(|| s.strip_suffix('H')));
    let cell = match hex.and_then(|h| u32::from_str_radix(h, 16).ok()) {
        Some(a) => pb::cell_ref::Cell::Address(a),
        None => pb::cell_ref::Cell::Name(s.to_string()),
    };
    pb::CellRef { cell: Some(cell) }
}

fn print(json_mode: bool, v: Value, human: impl FnOnce() -> String) {
    if json_mode {
        println!("{v}");
    } else {
        let h = human();
        if !h.is_empty() {
            println!("{h}");
        }
    }
}

async fn run(args: Args) -> Result<ExitCode, String> {
    if let Cmd::HashToken { token } = &args.cmd {
        println!("{}", daemon::runtime::api::auth::hash_token_hex(token));
        return Ok(ExitCode::SUCCESS);
    }
    if let Cmd::Preview {
        file,
        out,
        plane,
        page,
        velocity,
        remote: false,
    } = &args.cmd
    {
        return preview_local(file, out, plane, *page, *velocity, args.json);
    }
    let mut c = connect(&args).await?;
    let j = args.json;
    match args.cmd {
        Cmd::HashToken { .. } => unreachable!("handled above"),
        Cmd::Run { file, quiet } => {
            let done = upload(&mut c.g, &file, None, true, quiet || j).await?;
            for d in &done.diagnostics {
                eprintln!("{}", diag_line(d));
            }
            let job =
                c.m.start(pb::StartRequest {})
                    .await
                    .map_err(explain)?
                    .into_inner()
                    .job;
            follow(&mut c.m, job, quiet || j, j).await
        }
        Cmd::Load { file } => {
            let done = upload(&mut c.g, &file, None, true, j).await?;
            let blocks = done.program.as_ref().map_or(0, |p| p.blocks);
            print(
                j,
                json!({"blocks": blocks, "diagnostics": done.diagnostics.iter().map(diag_json).collect::<Vec<_>>()}),
                || {
                    let mut s = format!("loaded {} ({blocks} blocks)", file.display());
                    for d in &done.diagnostics {
                        s.push_str(&format!("\n  {}", diag_line(d)));
                    }
                    s
                },
            );
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Refine { file } => {
            let (_, text) = read_text(&file)?;
            let r =
                c.m.get_refined_program(pb::RefinedProgramRequest { text })
                    .await
                    .map_err(explain)?
                    .into_inner();
            let refs: Vec<Value> = r
                .refinements
                .iter()
                .map(|x| json!({"seq": x.seq, "block": x.block, "line": x.line, "coordinate": x.coordinate, "delta_mm": x.delta_mm, "e_word": x.e_word}))
                .collect();
            print(
                j,
                json!({"text": r.text, "refinements": refs, "diagnostics": r.diagnostics.iter().map(diag_json).collect::<Vec<_>>()}),
                || r.text.trim_end().to_string(),
            );
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Validate { file } => {
            let (_, text) = read_text(&file)?;
            let r =
                c.m.validate_program(pb::ValidateProgramRequest { text })
                    .await
                    .map_err(explain)?
                    .into_inner();
            print(
                j,
                json!({"valid": r.valid, "blocks": r.blocks, "diagnostics": r.diagnostics.iter().map(diag_json).collect::<Vec<_>>()}),
                || {
                    let mut s = if r.valid {
                        format!("{}: valid, {} blocks", file.display(), r.blocks)
                    } else {
                        format!("{}: has errors", file.display())
                    };
                    for d in &r.diagnostics {
                        s.push_str(&format!("\n  {}", diag_line(d)));
                    }
                    s
                },
            );
            Ok(if r.valid {
                ExitCode::SUCCESS
            } else {
                ExitCode::FAILURE
            })
        }
        Cmd::Upload { file, name } => {
            let done = upload(&mut c.g, &file, name, false, j).await?;
            let p = done.program.unwrap_or_default();
            print(
                j,
                json!({"name": p.name, "blocks": p.blocks, "size_bytes": p.size_bytes}),
                || {
                    format!(
                        "stored {} ({} blocks, {} bytes)",
                        p.name, p.blocks, p.size_bytes
                    )
                },
            );
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Select { name } => {
            let r =
                c.m.select_program(pb::SelectProgramRequest { name: name.clone() })
                    .await
                    .map_err(explain)?
                    .into_inner();
            print(j, json!({"name": name, "blocks": r.blocks}), || {
                format!("selected {name} ({} blocks)", r.blocks)
            });
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Programs => {
            let r =
                c.g.list(pb::LibraryListRequest {})
                    .await
                    .map_err(explain)?
                    .into_inner();
            print(
                j,
                json!({"selected": r.selected, "used_bytes": r.used_bytes, "max_bytes": r.max_bytes,
                    "programs": r.programs.iter().map(|p| json!({"name": p.name, "blocks": p.blocks,
                    "size_bytes": p.size_bytes, "modified_unix_ms": p.modified_unix_ms, "valid": p.valid,
                    "errors": p.errors, "warnings": p.warnings, "first_error": p.first_error})).collect::<Vec<_>>()}),
                || library_text(&r),
            );
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Download { name, out } => {
            let mut s =
                c.g.download(pb::ProgramName { name: name.clone() })
                    .await
                    .map_err(explain)?
                    .into_inner();
            let mut sink: Box<dyn std::io::Write> = match &out {
                Some(p) => Box::new(
                    std::fs::File::create(p)
                        .map_err(|e| format!("cannot write {}: {e}", p.display()))?,
                ),
                None => Box::new(std::io::stdout()),
            };
            while let Some(m) = s.message().await.map_err(explain)? {
                sink.write_all(&m.data).map_err(|e| e.to_string())?;
            }
            sink.flush().map_err(|e| e.to_string())?;
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Delete { name } => done(j, c.g.delete(pb::ProgramName { name }).await),
        Cmd::Rename { from, to } => {
            done(j, c.g.rename(pb::RenameProgramRequest { from, to }).await)
        }
        Cmd::Start => {
            let job =
                c.m.start(pb::StartRequest {})
                    .await
                    .map_err(explain)?
                    .into_inner()
                    .job;
            print(j, json!({"job": job}), || format!("started job {job}"));
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Stop => done(j, c.m.stop(pb::StopRequest {}).await),
        Cmd::Hold => done(j, c.m.hold(pb::HoldRequest {}).await),
        Cmd::Resume => done(j, c.m.resume(pb::ResumeRequest {}).await),
        Cmd::Reset => done(j, c.m.reset(pb::ResetRequest {}).await),
        Cmd::Override { percent } => done(
            j,
            c.m.set_override(pb::SetOverrideRequest { percent }).await,
        ),
        Cmd::SpindleOverride { percent } => done(
            j,
            c.m.set_spindle_override(pb::SetSpindleOverrideRequest { percent })
                .await,
        ),
        Cmd::RapidOverride { percent } => done(
            j,
            c.m.set_rapid_override(pb::SetRapidOverrideRequest { percent })
                .await,
        ),
        Cmd::SingleBlock { mode } => done(
            j,
            c.m.set_single_block(pb::SetSingleBlockRequest {
                enabled: mode == "on",
            })
            .await,
        ),
        Cmd::OptionalStop { mode } => done(
            j,
            c.m.set_optional_stop(pb::SetOptionalStopRequest { on: mode == "on" })
                .await,
        ),
        Cmd::Home { axes } => {
            let r =
                c.m.home(pb::HomeRequest { axes })
                    .await
                    .map_err(explain)?
                    .into_inner();
            print(j, json!({"homed": r.homed}), || {
                format!("homed {}", r.homed)
            });
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Jog { axis, speed, step } => jog(&mut c.m, j, &axis, speed, step).await,
        Cmd::Mdi { block } => {
            let job =
                c.m.mdi(pb::MdiRequest { block })
                    .await
                    .map_err(explain)?
                    .into_inner()
                    .job;
            print(j, json!({"job": job}), || format!("MDI job {job} started"));
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Status { watch, rate } => {
            let mut stream =
                c.m.stream_status(pb::StatusRequest {
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
                print(j, status_json(&s), || status_line(&s));
                return Ok(ExitCode::SUCCESS);
            }
            let bar = ProgressBar::new_spinner();
            bar.set_style(ProgressStyle::with_template("{msg}").expect("static template"));
            while let Some(s) = stream.message().await.map_err(explain)? {
                if j {
                    println!("{}", status_json(&s));
                } else {
                    bar.set_message(status_line(&s));
                }
            }
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Alarms { follow } => {
            let mut stream =
                c.m.stream_alarms(pb::StreamAlarmsRequest {
                    skip_history: false,
                })
                .await
                .map_err(explain)?
                .into_inner();
            loop {
                let next = if follow {
                    stream.message().await.map_err(explain)?
                } else {
                    // History arrives at once; stop when nothing more comes quickly.
                    match tokio::time::timeout(Duration::from_millis(300), stream.message()).await {
                        Ok(r) => r.map_err(explain)?,
                        Err(_) => None,
                    }
                };
                let Some(e) = next else { break };
                let a = e.alarm.unwrap_or_default();
                print(
                    j,
                    json!({"active": e.active, "from_history": e.from_history, "event_unix_ms": e.event_unix_ms, "alarm": alarm_json(&a)}),
                    || {
                        format!(
                            "#{:<4} {:<7} {:<8} {}",
                            a.id,
                            if e.active { "RAISED" } else { "cleared" },
                            a.source,
                            a.message
                        )
                    },
                );
            }
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Offsets { all } => {
            let r =
                c.o.get_offsets(pb::GetOffsetsRequest { include_zero: all })
                    .await
                    .map_err(explain)?
                    .into_inner();
            print(
                j,
                json!({"labels": r.labels, "entries": r.entries.iter().map(|e| json!({"entry": e.entry, "radius_mm": e.radius_mm, "length_mm": e.length_mm, "changed_by_program": e.changed_by_program})).collect::<Vec<_>>()}),
                || {
                    let mut s = format!(
                        "{:>3} {:>12}",
                        "D",
                        r.labels.first().cloned().unwrap_or_default()
                    );
                    for l in r.labels.iter().skip(1) {
                        s.push_str(&format!(" {l:>12}"));
                    }
                    for e in &r.entries {
                        s.push_str(&format!("\n{:>3} {:>12.4}", e.entry, e.radius_mm));
                        for l in &e.length_mm {
                            s.push_str(&format!(" {l:>12.4}"));
                        }
                        if e.changed_by_program {
                            s.push_str("  (G92, not in file)");
                        }
                    }
                    s
                },
            );
            Ok(ExitCode::SUCCESS)
        }
        Cmd::OffsetSet {
            entry,
            radius,
            l1,
            l2,
            l3,
            l4,
        } => {
            let e =
                c.o.set_offset(pb::SetOffsetRequest {
                    entry,
                    radius_mm: radius,
                    length1_mm: l1,
                    length2_mm: l2,
                    length3_mm: l3,
                    length4_mm: l4,
                })
                .await
                .map_err(explain)?
                .into_inner();
            print(
                j,
                json!({"entry": e.entry, "radius_mm": e.radius_mm, "length_mm": e.length_mm}),
                || format!("D{}: R={} lengths {:?}", e.entry, e.radius_mm, e.length_mm),
            );
            Ok(ExitCode::SUCCESS)
        }
        Cmd::OffsetsFile => {
            let f =
                c.o.get_offsets_file(pb::GetOffsetsFileRequest {})
                    .await
                    .map_err(explain)?
                    .into_inner();
            print(j, json!({"text": f.text}), || f.text.trim_end().to_string());
            Ok(ExitCode::SUCCESS)
        }
        Cmd::OffsetsReplace { file } => {
            let (_, text) = read_text(&file)?;
            let r =
                c.o.replace_offsets_file(pb::OffsetsFile { text })
                    .await
                    .map_err(explain)?
                    .into_inner();
            print(j, json!({"entries": r.entries}), || {
                format!("TAB0.KOR replaced: {} non-zero entries", r.entries)
            });
            Ok(ExitCode::SUCCESS)
        }
        Cmd::OffsetsReload => {
            let r =
                c.o.reload_offsets(pb::ReloadOffsetsRequest {})
                    .await
                    .map_err(explain)?
                    .into_inner();
            print(j, json!({"entries": r.entries}), || {
                format!("reloaded: {} non-zero entries", r.entries)
            });
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Plc { cmd } => {
            let cells = match cmd {
                PlcCmd::List => {
                    c.p.list_cells(pb::ListCellsRequest {})
                        .await
                        .map_err(explain)?
                        .into_inner()
                        .cells
                }
                PlcCmd::Read { cells } => {
                    c.p.read_cells(pb::ReadCellsRequest {
                        cells: cells.iter().map(|s| cell_ref(s)).collect(),
                    })
                    .await
                    .map_err(explain)?
                    .into_inner()
                    .cells
                }
                PlcCmd::Write { cell, value } => vec![
                    c.p.write_cell(pb::WriteCellRequest {
                        cell: Some(cell_ref(&cell)),
                        value,
                    })
                    .await
                    .map_err(explain)?
                    .into_inner(),
                ],
            };
            print(
                j,
                Value::Array(cells.iter().map(cell_json).collect()),
                || {
                    cells
                        .iter()
                        .map(|c| {
                            let rw = if c.access == pb::CellAccess::ReadOnly as i32 {
                                "R "
                            } else {
                                "RW"
                            };
                            format!(
                                "{:X}h {:<15} {rw} {:>12} {}",
                                c.address, c.name, c.value, c.unit
                            )
                        })
                        .collect::<Vec<_>>()
                        .join("\n")
                },
            );
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Constants { cmd } => match cmd {
            ConstCmd::Get { numbers } => {
                let r =
                    c.k.get_constants(pb::GetConstantsRequest { numbers })
                        .await
                        .map_err(explain)?
                        .into_inner();
                print(j, Value::Array(r.constants.iter().map(|k| json!({"number": k.number, "value": k.value, "text": k.text, "decades": k.decades, "negative": k.negative, "is_default": k.is_default})).collect()), || {
                    let mut s = "R      value        d8 d7 d6 d5 d4 d3 d2 d1".to_string();
                    for k in &r.constants {
                        let d: Vec<String> = k.decades.iter().rev().map(|d| format!("{d:>2}")).collect();
                        s.push_str(&format!("\nR{:<4} {:>12} {}{}", k.number, k.text, d.join(" "), if k.is_default { "  (default)" } else { "" }));
                    }
                    s
                });
                Ok(ExitCode::SUCCESS)
            }
            ConstCmd::Set { values } => {
                let values = values
                    .iter()
                    .map(|v| {
                        let (r, x) = v
                            .trim_start_matches(['R', 'r'])
                            .split_once('=')
                            .ok_or(format!("{v}: write Rnnn=value"))?;
                        Ok(pb::ConstantValue {
                            number: r.parse().map_err(|_| format!("{v}: bad number"))?,
                            value: x.parse().map_err(|_| format!("{v}: bad value"))?,
                        })
                    })
                    .collect::<Result<Vec<_>, String>>()?;
                let r =
                    c.k.set_constants(pb::SetConstantsRequest { values })
                        .await
                        .map_err(explain)?
                        .into_inner();
                print(
                    j,
                    json!({"restart_required": r.restart_required, "diagnostics": r.diagnostics.iter().map(diag_json).collect::<Vec<_>>()}),
                    || {
                        let mut s =
                            "constants saved; in force from the next program start".to_string();
                        if !r.restart_required.is_empty() {
                            s.push_str(&format!(
                                "\nrestart cncd for: {}",
                                r.restart_required
                                    .iter()
                                    .map(|n| format!("R{n}"))
                                    .collect::<Vec<_>>()
                                    .join(" ")
                            ));
                        }
                        for d in &r.diagnostics {
                            s.push_str(&format!("\n  {}", diag_line(d)));
                        }
                        s
                    },
                );
                Ok(ExitCode::SUCCESS)
            }
        },
        Cmd::PreviewData { file, junctions } => {
            let (_, text) = read_text(&file)?;
            let d =
                c.v.get_preview_data(pb::PreviewDataRequest { text, junctions })
                    .await
                    .map_err(explain)?
                    .into_inner();
            let el = |e: &pb::PathElement| {
                json!({"seq": e.seq, "block": e.block, "line": e.line,
                "kind": pb::PathKind::try_from(e.kind).map(|k| k.as_str_name()).unwrap_or("?"),
                "start_mm": e.start_mm, "end_mm": e.end_mm, "center_mm": e.center_mm, "plane": e.plane})
            };
            let red: Vec<&pb::Junction> = d
                .junctions
                .iter()
                .filter(|j| j.class != pb::JunctionClass::Smooth as i32)
                .collect();
            print(
                j,
                json!({"axes": d.axes, "programmed": d.programmed.iter().map(el).collect::<Vec<_>>(),
                "compensated": d.compensated.iter().map(el).collect::<Vec<_>>(),
                "junctions": d.junctions.iter().map(|x| json!({"seq": x.seq, "block": x.block, "line": x.line,
                    "class": pb::JunctionClass::try_from(x.class).map(|k| k.as_str_name()).unwrap_or("?"),
                    "position_mm": x.position_mm, "speed_mm_s": x.speed_mm_s})).collect::<Vec<_>>(),
                "diagnostics": d.diagnostics.iter().map(diag_json).collect::<Vec<_>>()}),
                || {
                    let mut s = format!(
                        "{} programmed moves, {} compensated moves, {} junctions ({} red: stop or speed drop)",
                        d.programmed.len(),
                        d.compensated.len(),
                        d.junctions.len(),
                        red.len()
                    );
                    for r in red.iter().take(50) {
                        let b = r
                            .block
                            .map(|n| format!("N{n}"))
                            .unwrap_or_else(|| "-".into());
                        s.push_str(&format!(
                            "\n  line {:<5} {b:<6} {}",
                            r.line,
                            pb::JunctionClass::try_from(r.class)
                                .map(|k| k.as_str_name())
                                .unwrap_or("?")
                        ));
                    }
                    for x in &d.diagnostics {
                        s.push_str(&format!("\n  {}", diag_line(x)));
                    }
                    s
                },
            );
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Preview {
            file,
            out,
            plane,
            page,
            velocity,
            ..
        } => {
            let (_, text) = read_text(&file)?;
            let png = out
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("png"));
            let r =
                c.v.get_preview(pb::GetPreviewRequest {
                    text,
                    format: if png {
                        pb::ImageFormat::Png
                    } else {
                        pb::ImageFormat::Svg
                    } as i32,
                    plane,
                    page,
                    velocity,
                    width_px: 0,
                    height_px: 0,
                })
                .await
                .map_err(explain)?
                .into_inner();
            std::fs::write(&out, &r.image)
                .map_err(|e| format!("cannot write {}: {e}", out.display()))?;
            let red: Vec<String> = r
                .red
                .iter()
                .map(|b| {
                    b.block
                        .map_or(format!("line {}", b.line), |n| format!("N{n}"))
                })
                .collect();
            print(
                j,
                json!({"out": out.display().to_string(), "page": r.page, "pages": r.pages,
                "red_blocks": red, "red_junctions": r.red_junctions, "smooth_junctions": r.smooth_junctions}),
                || {
                    format!(
                        "{}: page {} of {}, {} red junctions{}{}",
                        out.display(),
                        r.page,
                        r.pages,
                        r.red_junctions,
                        if red.is_empty() { "" } else { ": " },
                        red.join(" ")
                    )
                },
            );
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Trajectory { file, out } => {
            let text = match file {
                Some(f) => read_text(&f)?.1,
                None => String::new(),
            };
            let (total_s, ticks) = trajectory(&mut c.t, text, out.as_deref()).await?;
            if j {
                println!("{}", json!({"total_s": total_s, "ticks": ticks}));
            } else {
                println!("machining time {total_s:.3} s ({ticks} ticks of 4 ms)");
            }
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Health => {
            use tonic_health::pb::HealthCheckRequest;
            use tonic_health::pb::health_client::HealthClient;
            let mut h = HealthClient::new(InterceptedService::new(c.ch.clone(), c.token.clone()));
            let r = h
                .check(HealthCheckRequest {
                    service: String::new(),
                })
                .await
                .map_err(explain)?
                .into_inner();
            let name = tonic_health::pb::health_check_response::ServingStatus::try_from(r.status)
                .map(|s| s.as_str_name())
                .unwrap_or("UNKNOWN");
            print(j, json!({"status": name}), || name.to_string());
            Ok(if name == "SERVING" {
                ExitCode::SUCCESS
            } else {
                ExitCode::FAILURE
            })
        }
    }
}

/// `cncctl preview` without a daemon: the preview crate with default machine settings.
fn preview_local(
    file: &PathBuf,
    out: &std::path::Path,
    plane: &str,
    page: u32,
    velocity: bool,
    j: bool,
) -> Result<ExitCode, String> {
    let (_, text) = read_text(file)?;
    let plane =
        preview::ViewPlane::parse(plane).ok_or(format!("plane {plane}: use xy, xz or yz"))?;
    let opts = preview::PreviewOptions {
        plane,
        page: page.max(1),
        ..Default::default()
    };
    let png = out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    let errors = |d: Vec<kernel::Diagnostic>| {
        let mut s = format!("{}: rejected", file.display());
        for x in d {
            s.push_str(&format!("\n  {x}"));
        }
        s
    };
    let (bytes, summary, red) = if velocity {
        let v = preview::velocity_plot(&text, &opts, true).map_err(errors)?;
        let b = if png {
            v.to_png().map_err(|e| e.to_string())?
        } else {
            v.to_svg().into_bytes()
        };
        (
            b,
            format!(
                "velocity plot page {} of {}, {:.2} s .. {:.2} s",
                v.page, v.pages, v.start_s, v.end_s
            ),
            Vec::new(),
        )
    } else {
        let p = preview::render(&text, &opts).map_err(errors)?;
        let b = if png {
            p.to_png().map_err(|e| e.to_string())?
        } else {
            p.to_svg().into_bytes()
        };
        let red = p.red_blocks();
        (
            b,
            format!(
                "page {} of {}, {} red junctions",
                p.page, p.pages, p.red_junctions
            ),
            red,
        )
    };
    std::fs::write(out, &bytes).map_err(|e| format!("cannot write {}: {e}", out.display()))?;
    print(
        j,
        json!({"out": out.display().to_string(), "summary": summary, "red_blocks": red}),
        || {
            format!(
                "{}: {summary}{}{}",
                out.display(),
                if red.is_empty() { "" } else { ": " },
                red.join(" ")
            )
        },
    );
    Ok(ExitCode::SUCCESS)
}

/// `X+`, `X-` or `X` → (letter, direction: +1, -1 or 0).
fn jog_axis(arg: &str) -> Result<(String, i32), String> {
    let (name, dir) = match arg.trim() {
        a if a.ends_with('+') => (&a[..a.len() - 1], 1),
        a if a.ends_with('-') => (&a[..a.len() - 1], -1),
        a => (a, 0),
    };
    if name.chars().count() != 1 {
        return Err(format!("{arg:?}: give an axis letter, e.g. X+ or Z-"));
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
) -> Result<ExitCode, String> {
    let (axis, dir) = jog_axis(arg)?;
    if let Some(step) = step {
        let step_mm = if dir < 0 { -step.abs() } else { step };
        let r = m
            .jog_step(pb::JogStepRequest {
                axis,
                step_mm,
                speed_mm_min: speed,
            })
            .await
            .map_err(explain)?
            .into_inner();
        print(j, json!({"target_mm": r.target_mm}), || {
            format!("moving to {:.4}", r.target_mm)
        });
        return Ok(ExitCode::SUCCESS);
    }
    if dir == 0 {
        return Err("a continuous jog needs a direction: X+ or X-".into());
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
    let r = call.await.map_err(explain)?.into_inner();
    feeder.abort();
    print(j, json!({"stopped": true, "limit_mm": r.target_mm}), || {
        "jog stopped".to_string()
    });
    Ok(ExitCode::SUCCESS)
}

fn done<T>(j: bool, r: Result<tonic::Response<T>, tonic::Status>) -> Result<ExitCode, String> {
    r.map_err(explain)?;
    print(j, json!({"ok": true}), String::new);
    Ok(ExitCode::SUCCESS)
}

/// The library listing for people: `*` marks the selected program.
fn library_text(r: &pb::LibraryList) -> String {
    let mut out = format!(
        "{} programs, {} of {} bytes",
        r.programs.len(),
        r.used_bytes,
        r.max_bytes
    );
    for p in &r.programs {
        let when = p.modified_unix_ms / 1000;
        let verdict = if p.valid {
            format!("valid, {} warnings", p.warnings)
        } else {
            format!("{} errors: {}", p.errors, p.first_error)
        };
        out.push_str(&format!(
            "\n{} {:<30} {:>9} blocks {:>11} bytes  stored at {when} (Unix s)  {verdict}",
            if p.name == r.selected { "*" } else { " " },
            p.name,
            p.blocks,
            p.size_bytes,
        ));
    }
    out
}

/// Upload chunk size: well below the 4 MiB message limit.
const UPLOAD_CHUNK_BYTES: usize = 1 << 20;

/// Uploads `file` through Programs.Upload in chunks, read as it is sent (any size), with a
/// progress bar for the upload and then the validation; selects it when `select`.
async fn upload(
    g: &mut ProgramsClient<Svc>,
    file: &PathBuf,
    name: Option<String>,
    select: bool,
    quiet: bool,
) -> Result<pb::UploadDone, String> {
    use std::io::Read;
    let mut f =
        std::fs::File::open(file).map_err(|e| format!("cannot read {}: {e}", file.display()))?;
    let total = f.metadata().map(|m| m.len()).unwrap_or(0);
    let name = name.unwrap_or_else(|| {
        file.file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default()
    });
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(total)
    };
    bar.set_style(
        ProgressStyle::with_template("{msg:>10} [{bar:30}] {bytes}/{total_bytes} {bytes_per_sec}")
            .expect("static template"),
    );
    bar.set_message("upload");
    let (tx, rx) = tokio::sync::mpsc::channel::<pb::ProgramChunk>(4);
    let b = bar.clone();
    let reader = tokio::task::spawn_blocking(move || -> Result<(), String> {
        let mut first = Some((name, select, total));
        loop {
            let mut buf = vec![0u8; UPLOAD_CHUNK_BYTES];
            let n = f.read(&mut buf).map_err(|e| e.to_string())?;
            buf.truncate(n);
            let mut msg = pb::ProgramChunk {
                data: buf,
                ..Default::default()
            };
            if let Some((name, select, total)) = first.take() {
                msg.name = name;
                msg.select = select;
                msg.total_bytes = total;
            } else if n == 0 {
                return Ok(());
            }
            b.inc(n as u64);
            if tx.blocking_send(msg).is_err() {
                return Ok(()); // the server ended the call: its status says why
            }
        }
    });
    let mut replies = g
        .upload(tokio_stream::wrappers::ReceiverStream::new(rx))
        .await
        .map_err(explain)?
        .into_inner();
    let mut validating = false;
    while let Some(p) = replies.message().await.map_err(|e| {
        bar.abandon();
        explain(e)
    })? {
        if let Some(done) = p.done {
            bar.finish_and_clear();
            reader.await.map_err(|e| e.to_string())??;
            return Ok(done);
        }
        if p.blocks_validated > 0 {
            if !validating {
                validating = true;
                bar.set_style(
                    ProgressStyle::with_template("{msg:>10} {pos} blocks {per_sec}")
                        .expect("static template"),
                );
                bar.set_message("validate");
                bar.set_position(0);
            }
            bar.set_position(p.blocks_validated.into());
        }
    }
    Err("the daemon ended the upload without an answer".into())
}

/// Follows job `job` to its end. Exit code 0 when it ran to its end.
async fn follow(
    c: &mut MachineClient<Svc>,
    job: u32,
    quiet: bool,
    j: bool,
) -> Result<ExitCode, String> {
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
        let pos: Vec<String> = s.axes.iter().map(dro).collect();
        let block = s
            .block
            .map(|n| format!("N{n}"))
            .unwrap_or_else(|| "-".into());
        bar.set_message(format!("block {block} line {} {}", s.line, pos.join(" ")));
        if s.finished_job == job {
            bar.finish_and_clear();
            print(
                j,
                json!({"finished": true, "job": job, "status": status_json(&s)}),
                || format!("program finished: {}", status_line(&s)),
            );
            return Ok(ExitCode::SUCCESS);
        }
        if s.aborted_job == job || (s.job == job && s.state == pb::MachineState::Fault as i32) {
            bar.finish_and_clear();
            if j {
                println!(
                    "{}",
                    json!({"finished": false, "job": job, "status": status_json(&s)})
                );
            } else {
                eprintln!("program did not finish: {}", status_line(&s));
            }
            return Ok(ExitCode::FAILURE);
        }
    }
    Err("the daemon closed the status stream".into())
}

/// Streams the trajectory of `text` (the selected program when empty); writes the CSV to
/// `out` when given. Returns the total time and the number of ticks.
async fn trajectory(
    t: &mut TrajectoryClient<Svc>,
    text: String,
    out: Option<&std::path::Path>,
) -> Result<(f64, u64), String> {
    use std::io::Write;
    let mut stream = t
        .get_trajectory(pb::TrajectoryRequest { text })
        .await
        .map_err(explain)?
        .into_inner();
    let mut csv = match out {
        Some(p) => Some(std::io::BufWriter::new(
            std::fs::File::create(p).map_err(|e| format!("{}: {e}", p.display()))?,
        )),
        None => None,
    };
    let io = |e: std::io::Error| format!("writing the CSV: {e}");
    let (mut total_s, mut ticks) = (0.0, 0u64);
    while let Some(chunk) = stream.message().await.map_err(explain)? {
        if let Some(w) = csv.as_mut()
            && !chunk.axes.is_empty()
        {
            let names: Vec<String> = chunk.axes.iter().map(|a| format!("{a}_mm")).collect();
            writeln!(w, "t_s,{},path_v_mm_s,seq,block", names.join(",")).map_err(io)?;
        }
        for k in &chunk.ticks {
            ticks += 1;
            if let Some(w) = csv.as_mut() {
                let pos: Vec<String> = k.position_mm.iter().map(|p| format!("{p:.6}")).collect();
                let block = k.block.map(|n| n.to_string()).unwrap_or_default();
                writeln!(
                    w,
                    "{:.3},{},{:.6},{},{block}",
                    k.t_s,
                    pos.join(","),
                    k.path_v_mm_s,
                    k.seq
                )
                .map_err(io)?;
            }
        }
        if chunk.last {
            total_s = chunk.total_s;
        }
    }
    if let Some(mut w) = csv {
        w.flush().map_err(io)?;
    }
    Ok((total_s, ticks))
}
