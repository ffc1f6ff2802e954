//! The command line: subcommands and global flags (docs/api.md lists them with examples).

use std::path::PathBuf;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "cncctl", version, about = "Command-line client of cncd")]
pub struct Args {
    /// Address of the daemon: http://HOST:PORT, https://HOST:PORT (TLS) or unix:/PATH
    /// [default: $CNCCTL_ADDR, else the daemon of --config, else the first Unix socket this
    /// user can open of ./cncd-data/cncd.sock, the socket published by the last cncd this user
    /// started ($XDG_RUNTIME_DIR/cncd/cncd.addr), /run/cncd/cncd.sock, /var/lib/cncd/cncd.sock,
    /// else http://127.0.0.1:50051 (observer only unless the daemon allows more)].
    #[arg(long, global = true)]
    pub addr: Option<String>,
    /// The daemon's configuration file: talk to the daemon it configures (its Unix socket, else
    /// its api.listen address).
    #[arg(long, global = true)]
    pub config: Option<PathBuf>,
    /// Bearer token (needed on remote listeners, or for a role above api.local_role)
    /// [default: $CNCCTL_TOKEN].
    #[arg(long, global = true)]
    pub token: Option<String>,
    /// CA certificate (PEM) to check the daemon's TLS certificate with.
    #[arg(long, global = true)]
    pub ca: Option<PathBuf>,
    /// Server name to check the TLS certificate against (default: the host of --addr).
    #[arg(long, global = true)]
    pub tls_domain: Option<String>,
    /// Machine-readable JSON output.
    #[arg(long, global = true)]
    pub json: bool,
    #[command(subcommand)]
    pub cmd: Cmd,
}

#[derive(Subcommand)]
pub enum Cmd {
    /// Load a program, start it, and follow it to its end with a progress bar.
    Run {
        file: PathBuf,
        /// No progress bar (for scripts): print one line at the end.
        #[arg(long)]
        quiet: bool,
        /// Program language: cnc836 or iso [default: by the file's name (*.ngc, *.tap,
        /// *.gcode are ISO), else the machine's [program] dialect].
        #[arg(long)]
        dialect: Option<String>,
    },
    /// Upload, validate and select a program without starting it.
    Load {
        file: PathBuf,
        /// Program language: cnc836 or iso [default: by the file's name (*.ngc, *.tap,
        /// *.gcode are ISO), else the machine's [program] dialect].
        #[arg(long)]
        dialect: Option<String>,
    },
    /// Validate a program only: every error and warning with block and line.
    Validate {
        file: PathBuf,
        /// Program language: cnc836 or iso [default: by the file's name (*.ngc, *.tap,
        /// *.gcode are ISO), else the machine's [program] dialect].
        #[arg(long)]
        dialect: Option<String>,
    },
    /// The R325 listing: the program with the circle refinements written as address E.
    Refine {
        file: PathBuf,
        /// Program language: cnc836 or iso [default: by the file's name (*.ngc, *.tap,
        /// *.gcode are ISO), else the machine's [program] dialect].
        #[arg(long)]
        dialect: Option<String>,
    },
    /// Store a program on the daemon without selecting it.
    Upload {
        file: PathBuf,
        /// Name to store it under (default: the file name).
        #[arg(long)]
        name: Option<String>,
        /// Program language: cnc836 or iso [default: by the file's name (*.ngc, *.tap,
        /// *.gcode are ISO), else the machine's [program] dialect].
        #[arg(long)]
        dialect: Option<String>,
    },
    /// Select a stored program.
    Select {
        name: String,
        /// Program language, kept by the library from now on: cnc836 or iso [default: as
        /// stored].
        #[arg(long)]
        dialect: Option<String>,
    },
    /// The dry run: the program's interpreted moves, with the machine's axes, constants,
    /// offsets and work offsets, from machine zero, without moving anything (docs/language.md
    /// "The dry run"). With --json one JSON object per move and line; the messages go to
    /// standard error; exit 1 when the program has an error.
    Interpret {
        /// Program file [default: the selected program, or --stored NAME].
        file: Option<PathBuf>,
        /// A program of the daemon's library instead of a file.
        #[arg(long, value_name = "NAME", conflicts_with = "file")]
        stored: Option<String>,
        /// Start where the axes are (as a start now would) instead of machine zero.
        #[arg(long)]
        from_position: bool,
        /// Program language: cnc836 or iso [default: by the file's name (*.ngc, *.tap,
        /// *.gcode are ISO), else the machine's [program] dialect].
        #[arg(long)]
        dialect: Option<String>,
    },
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
    /// Start the selected program (or restart it from block N: docs/operator.md).
    Start {
        /// Restart from the block numbered N: the blocks before it set the modal state
        /// without motion, an approach (retract, over, down at feed) leads to its start.
        #[arg(long, value_name = "N")]
        from_block: Option<u32>,
        /// Confirm the approach of `--from-block` without asking.
        #[arg(long, short = 'y')]
        yes: bool,
    },
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
    /// Block delete on or off: when on, blocks starting with `/` are skipped.
    BlockDelete {
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
    Mdi {
        block: String,
        /// Its language: cnc836 or iso [default: the machine's [program] dialect].
        #[arg(long)]
        dialect: Option<String>,
    },
    /// Show the machine status.
    Status {
        /// Follow the status until interrupted: refreshed in place on a terminal, one line per
        /// update into a pipe or a file (one JSON object a line with --json).
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
    /// Touch-off (docs/setup.md): set entry ENTRY's length of AXIS so that where the axis
    /// stands reads VALUE in program coordinates (file and memory): `touch-off 1 X 0`.
    #[command(allow_negative_numbers = true)]
    TouchOff {
        entry: u32,
        /// The axis letter (axes 1..4).
        axis: String,
        /// What the present position shall read, mm.
        value: f64,
        /// Also set the entry's radius, mm.
        #[arg(long)]
        radius: Option<f64>,
        /// Take this work offset system's offset of the axis off too (ISO programs): G54 ...
        #[arg(long)]
        work: Option<String>,
    },
    /// Print the TAB0.KOR file.
    OffsetsFile,
    /// Replace TAB0.KOR with a file (validated; a refused file changes nothing). Only if the
    /// file on disk is still of the revision `--revision` (as `--json offsets-file` showed
    /// it), else of the revision read just before: a hand edit saved in between is refused
    /// with `storage_file_changed`.
    OffsetsReplace {
        file: PathBuf,
        #[arg(long)]
        revision: Option<String>,
    },
    /// Reload the offset table from its file (drops G92 changes).
    OffsetsReload,
    /// The work offsets G54..G59.3 of ISO programs (the file in the daemon's storage dir).
    WorkOffsets,
    /// Set axes of one work offset system in its file: `work-offset-set G55 X10 Y-2.5`
    /// (the other axes keep their value; in force from the next program start).
    #[command(allow_negative_numbers = true)]
    WorkOffsetSet {
        /// G54 .. G59, G59.1 .. G59.3.
        system: String,
        /// Axis letter and value in mm: X10, Y-2.5 (or X=10).
        #[arg(required = true, allow_hyphen_values = true)]
        values: Vec<String>,
    },
    /// The machine's inputs and outputs (docs/io.md): list them, watch them, force an
    /// output (admin), set a simulated input (admin, simulated machine only).
    Io {
        #[command(subcommand)]
        cmd: Option<IoCmd>,
        /// Print the list again whenever a value changes (Ctrl-C ends).
        #[arg(long)]
        watch: bool,
    },
    /// Probing (docs/setup.md): a probing move, or a workflow writing an entry of TAB0.KOR.
    Probe {
        #[command(subcommand)]
        cmd: ProbeCmd,
    },
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
        /// Program language: cnc836 or iso [default: by the file's name (*.ngc, *.tap,
        /// *.gcode are ISO), else the machine's [program] dialect].
        #[arg(long)]
        dialect: Option<String>,
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
        /// Program language: cnc836 or iso [default: by the file's name (*.ngc, *.tap,
        /// *.gcode are ISO), else the machine's [program] dialect].
        #[arg(long)]
        dialect: Option<String>,
    },
    /// The planned per-tick trajectory of a program file (or of the selected program) on the
    /// daemon, without moving the machine: total time, and with -o a CSV of every tick
    /// (time, setpoints, path speed, block) for plotting.
    Trajectory {
        file: Option<PathBuf>,
        /// The trajectory of a restart from block N, approach first.
        #[arg(long, value_name = "N")]
        from_block: Option<u32>,
        /// CSV output file.
        #[arg(short = 'o', long)]
        out: Option<PathBuf>,
        /// Program language: cnc836 or iso [default: by the file's name, else the machine's
        /// [program] dialect; the selected program: its own].
        #[arg(long)]
        dialect: Option<String>,
    },
    /// grpc.health.v1 status of the daemon.
    Health,
    /// Print the SHA-256 of a token, for `[[api.tokens]] sha256 = ...`.
    HashToken { token: String },
}

#[derive(Subcommand)]
pub enum ProbeCmd {
    /// A probing move: AXIS moves DISTANCE (signed, mm) until the probe touches; prints the
    /// positions taken at the contact.
    #[command(allow_negative_numbers = true)]
    Move {
        axis: String,
        distance: f64,
        /// mm/min (default `[probe] search_feed_mm_min`).
        #[arg(long, default_value_t = 0.0)]
        feed: f64,
        /// Move away from a contact until the probe releases.
        #[arg(long)]
        away: bool,
    },
    /// The tool on the tool setter: writes entry ENTRY's Z length (the tool's length unless
    /// `--value` says what the setter's top reads).
    #[command(allow_negative_numbers = true)]
    ToolSetter {
        entry: u32,
        #[arg(long)]
        value: Option<f64>,
        /// As touch-off's `--work`.
        #[arg(long)]
        work: Option<String>,
    },
    /// An edge: touches along AXIS in DIRECTION (+ or -) and writes entry ENTRY's length of
    /// AXIS so that the edge reads `--value` (default 0).
    #[command(allow_negative_numbers = true)]
    Edge {
        entry: u32,
        axis: String,
        #[arg(allow_hyphen_values = true)]
        direction: String,
        #[arg(long)]
        value: Option<f64>,
        #[arg(long)]
        work: Option<String>,
    },
    /// A bore's centre, from inside it: writes entry ENTRY's X and Y lengths so that the
    /// centre reads `--x`, `--y` (default 0).
    #[command(allow_negative_numbers = true)]
    Bore {
        entry: u32,
        #[arg(long)]
        x: Option<f64>,
        #[arg(long)]
        y: Option<f64>,
        #[arg(long)]
        work: Option<String>,
    },
}

#[derive(Subcommand)]
pub enum IoCmd {
    /// Every input and output with its function, wiring and value.
    List,
    /// Force an output to 0 or 1 for commissioning, or `release` it (admin role; Reset
    /// releases every forced output).
    Force { name: String, value: String },
    /// Set an input of the simulated machine to 0 or 1, or `release` it to the model
    /// (admin role; refused on a real bus).
    SimSet { name: String, value: String },
}

#[derive(Subcommand)]
pub enum PlcCmd {
    /// Every cell with unit, access and value.
    List,
    /// Read cells by name (AKRR_V) or address (0xA19C).
    Read { cells: Vec<String> },
    /// Write one input cell.
    Write { cell: String, value: i64 },
}

#[derive(Subcommand)]
pub enum ConstCmd {
    /// Read constants (all set or with a default when none are named), decades decoded.
    /// Constants by number, `384` or `R384`.
    Get { numbers: Vec<String> },
    /// Set constants: `R39=45 R384=20.0` (admin role).
    Set { values: Vec<String> },
}
