//! The MTConnect agent beyond the machine (issue #33): a non-loopback `[mtconnect] listen` is
//! served over TLS with the API's certificate, through the real `cncd` and a TLS client that
//! trusts only that certificate; plain HTTP on that port gets no document; and without a
//! certificate cncd refuses the configuration (`config_missing`, naming `mtconnect.listen`).

mod operator_support;

use std::sync::Arc;

use bytes::Bytes;
use http_body_util::{BodyExt, Empty};
use operator_support::*;
use tokio_rustls::rustls;
use tokio_rustls::rustls::pki_types::{CertificateDer, ServerName, pem::PemObject};

/// The mill of the operator tests with the agent on every address at `port`.
fn toml(port: u16, tls: bool) -> String {
    let api_tls = if tls {
        "tls_cert = \"cert.pem\"\ntls_key = \"key.pem\"\n"
    } else {
        ""
    };
    format!(
        "[storage]\ndir = \"data\"\n\n[api]\nlisten = \"127.0.0.1:0\"\n{api_tls}\n\
         [hmi]\nlisten = \"127.0.0.1:0\"\n\n[mtconnect]\nlisten = \"0.0.0.0:{port}\"\n\n\
         [rt]\nlock_memory = false\n"
    )
}

/// A port that was free a moment ago on every address.
fn free_port() -> u16 {
    std::net::TcpListener::bind("0.0.0.0:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// GET `path` from 127.0.0.1:`port` over TLS trusting `ca` only: status and body.
async fn get_tls(port: u16, ca: &[u8], path: &str) -> Result<(u16, String), String> {
    let mut roots = rustls::RootCertStore::empty();
    roots
        .add(CertificateDer::from_pem_slice(ca).map_err(|e| e.to_string())?)
        .map_err(|e| e.to_string())?;
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let cfg = rustls::ClientConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .map_err(|e| e.to_string())?
        .with_root_certificates(roots)
        .with_no_client_auth();
    let tcp = tokio::net::TcpStream::connect(("127.0.0.1", port))
        .await
        .map_err(|e| e.to_string())?;
    let name = ServerName::try_from("localhost").unwrap();
    let tls = tokio_rustls::TlsConnector::from(Arc::new(cfg))
        .connect(name, tcp)
        .await
        .map_err(|e| e.to_string())?;
    request(hyper_util::rt::TokioIo::new(tls), port, path).await
}

/// GET `path` from 127.0.0.1:`port` in plain HTTP.
async fn get_plain(port: u16, path: &str) -> Result<(u16, String), String> {
    let tcp = tokio::net::TcpStream::connect(("127.0.0.1", port))
        .await
        .map_err(|e| e.to_string())?;
    request(hyper_util::rt::TokioIo::new(tcp), port, path).await
}

async fn request<S>(io: S, port: u16, path: &str) -> Result<(u16, String), String>
where
    S: hyper::rt::Read + hyper::rt::Write + Unpin + Send + 'static,
{
    let (mut s, conn) = hyper::client::conn::http1::handshake(io)
        .await
        .map_err(|e| e.to_string())?;
    tokio::spawn(conn);
    let req = hyper::Request::builder()
        .uri(path)
        .header("host", format!("localhost:{port}"))
        .body(Empty::<Bytes>::new())
        .unwrap();
    let r = s.send_request(req).await.map_err(|e| e.to_string())?;
    let status = r.status().as_u16();
    let body = r.into_body().collect().await.map_err(|e| e.to_string())?;
    Ok((
        status,
        String::from_utf8_lossy(&body.to_bytes()).into_owned(),
    ))
}

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap()
}

#[test]
fn off_loopback_the_agent_is_served_over_tls_with_the_api_certificate() {
    let cwd = temp_dir("mtconnect_tls");
    let cert = rcgen::generate_simple_self_signed(vec!["localhost".into()]).unwrap();
    std::fs::write(cwd.join("cert.pem"), cert.cert.pem()).unwrap();
    std::fs::write(cwd.join("key.pem"), cert.signing_key.serialize_pem()).unwrap();
    let ca = cert.cert.pem().into_bytes();
    let port = free_port();
    let d = Cncd::start(&cwd, &toml(port, true));
    let rt = runtime();

    let mut probe = Err(String::new());
    wait_for("the agent over TLS", || {
        probe = rt.block_on(get_tls(port, &ca, "/probe"));
        probe.is_ok()
    });
    let (status, body) = probe.unwrap();
    assert_eq!(status, 200, "{body}");
    assert!(body.contains("<MTConnectDevices"), "{body}");
    let (status, body) = rt.block_on(get_tls(port, &ca, "/current")).unwrap();
    assert_eq!(status, 200, "{body}");
    assert!(body.contains("<MTConnectStreams"), "{body}");

    // Plain HTTP on the TLS port is no MTConnect answer.
    let plain = rt.block_on(get_plain(port, "/probe"));
    assert!(
        !matches!(&plain, Ok((200, b)) if b.contains("MTConnect")),
        "plain HTTP was served: {plain:?}"
    );
    drop(d);
}

#[test]
fn off_loopback_without_a_certificate_cncd_refuses_the_configuration() {
    let cwd = temp_dir("mtconnect_no_tls");
    std::fs::write(cwd.join("cncd.toml"), toml(free_port(), false)).unwrap();
    let out = std::process::Command::new(bin("cncd"))
        .args(["--config", "cncd.toml"])
        .current_dir(&cwd)
        .env("CNCD_RUNTIME_DIR", cwd.join("run"))
        .stdin(std::process::Stdio::null())
        .output()
        .unwrap();
    let text =
        String::from_utf8_lossy(&out.stderr).into_owned() + &String::from_utf8_lossy(&out.stdout);
    assert!(!out.status.success(), "cncd started: {text}");
    assert!(text.contains("config_missing"), "{text}");
    assert!(text.contains("mtconnect.listen"), "{text}");
    assert!(text.contains("TLS"), "{text}");
}
