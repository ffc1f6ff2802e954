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

/// Connects to `--addr` (else `$CNCCTL_ADDR`, else the daemon of `--config`, else
/// [`default_addr`]) with `--token` (else `$CNCCTL_TOKEN`).
pub async fn connect(args: &Args) -> Result<Clients, CliError> {
    let addr = match args
        .addr
        .clone()
        .or_else(|| std::env::var("CNCCTL_ADDR").ok())
    {
        Some(a) => a,
        None => match &args.config {
            Some(file) => addr_of_config(file)?,
            None => default_addr(),
        },
    };
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

/// The daemon a configuration file configures: its Unix socket (relative to where cncctl runs,
/// as for cncd started here), else its `api.listen` address.
fn addr_of_config(file: &std::path::Path) -> Result<String, CliError> {
    let config = daemon::runtime::config::Config::load(file).map_err(|e| CliError::Config {
        path: file.to_owned(),
        reason: e.to_string(),
    })?;
    Ok(match daemon::runtime::discovery::socket_of(&config) {
        Some(p) => format!("unix:{}", p.display()),
        None => format!("http://{}", config.api.listen),
    })
}

/// Unix sockets tried when no address is given, in order: the data directory of a `cncd`
/// started in this directory, the one the last `cncd` of this user published (whatever its
/// data directory, docs/operator.md), the systemd unit's, the unit's state directory.
fn default_sockets() -> Vec<std::path::PathBuf> {
    let mut v = vec![std::path::PathBuf::from("cncd-data/cncd.sock")];
    v.extend(daemon::runtime::discovery::published());
    v.push("/run/cncd/cncd.sock".into());
    v.push("/var/lib/cncd/cncd.sock".into());
    v
}

/// The first default socket this user can connect to (the socket's mode and group grant
/// control), else loopback TCP (where callers without a token are observers by default).
fn default_addr() -> String {
    for path in default_sockets() {
        let path = path.as_path();
        if std::os::unix::net::UnixStream::connect(path).is_ok() {
            let abs = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
            return format!("unix:{}", abs.display());
        }
    }
    "http://127.0.0.1:50051".into()
}
