//! The HMI's origin (issue #30, docs/hmi.md): static files with their content types and cache
//! policy, and the gRPC services over grpc-web with the API's roles and tokens, through the
//! door the browser uses (HTTP/1.1, grpc-web frames).

mod api_common;
mod hmi_common;

use api_common::{OPERATOR_TOKEN, config, with_token};
use daemon::runtime::config::Role;
use daemon::runtime::hmi::Assets;
use proto::v1 as pb;
use tonic::Code;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn static_files_have_their_types_and_cache_policy() {
    let h = hmi_common::start(config(Role::Admin)).await;
    let index = h.get("/", &[]).await;
    assert_eq!(index.status, 200);
    assert_eq!(index.header("content-type"), "text/html; charset=utf-8");
    assert_eq!(index.header("cache-control"), "no-cache");
    assert_eq!(index.header("x-content-type-options"), "nosniff");
    assert!(
        index.text().contains("cncd HMI test fixture"),
        "{}",
        index.text()
    );
    assert_eq!(h.get("/index.html", &[]).await.body, index.body);

    let js = h.get("/assets/app-5XCCWSTC.js", &[]).await;
    assert_eq!(js.status, 200);
    assert!(
        js.header("content-type").contains("javascript"),
        "{js:?}",
        js = js.headers
    );
    assert_eq!(
        js.header("cache-control"),
        "public, max-age=31536000, immutable"
    );
    let css = h.get("/style.css", &[]).await;
    assert_eq!(css.header("content-type"), "text/css; charset=utf-8");
    assert_eq!(css.header("cache-control"), "no-cache");

    // Revalidation: the same entity tag is a 304 without a body.
    let etag = index.header("etag").to_string();
    assert!(etag.starts_with('"'), "{etag}");
    let again = h.get("/", &[("if-none-match", &etag)]).await;
    assert_eq!(again.status, 304);
    assert!(again.body.is_empty());

    assert_eq!(h.get("/no/such/file.js", &[]).await.status, 404);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn without_assets_the_page_says_they_are_missing_and_grpc_web_still_works() {
    let h = hmi_common::start_with(config(Role::Admin), Assets::default()).await;
    let index = h.get("/", &[]).await;
    assert_eq!(index.status, 503);
    assert_eq!(index.header("content-type"), "text/html; charset=utf-8");
    assert!(
        index.text().contains("HMI assets are missing"),
        "{}",
        index.text()
    );
    let me = h
        .machine()
        .who_am_i(pb::WhoAmIRequest {})
        .await
        .unwrap()
        .into_inner();
    assert_eq!(me.role, "observer");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn who_am_i_is_observer_without_a_token_and_the_tokens_role_with_one() {
    let h = hmi_common::start(config(Role::Admin)).await;
    let mut m = h.machine();
    let me = m.who_am_i(pb::WhoAmIRequest {}).await.unwrap().into_inner();
    assert_eq!((me.role.as_str(), me.who.as_str()), ("observer", "local"));
    let me = m
        .who_am_i(with_token(pb::WhoAmIRequest {}, OPERATOR_TOKEN))
        .await
        .unwrap()
        .into_inner();
    assert_eq!((me.role.as_str(), me.who.as_str()), ("operator", "hmi-op"));
    let e = m
        .who_am_i(with_token(pb::WhoAmIRequest {}, "not-a-token"))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::Unauthenticated, "{e:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_observer_cannot_start_or_jog() {
    let h = hmi_common::start(config(Role::Admin)).await;
    let mut m = h.machine();
    let e = m.start(pb::StartRequest::default()).await.unwrap_err();
    assert_eq!(e.code(), Code::PermissionDenied, "{e:?}");
    let jog = pb::JogLeaseRequest {
        axis: "X".into(),
        direction: 1,
        speed_mm_min: 600.0,
        lease_ms: 0,
    };
    let e = m.jog_lease(jog).await.unwrap_err();
    assert_eq!(e.code(), Code::PermissionDenied, "{e:?}");
    let e = m.jog_stop(pb::JogStopRequest {}).await.unwrap_err();
    assert_eq!(e.code(), Code::PermissionDenied, "{e:?}");
    let e = h
        .programs()
        .upload_begin(pb::ProgramChunk {
            name: "p.nc".into(),
            ..Default::default()
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::PermissionDenied, "{e:?}");
    assert_eq!(h.ctl.snapshot().axes.commanded[0], 0.0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn status_streams_over_grpc_web() {
    let h = hmi_common::start(config(Role::Admin)).await;
    let mut s = h
        .machine()
        .stream_status(pb::StatusRequest { rate_hz: 50 })
        .await
        .unwrap()
        .into_inner();
    let first = s.message().await.unwrap().unwrap();
    let mut last = first.clone();
    for _ in 0..5 {
        last = s.message().await.unwrap().unwrap();
    }
    assert_eq!(first.axes.len(), 3);
    assert!(last.sequence > first.sequence, "{first:?} {last:?}");
    assert_eq!(last.state, pb::MachineState::Idle as i32);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_grpc_web_call_of_an_unknown_method_is_unimplemented() {
    let h = hmi_common::start(config(Role::Admin)).await;
    let (svc, origin) = hmi_common::web_channel(&h.base);
    let mut g = tonic::client::Grpc::with_origin(svc, origin);
    g.ready().await.unwrap();
    let codec = tonic_prost::ProstCodec::<pb::WhoAmIRequest, pb::WhoAmIReply>::default();
    let e = g
        .unary(
            tonic::Request::new(pb::WhoAmIRequest {}),
            "/cnc.v1.Nothing/Here".parse().unwrap(),
            codec,
        )
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::Unimplemented, "{e:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_non_loopback_hmi_without_tls_is_refused() {
    use daemon::runtime::server::{self, HmiListener, Listeners};
    let cfg = config(Role::Admin);
    let bus = sim::SimBus::new(sim::SimDriveParams::default(), &vec![0.0; cfg.axes.len()]);
    let ctl = daemon::runtime::controller::Controller::start_with_bus(
        cfg,
        daemon::runtime::controller::ClockKind::Monotonic,
        Box::new(bus),
    )
    .unwrap();
    // Bound, never connected to: only the address's kind matters.
    let listener = tokio::net::TcpListener::bind("0.0.0.0:0").await.unwrap();
    let hmi = HmiListener {
        listener,
        assets: std::sync::Arc::new(Assets::default()),
        tls: None,
    };
    let e = server::serve_with_hmi(ctl, Listeners::default(), None, Some(hmi), async {})
        .await
        .unwrap_err();
    assert_eq!(e.code(), "hmi_tls_required", "{e}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_hmi_listener_serves_over_tls() {
    use daemon::runtime::server::{self, HmiListener, Listeners};
    use tonic::transport::{Certificate, ClientTlsConfig, Endpoint, Identity, ServerTlsConfig};
    let cfg = config(Role::Admin);
    let bus = sim::SimBus::new(sim::SimDriveParams::default(), &vec![0.0; cfg.axes.len()]);
    let ctl = daemon::runtime::controller::Controller::start_with_bus(
        cfg,
        daemon::runtime::controller::ClockKind::Monotonic,
        Box::new(bus),
    )
    .unwrap();
    let cert = rcgen::generate_simple_self_signed(vec!["localhost".to_string()]).unwrap();
    let tls = ServerTlsConfig::new().identity(Identity::from_pem(
        cert.cert.pem(),
        cert.signing_key.serialize_pem(),
    ));
    // TLS as a non-loopback HMI address has it; bound on loopback to stay on this machine
    // (a non-loopback address without TLS is refused: the test above).
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let port = listener.local_addr().unwrap().port();
    let hmi = HmiListener {
        listener,
        assets: std::sync::Arc::new(hmi_common::fixture()),
        tls: Some(tls),
    };
    tokio::spawn(server::serve_with_hmi(
        ctl.clone(),
        Listeners::default(),
        None,
        Some(hmi),
        std::future::pending(),
    ));
    hmi_common::wait_state(&ctl, daemon::runtime::rt::MachineState::Idle).await;
    let client_tls = ClientTlsConfig::new()
        .ca_certificate(Certificate::from_pem(cert.cert.pem()))
        .domain_name("localhost");
    let channel = Endpoint::from_shared(format!("https://localhost:{port}"))
        .unwrap()
        .tls_config(client_tls)
        .unwrap()
        .connect()
        .await
        .unwrap();
    let mut m = pb::machine_client::MachineClient::new(channel);
    let me = m
        .who_am_i(with_token(pb::WhoAmIRequest {}, OPERATOR_TOKEN))
        .await
        .unwrap()
        .into_inner();
    assert_eq!(me.role, "operator");
}
