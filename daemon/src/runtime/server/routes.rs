//! Every service of the API on one router behind a listener's interceptor: the `cnc.v1`
//! services, health, both reflection versions, and the refusal of oversized messages.

use std::sync::Arc;

use proto::v1::constants_server::ConstantsServer;
use proto::v1::machine_server::MachineServer;
use proto::v1::offsets_server::OffsetsServer;
use proto::v1::plc_server::PlcServer;
use proto::v1::preview_server::PreviewServer;
use proto::v1::programs_server::ProgramsServer;
use proto::v1::trajectory_server::TrajectoryServer;
use tonic::service::Routes;
use tonic::service::interceptor::InterceptedService;
use tonic::transport::server::Router;
use tonic::transport::{Server, ServerTlsConfig};

use super::ServerError;
use crate::runtime::api::auth::{Auth, Trust};
use crate::runtime::api::{
    ApiState, ConstantsSvc, MachineSvc, OffsetsSvc, PlcSvc, PreviewSvc, ProgramsSvc, TrajectorySvc,
};

/// Largest unary request message, bytes (the gRPC default, stated). Programs of any size go
/// through the client-streaming `Programs.Upload` in chunks below this.
pub const MAX_MESSAGE_BYTES: usize = 4 << 20;

/// tonic refuses an oversized message with OUT_OF_RANGE and a transport-level text; clients
/// get RESOURCE_EXHAUSTED with the limit and what to use instead.
pub fn size_refusal<B>(mut r: http::Response<B>) -> http::Response<B> {
    let h = r.headers_mut();
    let too_large = h.get("grpc-status").is_some_and(|v| v == "11")
        && h.get("grpc-message").is_some_and(|m| {
            String::from_utf8_lossy(m.as_bytes())
                .replace("%20", " ")
                .contains("message length too large")
        });
    if too_large {
        let msg = format!(
            "the request is larger than {} MiB, the limit of one message (docs/api.md): upload \
             programs with Programs.Upload (cncctl load/upload/run do)",
            MAX_MESSAGE_BYTES >> 20
        );
        h.insert("grpc-status", http::HeaderValue::from_static("8"));
        if let Ok(v) = http::HeaderValue::from_str(&msg.replace('%', "%25")) {
            h.insert("grpc-message", v);
        }
    }
    r
}

type SizeLayer = tower::util::MapResponseLayer<
    fn(http::Response<tonic::body::Body>) -> http::Response<tonic::body::Body>,
>;
type ApiRouter = Router<tower::layer::util::Stack<SizeLayer, tower::layer::util::Identity>>;

pub(crate) type Health<H> = tonic_health::pb::health_server::HealthServer<H>;

pub(super) fn router<H: tonic_health::pb::health_server::Health>(
    st: &Arc<ApiState>,
    auth: &Arc<Auth>,
    trust: Trust,
    tls: Option<ServerTlsConfig>,
    health: &Health<H>,
) -> Result<ApiRouter, ServerError> {
    let mut b = Server::builder();
    if let Some(t) = tls {
        b = b
            .tls_config(t)
            .map_err(|e| ServerError::Tls(e.to_string()))?;
    }
    let layer: SizeLayer = tower::util::MapResponseLayer::new(size_refusal);
    Ok(b.layer(layer).add_routes(routes(st, auth, trust, health)?))
}

/// What the HMI's listener serves: every service behind the interceptor of kind `trust` over
/// grpc-web with the message-size refusal, and `assets` for everything else (also the
/// grpc-web fuzz target's service, so it fuzzes exactly this stack).
pub(crate) fn hmi_routes<H: tonic_health::pb::health_server::Health>(
    st: &Arc<ApiState>,
    auth: &Arc<Auth>,
    trust: Trust,
    health: &Health<H>,
    assets: Arc<crate::runtime::hmi::Assets>,
) -> Result<Routes, ServerError> {
    Ok(crate::runtime::hmi::app(
        routes(st, auth, trust, health)?,
        tower::util::MapResponseLayer::new(size_refusal::<axum::body::Body>),
        assets,
    ))
}

/// Every service of the API behind the interceptor of a listener of kind `trust`.
pub(super) fn routes<H: tonic_health::pb::health_server::Health>(
    st: &Arc<ApiState>,
    auth: &Arc<Auth>,
    trust: Trust,
    health: &Health<H>,
) -> Result<Routes, ServerError> {
    let i = auth.interceptor(trust);
    // Both reflection versions: grpcurl speaks v1, Python's grpcio-reflection and many older
    // tools only v1alpha.
    let reflection_builder = || {
        tonic_reflection::server::Builder::configure()
            .register_encoded_file_descriptor_set(proto::FILE_DESCRIPTOR_SET)
            .register_encoded_file_descriptor_set(tonic_health::pb::FILE_DESCRIPTOR_SET)
            .register_encoded_file_descriptor_set(tonic_reflection::pb::v1::FILE_DESCRIPTOR_SET)
            .register_encoded_file_descriptor_set(
                tonic_reflection::pb::v1alpha::FILE_DESCRIPTOR_SET,
            )
    };
    let reflection = reflection_builder()
        .build_v1()
        .map_err(|e| ServerError::Reflection(e.to_string()))?;
    let reflection_alpha = reflection_builder()
        .build_v1alpha()
        .map_err(|e| ServerError::Reflection(e.to_string()))?;
    let m = MAX_MESSAGE_BYTES;
    let mut rb = Routes::builder();
    rb.add_service(InterceptedService::new(
        MachineServer::new(MachineSvc(st.clone())).max_decoding_message_size(m),
        i.clone(),
    ))
    .add_service(InterceptedService::new(
        OffsetsServer::new(OffsetsSvc(st.clone())).max_decoding_message_size(m),
        i.clone(),
    ))
    .add_service(InterceptedService::new(
        PlcServer::new(PlcSvc(st.clone())).max_decoding_message_size(m),
        i.clone(),
    ))
    .add_service(InterceptedService::new(
        ConstantsServer::new(ConstantsSvc(st.clone())).max_decoding_message_size(m),
        i.clone(),
    ))
    .add_service(InterceptedService::new(
        PreviewServer::new(PreviewSvc(st.clone())).max_decoding_message_size(m),
        i.clone(),
    ))
    .add_service(InterceptedService::new(
        TrajectoryServer::new(TrajectorySvc(st.clone())).max_decoding_message_size(m),
        i.clone(),
    ))
    .add_service(InterceptedService::new(
        ProgramsServer::new(ProgramsSvc(st.clone())).max_decoding_message_size(m),
        i.clone(),
    ))
    .add_service(InterceptedService::new(health.clone(), i.clone()))
    .add_service(InterceptedService::new(reflection, i.clone()))
    .add_service(InterceptedService::new(reflection_alpha, i));
    Ok(rb.routes())
}
