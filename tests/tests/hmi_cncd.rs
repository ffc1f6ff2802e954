//! The README's first command (issue #30): `cncd` with no configuration serves the gRPC API on
//! `127.0.0.1:50051` and the HMI on `http://127.0.0.1:8080/` (its page and grpc-web). The real
//! binary on the default ports: a port already taken fails the test with the reason.

mod hmi_common;
mod systemd_support;

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use proto::v1 as pb;
use proto::v1::machine_client::MachineClient;

const API: &str = "http://127.0.0.1:50051";
const HMI: &str = "http://127.0.0.1:8080";

/// Kills cncd when the test ends, however it ends.
struct Running(std::process::Child);

impl Drop for Running {
    fn drop(&mut self) {
        // SAFETY: kill(2) on the child's own pid.
        unsafe { libc::kill(self.0.id() as i32, libc::SIGTERM) };
        let t0 = Instant::now();
        while t0.elapsed() < Duration::from_secs(20) {
            if let Ok(Some(_)) = self.0.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cncd_with_no_configuration_serves_the_api_and_the_hmi() {
    let dir = std::env::temp_dir().join(format!("cnc-hmi-cncd-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let mut cncd = Running(
        Command::new(systemd_support::cncd_binary())
            .args(["--log", "stderr"])
            .env_remove("NOTIFY_SOCKET")
            .env_remove("WATCHDOG_USEC")
            .current_dir(&dir)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    // The API: a gRPC client on 50051 (HTTP/2), once cncd is up.
    let t0 = Instant::now();
    let channel = loop {
        if let Ok(Some(status)) = cncd.0.try_wait() {
            panic!("cncd exited with {status} (ports 50051 and 8080 must be free)");
        }
        match tonic::transport::Endpoint::from_static(API).connect().await {
            Ok(c) => break c,
            Err(e) => assert!(t0.elapsed() < tests::PATIENCE, "no API: {e}"),
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    let me = MachineClient::new(channel)
        .who_am_i(pb::WhoAmIRequest {})
        .await
        .unwrap()
        .into_inner();
    assert_eq!(me.role, "observer");

    // The HMI: its page (the screen, or the note that this build has none) ...
    let page = hmi_common::get(&format!("{HMI}/"), &[]).await;
    assert_eq!(page.header("content-type"), "text/html; charset=utf-8");
    let built_with_assets = systemd_support::repo().join("hmi/dist/index.html").exists();
    if built_with_assets {
        assert_eq!(page.status, 200, "{}", page.text());
    } else {
        assert_eq!(page.status, 503);
        assert!(
            page.text().contains("HMI assets are missing"),
            "{}",
            page.text()
        );
    }
    // ... and the same services over grpc-web, as the page calls them.
    let (svc, origin) = hmi_common::web_channel(HMI);
    let mut m = MachineClient::with_origin(svc, origin);
    let me = m.who_am_i(pb::WhoAmIRequest {}).await.unwrap().into_inner();
    assert_eq!((me.role.as_str(), me.who.as_str()), ("observer", "local"));
    let mut s = m
        .stream_status(pb::StatusRequest { rate_hz: 25 })
        .await
        .unwrap()
        .into_inner();
    let st = s.message().await.unwrap().unwrap();
    assert_eq!(st.axes.len(), 3);
    drop(s);
    drop(cncd);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn check_config_refuses_a_remote_hmi_without_tls() {
    let dir = std::env::temp_dir().join(format!("cnc-hmi-check-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("remote-hmi.toml");
    std::fs::write(&path, "[hmi]\nlisten = \"0.0.0.0:8443\"\n").unwrap();
    let out = Command::new(systemd_support::cncd_binary())
        .args(["--check-config", "--config"])
        .arg(&path)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("error [config_missing]: "), "{err}");
    assert!(err.contains("hmi.tls_cert, hmi.tls_key"), "{err}");
    // Disabled, the same address is not checked.
    std::fs::write(&path, "[hmi]\nenabled = false\nlisten = \"0.0.0.0:8443\"\n").unwrap();
    let out = Command::new(systemd_support::cncd_binary())
        .args(["--check-config", "--config"])
        .arg(&path)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("HMI disabled"), "{text}");
    let _ = std::fs::remove_dir_all(&dir);
}
