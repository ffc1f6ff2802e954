//! Safe machine operation (issue #15) through the gRPC API on the simulated machine, in virtual
//! time: program end and stops (M2/M30, M0/M1, optional stop), Stop stops the spindle,
//! FAILED_PRECONDITION for commands that cannot apply, soft limits, fault reaction.

use std::sync::Arc;
use std::time::{Duration, Instant};

use daemon::runtime::config::Config;
use daemon::runtime::controller::{ClockKind, Controller};
use daemon::runtime::rt::{MachineState, Snapshot};
use daemon::runtime::server;
use proto::v1 as pb;
use proto::v1::machine_client::MachineClient;
use tests::{Recording, RecordingBus, SpindleRecording, wait_job_finished, wait_state};
use tonic::Code;
use tonic::transport::Channel;

struct Daemon {
    c: MachineClient<Channel>,
    ctl: Arc<Controller>,
    record: Recording,
    spindle: SpindleRecording,
}

/// A daemon on the simulated bus built from `cfg` (as `cncd` builds it), virtual clock.
async fn daemon(cfg: Config) -> Daemon {
    let params = sim::SimDriveParams {
        kv_per_s: cfg.sim.kv_per_s,
        following_window_mm: cfg.sim.following_window_mm,
        ..Default::default()
    };
    let start: Vec<f64> = cfg.axes.iter().map(|a| a.home_mm).collect();
    let (bus, record, spindle) = RecordingBus::with_spindle(sim::SimBus::new(params, &start));
    let ctl = Controller::start_with_bus(cfg, ClockKind::Virtual, Box::new(bus)).unwrap();
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    tokio::spawn(server::serve(ctl.clone(), listener, std::future::pending()));
    let c = MachineClient::connect(format!("http://{addr}"))
        .await
        .unwrap();
    wait_state(&ctl, MachineState::Idle, Duration::from_secs(10)).await;
    Daemon {
        c,
        ctl,
        record,
        spindle,
    }
}

async fn wait_for(ctl: &Controller, what: &str, mut f: impl FnMut(&Snapshot) -> bool) {
    let t0 = Instant::now();
    loop {
        let s = ctl.snapshot();
        if f(&s) {
            return;
        }
        assert!(t0.elapsed() < Duration::from_secs(60), "{what}: {s:?}");
        tokio::time::sleep(Duration::from_millis(2)).await;
    }
}

async fn load(
    c: &mut MachineClient<Channel>,
    text: &str,
) -> Result<pb::LoadProgramReply, tonic::Status> {
    c.load_program(pb::LoadProgramRequest {
        name: "t.nc".into(),
        text: text.into(),
    })
    .await
    .map(|r| r.into_inner())
}

async fn start(c: &mut MachineClient<Channel>) -> u32 {
    c.start(pb::StartRequest {}).await.unwrap().into_inner().job
}

async fn status(c: &mut MachineClient<Channel>) -> pb::Status {
    let mut s = c
        .stream_status(pb::StatusRequest { rate_hz: 50 })
        .await
        .unwrap()
        .into_inner();
    s.message().await.unwrap().unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn m30_ends_the_program_and_the_spindle_stops() {
    let mut d = daemon(tests::test_config()).await;
    let text = "N10 S1000 M3\nN20 G1 X10 F3000\nN30 M30\nN40 G1 X50\n";
    let loaded = load(&mut d.c, text).await.unwrap();
    assert_eq!(loaded.blocks, 3, "blocks after M30 are not part of the run");
    let job = start(&mut d.c).await;
    wait_job_finished(&d.ctl, job, Duration::from_secs(60)).await;
    let s = d.ctl.snapshot();
    assert!((s.commanded[0] - 10.0).abs() < 1e-9, "N40 ran: {s:?}");
    assert!(
        d.spindle.lock().unwrap().iter().any(|&r| r > 900.0),
        "the spindle never ran"
    );
    wait_for(&d.ctl, "spindle stopped at M30", |s| s.spindle_rpm == 0.0).await;
    // M2 does the same.
    load(&mut d.c, "N10 S500 M3\nN20 G1 X20 F3000\nN30 M2\nN40 X0\n")
        .await
        .unwrap();
    let job = start(&mut d.c).await;
    wait_job_finished(&d.ctl, job, Duration::from_secs(60)).await;
    assert!((d.ctl.snapshot().commanded[0] - 20.0).abs() < 1e-9);
    wait_for(&d.ctl, "spindle stopped at M2", |s| s.spindle_rpm == 0.0).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn m0_stops_until_resume_and_m1_only_with_optional_stop() {
    let mut d = daemon(tests::test_config()).await;
    let text = "N10 G1 X10 F3000\nN20 M0\nN30 X20\nN40 M1\nN50 X30\n";
    load(&mut d.c, text).await.unwrap();
    // Optional stop off: M0 stops, M1 does not.
    let job = start(&mut d.c).await;
    wait_for(&d.ctl, "held at M0", |s| {
        s.state == MachineState::Hold && s.program_stop
    })
    .await;
    let s = d.ctl.snapshot();
    assert!(
        (s.commanded[0] - 10.0).abs() < 1e-9,
        "stopped off the M0 point: {s:?}"
    );
    let st = status(&mut d.c).await;
    assert!(st.program_stop && !st.optional_stop);
    // At rest it stays there.
    let seq = s.sequence;
    wait_for(&d.ctl, "time passes", |s| s.sequence > seq + 200).await;
    assert_eq!(d.ctl.snapshot().commanded[0], s.commanded[0]);
    d.c.resume(pb::ResumeRequest {}).await.unwrap();
    wait_job_finished(&d.ctl, job, Duration::from_secs(60)).await;
    assert!((d.ctl.snapshot().commanded[0] - 30.0).abs() < 1e-9);

    // Optional stop on: M0 and M1 both stop; Start continues like Resume.
    d.c.set_optional_stop(pb::SetOptionalStopRequest { on: true })
        .await
        .unwrap();
    load(&mut d.c, "N10 G0 X0\nN20 G1 X10 F3000 M1\nN30 X20\n")
        .await
        .unwrap();
    let job = start(&mut d.c).await;
    wait_for(&d.ctl, "held at M1", |s| {
        s.state == MachineState::Hold && s.program_stop
    })
    .await;
    assert!((d.ctl.snapshot().commanded[0] - 10.0).abs() < 1e-9);
    assert!(status(&mut d.c).await.optional_stop);
    let again = start(&mut d.c).await;
    assert_eq!(again, job, "Start at a program stop continues the job");
    wait_job_finished(&d.ctl, job, Duration::from_secs(60)).await;
    assert!((d.ctl.snapshot().commanded[0] - 20.0).abs() < 1e-9);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn stop_stops_the_spindle_and_wrong_states_are_refused() {
    let mut d = daemon(tests::test_config()).await;
    // Idle: hold and resume cannot apply.
    let e = d.c.hold(pb::HoldRequest {}).await.unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition, "hold when idle");
    let e = d.c.resume(pb::ResumeRequest {}).await.unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition, "resume when idle");

    // Long enough that it is still cutting when the test looks (virtual time runs fast).
    load(&mut d.c, "N10 S1000 M3\nN20 G1 X1000000 F600\n")
        .await
        .unwrap();
    let job = start(&mut d.c).await;
    wait_for(&d.ctl, "cutting with the spindle on", |s| {
        s.state == MachineState::Running && s.spindle_rpm > 900.0 && s.commanded[0] > 1.0
    })
    .await;
    d.c.stop(pb::StopRequest {}).await.unwrap();
    wait_for(&d.ctl, "stopped", |s| {
        s.aborted_job == job && s.state == MachineState::Idle
    })
    .await;
    wait_for(&d.ctl, "spindle stopped after Stop", |s| {
        s.spindle_rpm == 0.0
    })
    .await;
    // Resume after a stop has nothing to continue.
    let e = d.c.resume(pb::ResumeRequest {}).await.unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition, "resume after stop");
    // Stop is never refused (it also stops a spindle on an idle machine).
    d.c.stop(pb::StopRequest {}).await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn soft_limits_refuse_programs_and_mdi_with_the_offsets_in_force() {
    let mut cfg = tests::test_config();
    cfg.axes[0].soft_min_mm = Some(-10.0);
    cfg.axes[0].soft_max_mm = Some(100.0);
    cfg.axes[2].soft_min_mm = Some(-50.0);
    cfg.axes[2].soft_max_mm = Some(0.0);
    let mut d = daemon(cfg).await;
    // Inside: runs. Y has no limits (documented): far away is fine.
    load(&mut d.c, "N10 G0 X100 Y99999 Z0\nN20 G0 X0 Y0\n")
        .await
        .unwrap();

    let e = load(&mut d.c, "N10 G0 X50\nN20 G1 X123456789012 F1000\n")
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    let diags = diagnostics(&e);
    let hit = diags
        .iter()
        .find_map(|d| d.soft_limit.clone().map(|h| (d.clone(), h)));
    let (diag, hit) = hit.expect("a soft-limit diagnostic");
    assert_eq!((diag.block, diag.line), (Some(20), 2));
    assert_eq!(hit.axis, "X");
    assert!(hit.upper && hit.limit_mm == 100.0 && hit.position_mm > 1e11);

    // 100 km of G91 moves: refused at the block that leaves the travel.
    let e = load(&mut d.c, "N10 G91 G1 X60 F5000\nN20 X60\nN30 X60\n")
        .await
        .unwrap_err();
    let diags = diagnostics(&e);
    let d20 = diags.iter().find(|d| d.soft_limit.is_some()).unwrap();
    assert_eq!(d20.block, Some(20));

    // An arc bulging past the limit between two end points inside it.
    let e = load(&mut d.c, "N10 G0 X0 Y40\nN20 G3 X0 Y0 I0 J-20 F1000\n")
        .await
        .unwrap_err();
    let hit = diagnostics(&e)
        .into_iter()
        .find_map(|d| d.soft_limit)
        .unwrap();
    assert!(
        !hit.upper && (hit.position_mm + 20.0).abs() < 1e-6,
        "{hit:?}"
    );

    // With the length offset of entry 1 (Z +30) in force, Z-25 programmed is Z+5 on the
    // machine: beyond Z max 0. Without the offset it runs.
    load(&mut d.c, "N10 G1 Z-25 F1000\n").await.unwrap();
    let e = load(&mut d.c, "N5 G92 D1 R3=30\nN10 G1 Z-25 F1000 &1\n")
        .await
        .unwrap_err();
    let hit = diagnostics(&e)
        .into_iter()
        .find_map(|d| d.soft_limit)
        .unwrap();
    assert_eq!(hit.axis, "Z");
    assert!((hit.position_mm - 5.0).abs() < 1e-9 && hit.upper);

    // MDI is refused the same way and nothing moves.
    let e =
        d.c.mdi(pb::MdiRequest {
            block: "G0 X-5000 Y99999 Z-3000".into(),
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    assert!(diagnostics(&e).iter().any(|d| d.soft_limit.is_some()));
    assert_eq!(d.ctl.snapshot().commanded[0], 0.0);

    // Status shows the limits per axis; an axis without limits has none.
    let st = status(&mut d.c).await;
    assert_eq!(st.axes[0].soft_min_mm, Some(-10.0));
    assert_eq!(st.axes[0].soft_max_mm, Some(100.0));
    assert_eq!(st.axes[1].soft_min_mm, None);
    let _ = &d.record;
}

fn diagnostics(s: &tonic::Status) -> Vec<pb::Diagnostic> {
    use prost::Message;
    pb::Diagnostics::decode(s.details()).unwrap().items
}
