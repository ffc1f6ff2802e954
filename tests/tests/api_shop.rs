//! The API for real shops (issue #19), through gRPC and `cncctl`: local access that holds,
//! reflection v1alpha, refusals with locations, stream shares, large programs, the program
//! library and the HMI overrides.

mod api_common;
mod vcan_support;

use std::path::Path;
use std::process::Command;
use std::time::Duration;

use api_common::*;
use daemon::runtime::config::Role;
use proto::v1 as pb;
use proto::v1::machine_client::MachineClient;
use tonic::Code;

/// Runs the real `cncctl` with `args` in `cwd` (no `--addr`, no `$CNCCTL_ADDR`).
async fn cncctl_in(cwd: &Path, args: &[&str]) -> (bool, String) {
    let cwd = cwd.to_owned();
    let args: Vec<String> = args.iter().map(|s| s.to_string()).collect();
    tokio::task::spawn_blocking(move || {
        let mut cmd = Command::new(vcan_support::bin("cncctl"));
        cmd.args(&args).current_dir(&cwd).env_remove("CNCCTL_ADDR");
        vcan_support::run_with_timeout(&mut cmd, Duration::from_secs(60))
    })
    .await
    .unwrap()
}

/// Runs `cncctl --addr ADDR args..`.
async fn cncctl(addr: &str, args: &[&str]) -> (bool, String) {
    let mut all = vec!["--addr", addr];
    all.extend_from_slice(args);
    cncctl_in(&std::env::temp_dir(), &all).await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn loopback_is_observer_by_default_the_socket_controls() {
    let mut cfg = config(Role::Admin);
    cfg.api.loopback_role = daemon::runtime::config::ApiConfig::default().loopback_role;
    let d = start(cfg).await;
    // Any local account can open loopback TCP: without a token it only observes.
    let mut tcp = MachineClient::new(d.loopback_channel().await);
    tcp.list_programs(pb::ListProgramsRequest {}).await.unwrap();
    let e = tcp.mdi(mdi_block("G1 X1 F500")).await.unwrap_err();
    assert_eq!(e.code(), Code::PermissionDenied, "{e:?}");
    // A token gives its role on loopback too.
    tcp.set_override(with_token(
        pb::SetOverrideRequest { percent: 90.0 },
        OPERATOR_TOKEN,
    ))
    .await
    .unwrap();
    // The Unix socket (mode 0660, its group decides) gives the socket role.
    let mut unix = MachineClient::new(d.unix_channel().await);
    unix.set_override(pb::SetOverrideRequest { percent: 100.0 })
        .await
        .unwrap();
    // cncctl over loopback: refused with the role it needs.
    let (ok, out) = cncctl(&d.local, &["override", "80"]).await;
    assert!(!ok && out.contains("PermissionDenied"), "{out}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cncctl_uses_the_unix_socket_by_default() {
    let mut cfg = config(Role::Admin);
    cfg.api.loopback_role = Role::Observer;
    // cncctl looks for ./cncd-data/cncd.sock (cncd started in the same directory).
    let base = cfg.storage.dir.clone();
    cfg.storage.dir = base.join("cncd-data");
    let d = start(cfg).await;
    if Path::new("/run/cncd/cncd.sock").exists() {
        println!("SKIPPED: /run/cncd/cncd.sock exists here and comes first");
        return;
    }
    let (ok, out) = cncctl_in(&base, &["override", "70"]).await;
    assert!(ok, "cncctl over the default socket: {out}");
    wait_until("override 70 %", || {
        (d.ctl.snapshot().operator.feed_override_pct - 70.0).abs() < 1e-9
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn reflection_v1alpha_beside_v1() {
    let d = start(config(Role::Observer)).await;
    let names = reflected_services!(v1alpha, d.channel().await);
    for s in [
        "cnc.v1.Machine",
        "cnc.v1.Offsets",
        "grpc.health.v1.Health",
        "grpc.reflection.v1.ServerReflection",
        "grpc.reflection.v1alpha.ServerReflection",
    ] {
        assert!(names.contains(&s.to_string()), "{s} missing from {names:?}");
    }
}

/// `LoadProgramRequest` with the text as raw bytes, to send what a `string` cannot hold.
#[derive(Clone, PartialEq, prost::Message)]
struct RawLoad {
    #[prost(string, tag = "1")]
    name: String,
    #[prost(bytes = "vec", tag = "2")]
    text: Vec<u8>,
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn text_that_is_not_utf8_is_invalid_argument_with_its_location() {
    let d = start(config(Role::Admin)).await;
    let mut g = tonic::client::Grpc::new(d.channel().await);
    g.ready().await.unwrap();
    let req = RawLoad {
        name: "latin2.nc".into(),
        // "č" in ISO 8859-2 (0xE8) on line 2, after 5 characters.
        text: b"N10 G0 X1\nN20 (\xe8ep) G1 X2 F100\n".to_vec(),
    };
    let e = g
        .unary::<_, pb::LoadProgramReply, _>(
            tonic::Request::new(req),
            "/cnc.v1.Machine/LoadProgram".parse().unwrap(),
            proto::codec::CncCodec::<RawLoad, pb::LoadProgramReply>::default(),
        )
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    assert!(e.message().contains("byte offset 15"), "{}", e.message());
    let diags = diagnostics(&e);
    assert_eq!(diags[0].code, "text_not_utf8", "{diags:?}");
    assert_eq!((diags[0].line, diags[0].column), (2, 6), "{diags:?}");
    // Nothing was selected.
    assert!(d.ctl.program().is_none());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_unary_message_over_the_limit_is_resource_exhausted() {
    let d = start(config(Role::Admin)).await;
    let mut m = MachineClient::new(d.channel().await);
    let text = "G1 X1 F100\n".repeat(500_000); // 5.5 MB
    let e = m
        .validate_program(pb::ValidateProgramRequest {
            text,
            dialect: String::new(),
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::ResourceExhausted, "{e:?}");
    assert!(e.message().contains("Programs.Upload"), "{}", e.message());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn values_needing_rounding_are_refused_and_negative_options_parse() {
    let d = start(config(Role::Admin)).await;
    let (ok, out) = cncctl(&d.socket(), &["constants", "set", "R52=1.2345"]).await;
    assert!(!ok, "{out}");
    assert!(
        out.contains("R52") && out.contains("[value_too_precise]"),
        "{out}"
    );
    assert!(!out.contains("line 0"), "{out}");
    assert_eq!(
        d.ctl.constants().get(52),
        kernel::constants::Constants::new().get(52)
    );
    let (ok, out) = cncctl(&d.socket(), &["constants", "set", "R52=1.235"]).await;
    assert!(ok, "{out}");

    let (ok, out) = cncctl(&d.socket(), &["offset-set", "6", "--radius", "1.1234567"]).await;
    assert!(!ok, "{out}");
    assert!(
        out.contains("D06 radius") && out.contains("[value_too_precise]"),
        "{out}"
    );
    assert!(!out.contains("line 0"), "{out}");
    let (ok, out) = cncctl(
        &d.socket(),
        &["offset-set", "6", "--radius", "-5", "--l3", "-0.5"],
    )
    .await;
    assert!(ok, "{out}");
    let e = d.ctl.offsets_memory().entry(6).copied().unwrap();
    assert_eq!((e.radius_mm, e.length_mm[2]), (-5.0, -0.5));
    let (ok, out) = cncctl(&d.socket(), &["offset-set", "6", "--radius", "100000"]).await;
    assert!(
        !ok && out.contains("D06 radius")
            && out.contains("[value_out_of_range]")
            && !out.contains("line 0"),
        "{out}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn observers_cannot_take_the_operators_streams() {
    let mut cfg = config(Role::Admin);
    cfg.api.loopback_role = Role::Observer;
    cfg.api.max_streams = 4;
    cfg.api.reserved_streams = 2;
    let d = start(cfg).await;
    let mut obs = MachineClient::new(d.loopback_channel().await);
    let mut held = Vec::new();
    for _ in 0..2 {
        held.push(
            obs.stream_status(pb::StatusRequest { rate_hz: 50 })
                .await
                .unwrap()
                .into_inner(),
        );
    }
    // The observers' share is full.
    let e = obs
        .stream_alarms(pb::StreamAlarmsRequest { skip_history: true })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::ResourceExhausted, "{e:?}");
    assert!(e.message().contains("reserved"), "{}", e.message());
    // The operator still gets the reserved ones: over loopback with a token, and on the socket.
    let mut s1 = obs
        .stream_status(with_token(
            pb::StatusRequest { rate_hz: 10 },
            OPERATOR_TOKEN,
        ))
        .await
        .unwrap()
        .into_inner();
    s1.message().await.unwrap().unwrap();
    let mut unix = MachineClient::new(d.unix_channel().await);
    let mut s2 = unix
        .stream_status(pb::StatusRequest { rate_hz: 10 })
        .await
        .unwrap()
        .into_inner();
    s2.message().await.unwrap().unwrap();
    // Now every slot is taken, for everyone.
    let e = unix
        .stream_status(pb::StatusRequest { rate_hz: 10 })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::ResourceExhausted);
    // An observer leaving frees a slot for observers again.
    drop(held.pop());
    let t0 = std::time::Instant::now();
    loop {
        match obs.stream_status(pb::StatusRequest { rate_hz: 1 }).await {
            Ok(_) => break,
            Err(e) => {
                assert_eq!(e.code(), Code::ResourceExhausted);
                assert!(t0.elapsed() < tests::PATIENCE, "slot never freed");
                tokio::time::sleep(Duration::from_millis(10)).await;
            }
        }
    }
}

/// Writes `text` to a file in the daemon's test directory and returns its path.
fn program_file(d: &Daemon, name: &str, text: &str) -> String {
    let p = d.ctl.config().storage.dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.to_str().unwrap().to_owned()
}

async fn library(d: &Daemon) -> pb::LibraryList {
    let mut g = proto::v1::programs_client::ProgramsClient::new(d.channel().await);
    g.list(pb::LibraryListRequest {})
        .await
        .unwrap()
        .into_inner()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn program_library_on_disk_survives_a_restart() {
    let cfg = config(Role::Admin);
    let d = start(cfg.clone()).await;
    let a = "N10 G0 X5 Y5\nN20 G1 X10 F1200\n";
    let b = "N10 G0 X1\nN20 G1 Y2 F600\nN30 G1 X0\n";
    let pa = program_file(&d, "a.nc", a);
    let pb_ = program_file(&d, "b.nc", b);
    let (ok, out) = cncctl(&d.socket(), &["upload", &pa, "--name", "part A"]).await;
    assert!(ok, "{out}");
    let (ok, out) = cncctl(&d.socket(), &["load", &pb_]).await;
    assert!(ok, "{out}");
    let l = library(&d).await;
    assert_eq!(l.selected, "b.nc");
    let names: Vec<_> = l.programs.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["b.nc", "part A"]);
    let pa_entry = &l.programs[1];
    assert_eq!(
        (pa_entry.size_bytes, pa_entry.blocks, pa_entry.valid),
        (a.len() as u64, 2, true)
    );
    assert!(pa_entry.modified_unix_ms > 0);
    // Download gives the text back, byte for byte.
    let out_file = d.ctl.config().storage.dir.join("back.nc");
    let (ok, out) = cncctl(
        &d.socket(),
        &["download", "part A", "-o", out_file.to_str().unwrap()],
    )
    .await;
    assert!(ok, "{out}");
    assert_eq!(std::fs::read_to_string(&out_file).unwrap(), a);
    // Rename, delete; the selected program can be neither.
    let (ok, out) = cncctl(&d.socket(), &["rename", "part A", "part C"]).await;
    assert!(ok, "{out}");
    let (ok, out) = cncctl(&d.socket(), &["delete", "b.nc"]).await;
    assert!(!ok && out.contains("FailedPrecondition"), "{out}");
    let (ok, out) = cncctl(&d.socket(), &["upload", &pa, "--name", "doomed"]).await;
    assert!(ok, "{out}");
    let (ok, out) = cncctl(&d.socket(), &["delete", "doomed"]).await;
    assert!(ok, "{out}");
    let (ok, out) = cncctl(&d.socket(), &["delete", "doomed"]).await;
    assert!(!ok && out.contains("NotFound"), "{out}");

    // Restart on the same data directory: the library and the selection are back, and
    // nothing runs.
    let ctl = d.ctl.clone();
    tokio::task::spawn_blocking(move || ctl.shutdown())
        .await
        .unwrap();
    drop(d);
    let d = start(cfg).await;
    wait_until("the selection restored", || {
        d.ctl.program().is_some_and(|p| p.name == "b.nc")
    })
    .await;
    let l = library(&d).await;
    let names: Vec<_> = l.programs.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["b.nc", "part C"]);
    assert_eq!(l.selected, "b.nc");
    assert_eq!(d.ctl.snapshot().progress.job, 0, "nothing was started");
    let (ok, out) = cncctl(&d.socket(), &["run", "--quiet", "--json"]).await;
    assert!(!ok, "run needs a file: {out}");
    let mut m = MachineClient::new(d.channel().await);
    let job = start_job(&mut m).await;
    wait_job_finished(&d.ctl, job).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_library_is_bounded_and_refusals_store_nothing() {
    let mut cfg = config(Role::Admin);
    cfg.storage.programs_max_bytes = 4000;
    let d = start(cfg).await;
    let small = program_file(&d, "small.nc", &"G1 X1 F100\n".repeat(100)); // 1100 bytes
    let big = program_file(&d, "big.nc", &"G1 X1 F100\n".repeat(300)); // 3300 bytes
    let (ok, out) = cncctl(&d.socket(), &["upload", &small]).await;
    assert!(ok, "{out}");
    let (ok, out) = cncctl(&d.socket(), &["upload", &big]).await;
    assert!(!ok && out.contains("ResourceExhausted"), "{out}");
    assert!(out.contains("programs_max_bytes"), "{out}");
    // A program with errors is refused with its diagnostics and not stored.
    let bad = program_file(&d, "bad.nc", "G1 X1 F100\nG1 Q7\n");
    let (ok, out) = cncctl(&d.socket(), &["upload", &bad]).await;
    assert!(!ok && out.contains("line 2"), "{out}");
    assert!(
        out.contains("[unknown_address]"),
        "cncctl prints the code: {out}"
    );
    let l = library(&d).await;
    let names: Vec<_> = l.programs.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["small.nc"]);
    assert_eq!(l.used_bytes, 1100);
    // No temporary files are left behind.
    let dir = d.ctl.config().storage.programs_path();
    let tmp = std::fs::read_dir(dir)
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .file_name()
                .to_string_lossy()
                .contains("upload")
        })
        .count();
    assert_eq!(tmp, 0);
}

/// A program above the 4 MiB message limit: streamed up in chunks, validated from the file,
/// run from the file.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_program_over_the_message_limit_loads_and_runs_from_its_file() {
    let d = start(config(Role::Admin)).await;
    let mut text = String::from("N1 G1 X0 Y0 F6000\n");
    for i in 0..300_000u32 {
        let x = (i % 100) as f64 * 0.01;
        text.push_str(&format!("G1 X{x:.2} Y{:.2}\n", (i % 7) as f64 * 0.01));
    }
    assert!(text.len() > 4 << 20);
    let p = program_file(&d, "cam.nc", &text);
    let (ok, out) = cncctl(&d.socket(), &["load", &p]).await;
    assert!(ok, "{out}");
    assert!(out.contains("300001 blocks"), "{out}");
    let loaded = d.ctl.program().unwrap();
    assert!(matches!(
        loaded.text,
        daemon::runtime::library::ProgramText::File(_)
    ));
    let mut m = MachineClient::new(d.channel().await);
    let job = start_job(&mut m).await;
    wait_until("moving through the program", || {
        let s = d.ctl.snapshot();
        s.progress.job == job && s.progress.block_seq > 10
    })
    .await;
    m.stop(pb::StopRequest {}).await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn status_shows_the_distance_to_go() {
    let d = start(config(Role::Admin)).await;
    let mut m = MachineClient::new(d.channel().await);
    let job = load_and_start(&mut m, "slow.nc", "N10 G1 X40 Y-20 F60\n").await;
    let mut s = status_stream(&mut m).await;
    loop {
        let st = s.message().await.unwrap().unwrap();
        if st.job == job && st.state == pb::MachineState::Running as i32 {
            let (x, y) = (&st.axes[0], &st.axes[1]);
            if x.distance_to_go_mm > 1.0 {
                assert!((40.0 - x.commanded_mm - x.distance_to_go_mm).abs() < 1e-9);
                assert!((-20.0 - y.commanded_mm - y.distance_to_go_mm).abs() < 1e-9);
                assert!(y.distance_to_go_mm < 0.0);
                break;
            }
        }
        assert_ne!(st.aborted_job, job);
        assert_ne!(st.finished_job, job, "finished before a status in motion");
    }
    // Held on the path (not timing-dependent): the distance to go stays, cncctl shows it.
    m.hold(pb::HoldRequest {}).await.unwrap();
    wait_state(&d.ctl, daemon::runtime::rt::MachineState::Hold).await;
    let (ok, out) = cncctl(&d.socket(), &["status"]).await;
    assert!(ok && out.contains("to go X"), "{out}");
    m.stop(pb::StopRequest {}).await.unwrap();
    wait_state(&d.ctl, daemon::runtime::rt::MachineState::Idle).await;
    // The stream may still hold older snapshots: read on to the first one at rest.
    let st = loop {
        let st = s.message().await.unwrap().unwrap();
        if st.state == pb::MachineState::Idle as i32 {
            break st;
        }
    };
    assert!(
        st.axes.iter().all(|a| a.distance_to_go_mm == 0.0),
        "at rest: {st:?}"
    );
}
