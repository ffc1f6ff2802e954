//! Access control: each role boundary (observer / operator / admin), unknown tokens, the
//! remote listener (TLS, token required) and the Unix socket.

mod api_common;

use api_common::*;
use daemon::runtime::config::{Config, Role};
use proto::v1 as pb;
use proto::v1::constants_client::ConstantsClient;
use proto::v1::machine_client::MachineClient;
use proto::v1::offsets_client::OffsetsClient;
use proto::v1::plc_client::PlcClient;
use tonic::Code;

fn write_dynam(v: i64) -> pb::WriteCellRequest {
    pb::WriteCellRequest {
        cell: Some(pb::CellRef {
            cell: Some(pb::cell_ref::Cell::Name("DYNAM_SET".into())),
        }),
        value: v,
    }
}

fn set_r39(v: f64) -> pb::SetConstantsRequest {
    constant_values(&[(39, v)])
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn roles_observer_operator_admin() {
    // Local callers without a token are observers here.
    let d = start(config(Role::Observer)).await;
    let ch = d.channel().await;
    let mut m = MachineClient::new(ch.clone());
    let mut o = OffsetsClient::new(ch.clone());
    let mut p = PlcClient::new(ch.clone());
    let mut k = ConstantsClient::new(ch.clone());

    // Observer: reads work, writes are PERMISSION_DENIED.
    m.list_programs(pb::ListProgramsRequest {}).await.unwrap();
    m.validate_program(pb::ValidateProgramRequest {
        text: "G1 X1 F100".into(),
        dialect: String::new(),
    })
    .await
    .unwrap();
    let mut s = m
        .stream_status(pb::StatusRequest { rate_hz: 10 })
        .await
        .unwrap()
        .into_inner();
    s.message().await.unwrap().unwrap();
    o.get_offsets(pb::GetOffsetsRequest::default())
        .await
        .unwrap();
    p.list_cells(pb::ListCellsRequest {}).await.unwrap();
    k.get_constants(pb::GetConstantsRequest::default())
        .await
        .unwrap();
    let denied = [
        m.start(pb::StartRequest::default()).await.unwrap_err(),
        m.stop(pb::StopRequest {}).await.unwrap_err(),
        m.hold(pb::HoldRequest {}).await.unwrap_err(),
        m.set_override(pb::SetOverrideRequest { percent: 50.0 })
            .await
            .unwrap_err(),
        m.mdi(mdi_block("G1 X1 F100")).await.unwrap_err(),
        m.load_program(named_program("a", "G1 X1 F100"))
            .await
            .unwrap_err(),
        o.set_offset(pb::SetOffsetRequest {
            entry: 1,
            radius_mm: Some(1.0),
            ..Default::default()
        })
        .await
        .unwrap_err(),
        o.replace_offsets_file(pb::OffsetsFile {
            text: "$KOR\n".into(),
            revision: String::new(),
        })
        .await
        .unwrap_err(),
        p.write_cell(write_dynam(1)).await.unwrap_err(),
        k.set_constants(set_r39(45.0)).await.unwrap_err(),
    ];
    for e in &denied {
        assert_eq!(e.code(), Code::PermissionDenied, "{e:?}");
    }
    // Nothing changed.
    assert_eq!(d.ctl.snapshot().plc.read_by_name("DYNAM_SET"), Ok(0));
    assert!(d.ctl.program().is_none());

    // Operator token: programs, offsets, PLC; not constants.
    m.load_program(with_token(
        named_program("a", "G1 X1 F3000"),
        OPERATOR_TOKEN,
    ))
    .await
    .unwrap();
    o.set_offset(with_token(
        pb::SetOffsetRequest {
            entry: 1,
            radius_mm: Some(1.0),
            ..Default::default()
        },
        OPERATOR_TOKEN,
    ))
    .await
    .unwrap();
    p.write_cell(with_token(write_dynam(1), OPERATOR_TOKEN))
        .await
        .unwrap();
    let e = k
        .set_constants(with_token(set_r39(45.0), OPERATOR_TOKEN))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::PermissionDenied);
    assert_eq!(d.ctl.constants().get(39), 60.0);

    // Observer token explicitly: same as observer.
    let e = m
        .start(with_token(pb::StartRequest::default(), OBSERVER_TOKEN))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::PermissionDenied);

    // Admin token: constants too (and everything below).
    k.set_constants(with_token(set_r39(45.0), ADMIN_TOKEN))
        .await
        .unwrap();
    assert_eq!(d.ctl.constants().get(39), 45.0);
    m.start(with_token(pb::StartRequest::default(), ADMIN_TOKEN))
        .await
        .unwrap();

    // Unknown token: UNAUTHENTICATED even for reads on a local listener.
    let e = m
        .list_programs(with_token(pb::ListProgramsRequest {}, "guess"))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::Unauthenticated);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn remote_listener_needs_tls_and_a_token() {
    let d = start(config(Role::Admin)).await;
    let ch = d.tls_channel().await;
    let mut m = MachineClient::new(ch.clone());
    let mut k = ConstantsClient::new(ch);
    // No token: refused, whatever local_role says.
    let e = m
        .list_programs(pb::ListProgramsRequest {})
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::Unauthenticated);
    let e = m
        .stream_status(pb::StatusRequest { rate_hz: 10 })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::Unauthenticated);
    // Observer token: reads yes, control no.
    m.list_programs(with_token(pb::ListProgramsRequest {}, OBSERVER_TOKEN))
        .await
        .unwrap();
    let e = m
        .set_override(with_token(
            pb::SetOverrideRequest { percent: 80.0 },
            OBSERVER_TOKEN,
        ))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::PermissionDenied);
    m.set_override(with_token(
        pb::SetOverrideRequest { percent: 80.0 },
        OPERATOR_TOKEN,
    ))
    .await
    .unwrap();
    let e = k
        .set_constants(with_token(set_r39(50.0), OPERATOR_TOKEN))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::PermissionDenied);
    k.set_constants(with_token(set_r39(50.0), ADMIN_TOKEN))
        .await
        .unwrap();

    // Plain text to the TLS listener does not get through.
    let plain = format!("http://{}", d.remote.trim_start_matches("https://"));
    let r = async {
        let ch = tonic::transport::Channel::from_shared(plain)
            .unwrap()
            .connect()
            .await?;
        MachineClient::new(ch)
            .list_programs(with_token(pb::ListProgramsRequest {}, ADMIN_TOKEN))
            .await
            .map_err(|e| e.into())
            .map(|_| ())
    };
    let r: Result<(), Box<dyn std::error::Error>> =
        tokio::time::timeout(std::time::Duration::from_secs(5), r)
            .await
            .unwrap_or(Err("timeout".into()));
    assert!(r.is_err(), "plain-text call succeeded on the TLS listener");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn unix_socket_is_local_with_mode_0660() {
    use std::os::unix::fs::PermissionsExt;
    let d = start(config(Role::Operator)).await;
    let mode = std::fs::metadata(&d.unix).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o660);
    let mut m = MachineClient::new(d.unix_channel().await);
    m.set_override(pb::SetOverrideRequest { percent: 90.0 })
        .await
        .unwrap();
    let mut k = ConstantsClient::new(d.unix_channel().await);
    let e = k.set_constants(set_r39(50.0)).await.unwrap_err();
    assert_eq!(e.code(), Code::PermissionDenied, "local role is operator");
}

#[test]
fn config_requires_tls_and_tokens_off_loopback() {
    let p = std::path::Path::new("t.toml");
    let e = Config::parse("[api]\nextra_listen = [\"0.0.0.0:50052\"]\n", p).unwrap_err();
    assert!(e.to_string().contains("api.tls_cert"), "{e}");
    let e = Config::parse(
        "[api]\nlisten = \"0.0.0.0:50051\"\ntls_cert = \"c.pem\"\ntls_key = \"k.pem\"\n",
        p,
    )
    .unwrap_err();
    assert!(e.to_string().contains("api.tokens"), "{e}");
    let e = Config::parse(
        "[api]\n[[api.tokens]]\nname = \"a\"\nrole = \"admin\"\nsha256 = \"xyz\"\n",
        p,
    )
    .unwrap_err();
    assert!(e.to_string().contains("api.tokens[0].sha256"), "{e}");
    let e = Config::parse(
        "[api]\n[[api.tokens]]\nname = \"a\"\nrole = \"root\"\nsha256 = \"00\"\n",
        p,
    )
    .unwrap_err();
    assert!(
        e.to_string().contains("role") || e.to_string().contains("root"),
        "{e}"
    );
    let ok = Config::parse(
        &format!(
            "[api]\nlisten = \"0.0.0.0:50051\"\ntls_cert = \"c.pem\"\ntls_key = \"k.pem\"\nsocket_mode = 0o600\nsocket_group = \"cnc\"\nlocal_role = \"operator\"\n[[api.tokens]]\nname = \"hmi\"\nrole = \"observer\"\nsha256 = \"{}\"\n",
            daemon::runtime::api::auth::hash_token_hex("t")
        ),
        p,
    )
    .unwrap();
    assert_eq!(ok.api.socket_mode, 0o600);
    assert_eq!(ok.api.tokens[0].role, Role::Observer);
}
