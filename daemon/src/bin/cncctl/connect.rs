//! The connection to the daemon: address, TLS, bearer token, one client per gRPC service.

use std::time::Duration;

use proto::v1::constants_client::ConstantsClient;
use proto::v1::machine_client::MachineClient;
use proto::v1::offsets_client::OffsetsClient;
use proto::v1::plc_client::PlcClient;
use proto::v1::preview_client::PreviewClient;
use proto::v1::programs_client::ProgramsClient;
use proto::v1::trajectory_client::TrajectoryClient;
use tonic::metadata::{Ascii, MetadataValue};
use tonic::service::Interceptor;
use tonic::service::interceptor::InterceptedService;
use tonic::transport::{Certificate, Channel, ClientTlsConfig, Endpoint};
use tonic_health::pb::health_client::HealthClient;

use crate::args::Args;
use crate::error::CliError;

/// Adds the bearer token to every call.
#[derive(Clone)]
pub struct Token(Option<MetadataValue<Ascii>>);

impl Interceptor for Token {
    fn call(&mut self, mut req: tonic::Request<()>) -> Result<tonic::Request<()>, tonic::Status> {
        if let Some(t) = &self.0 {
            req.metadata_mut().insert("authorization", t.clone());
        }
        Ok(req)
    }
}

pub type Svc = InterceptedService<Channel, Token>;

/// One client per service, sharing the channel and the token.
pub struct Clients {
    pub machine: MachineClient<Svc>,
    pub programs: ProgramsClient<Svc>,
    pub offsets: OffsetsClient<Svc>,
    pub plc: PlcClient<Svc>,
    pub constants: ConstantsClient<Svc>,
    pub preview: PreviewClient<Svc>,
    pub trajectory: TrajectoryClient<Svc>,
    pub health: HealthClient<Svc>,
}

/// Connects to `--addr` (else `$CNCCTL_ADDR`, else [`default_addr`]) with `--token` (else
/// `$CNCCTL_TOKEN`).
pub async fn connect(args: &Args) -> Result<Clients, CliError> {
    let addr = args
        .addr
        .clone()
        .or_else(|| std::env::var("CNCCTL_ADDR").ok())
        .unwrap_or_else(default_addr);
    let token_text = args
        .token
        .clone()
        .or_else(|| std::env::var("CNCCTL_TOKEN").ok());
    let ch = endpoint(args, &addr)?
        .connect_timeout(Duration::from_secs(5))
        .connect()
        .await
        .map_err(|e| CliError::Unreachable {
            addr: addr.clone(),
            reason: e.to_string(),
        })?;
    let token = Token(match &token_text {
        Some(t) => Some(
            format!("Bearer {t}")
                .parse()
                .map_err(|_| CliError::TokenNotAscii)?,
        ),
        None => None,
    });
    let svc = || InterceptedService::new(ch.clone(), token.clone());
    Ok(Clients {
        machine: MachineClient::new(svc()),
        programs: ProgramsClient::new(svc()),
        offsets: OffsetsClient::new(svc()),
        plc: PlcClient::new(svc()),
        constants: ConstantsClient::new(svc()),
        preview: PreviewClient::new(svc()),
        trajectory: TrajectoryClient::new(svc()),
        health: HealthClient::new(svc()),
    })
}

/// The endpoint of `addr`, with TLS (`--ca`, `--tls-domain`) on an `https://` address.
fn endpoint(args: &Args, addr: &str) -> Result<Endpoint, CliError> {
    let ep = Endpoint::from_shared(addr.to_string()).map_err(|e| CliError::BadAddress {
        addr: addr.to_string(),
        reason: e.to_string(),
    })?;
    if !addr.starts_with("https://") {
        return Ok(ep);
    }
    let mut tls = ClientTlsConfig::new();
    if let Some(ca) = &args.ca {
        let pem = std::fs::read(ca).map_err(CliError::read(ca))?;
        tls = tls.ca_certificate(Certificate::from_pem(pem));
    }
    if let Some(d) = &args.tls_domain {
        tls = tls.domain_name(d.clone());
    }
    ep.tls_config(tls).map_err(|e| CliError::Tls(e.to_string()))
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
