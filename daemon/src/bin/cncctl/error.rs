//! What can go wrong in `cncctl`, each with a stable code (scripts and tests match the code;
//! the message, printed as `cncctl: <message>`, may improve).

use std::path::PathBuf;

use crate::render::explain;

#[derive(Debug, thiserror::Error)]
pub enum CliError {
    #[error("bad address {addr}: {reason}")]
    BadAddress { addr: String, reason: String },
    #[error("TLS: {0}")]
    Tls(String),
    #[error("--config {}: {reason}", path.display())]
    Config { path: PathBuf, reason: String },
    #[error("cannot reach cncd at {addr}: {reason}")]
    Unreachable { addr: String, reason: String },
    #[error("the token must be printable ASCII")]
    TokenNotAscii,
    #[error("cannot read {}: {source}", path.display())]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot write {}: {source}", path.display())]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// Writing a downloaded program to its sink failed.
    #[error("{0}")]
    Output(#[source] std::io::Error),
    #[error("{}: {source}", path.display())]
    CsvCreate {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("writing the CSV: {0}")]
    Csv(#[source] std::io::Error),
    /// The daemon refused a call: the status and every diagnostic it carried.
    #[error("{}", explain(.0))]
    Rpc(Box<tonic::Status>),
    #[error("the daemon closed the status stream")]
    StatusStreamClosed,
    #[error("the daemon ended the upload without an answer")]
    UploadUnanswered,
    /// The local file reader of an upload stopped (reading the file or the task itself).
    #[error("{0}")]
    UploadReader(String),
    #[error("{arg:?}: give an axis letter, e.g. X+ or Z-")]
    JogAxis { arg: String },
    #[error("a continuous jog needs a direction: X+ or X-")]
    JogDirection,
    #[error("{0:?}: give 0, 1 or release")]
    IoLevel(String),
    #[error("plane {0}: use xy, xz or yz")]
    Plane(String),
    #[error("{0}: write Rnnn=value")]
    ConstantSyntax(String),
    #[error("{0}: bad number")]
    ConstantNumber(String),
    #[error("{0}: bad value")]
    ConstantValue(String),
    /// A local preview refused the program: one diagnostic a line.
    #[error("{}: rejected{}", file.display(), lines.iter().map(|l| format!("\n  {l}")).collect::<String>())]
    PreviewRejected { file: PathBuf, lines: Vec<String> },
    #[error("{0}")]
    Png(String),
    #[error("not started: confirm the approach with --yes (or y at the prompt)")]
    NotConfirmed,
    #[error("--dialect: {0}")]
    Dialect(#[from] daemon::runtime::dialect::UnknownDialect),
    #[error("{0:?}: give an axis letter and a value in mm, e.g. X10 or Y-2.5")]
    AxisValue(String),
    #[error("{0:?}: give the direction of the touch, + or -")]
    ProbeDirection(String),
}

impl CliError {
    /// Stable code (tests match it; the message may improve). cncctl prints the message only,
    /// so that scripts reading standard error see what they always saw.
    #[cfg_attr(not(test), allow(dead_code))]
    pub fn code(&self) -> &'static str {
        match self {
            CliError::BadAddress { .. } => "cli_bad_address",
            CliError::Tls(_) => "cli_tls",
            CliError::Config { .. } => "cli_config",
            CliError::Unreachable { .. } => "cli_unreachable",
            CliError::TokenNotAscii => "cli_token_not_ascii",
            CliError::Read { .. } => "cli_read",
            CliError::Write { .. } => "cli_write",
            CliError::Output(_) => "cli_output",
            CliError::CsvCreate { .. } => "cli_csv_create",
            CliError::Csv(_) => "cli_csv",
            CliError::Rpc(_) => "cli_rpc",
            CliError::StatusStreamClosed => "cli_status_stream_closed",
            CliError::UploadUnanswered => "cli_upload_unanswered",
            CliError::UploadReader(_) => "cli_upload_reader",
            CliError::JogAxis { .. } => "cli_jog_axis",
            CliError::JogDirection => "cli_jog_direction",
            CliError::Plane(_) => "cli_plane",
            CliError::ConstantSyntax(_) => "cli_constant_syntax",
            CliError::IoLevel(_) => "cli_io_level",
            CliError::ConstantNumber(_) => "cli_constant_number",
            CliError::ConstantValue(_) => "cli_constant_value",
            CliError::PreviewRejected { .. } => "cli_preview_rejected",
            CliError::Png(_) => "cli_png",
            CliError::NotConfirmed => "cli_not_confirmed",
            CliError::Dialect(_) => "cli_dialect",
            CliError::AxisValue(_) => "cli_axis_value",
            CliError::ProbeDirection(_) => "cli_probe_direction",
        }
    }

    pub fn read(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> CliError {
        let path = path.to_path_buf();
        move |source| CliError::Read { path, source }
    }

    pub fn write(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> CliError {
        let path = path.to_path_buf();
        move |source| CliError::Write { path, source }
    }
}

impl From<tonic::Status> for CliError {
    fn from(s: tonic::Status) -> Self {
        CliError::Rpc(Box::new(s))
    }
}
