//! The walking skeleton end to end: daemon in-process on the simulated machine, gRPC client,
//! program in, ticks, drives move, status out.

mod api_common;

use std::sync::Arc;
use std::time::{Duration, Instant};

use api_common::{named_program, start_job};
use daemon::runtime::config::Config;
use daemon::runtime::controller::{ClockKind, Controller};
use daemon::runtime::rt::MachineState;
use prost::Message;
use proto::v1 as pb;
use proto::v1::machine_client::MachineClient;
use tests::{Recording, RecordingBus, max_rates, wait_job_finished, wait_state};
use tonic::transport::Channel;

const TS_S: f64 = 0.004;

fn sim_bus(cfg: &Config) -> sim::SimBus {
    sim::SimBus::new(sim::SimDriveParams::default(), &vec![0.0; cfg.axes.len()])
}

/// A daemon on a Unix socket in its data directory; returns the client and the controller.
async fn daemon(
    cfg: Config,
    clock: ClockKind,
) -> (MachineClient<Channel>, Arc<Controller>, Recording) {
    let (bus, record) = RecordingBus::new(sim_bus(&cfg));
    let ctl = Controller::start_with_bus(cfg, clock, Box::new(bus)).unwrap();
    // The Unix socket: tokenless loopback TCP is observer-only.
    let addr = tests::serve_unix(&ctl).await;
    let client = MachineClient::connect(addr.clone()).await.unwrap();
    wait_state(&ctl, MachineState::Idle).await;
    (client, ctl, record)
}

const PROGRAM: &str = "\
; walking-skeleton test part
N10 G0 X10 Y5
N20 G1 X30 F1500
N30 Y20 Z-2
N40 G91 X-5 Y-5
N50 G90 G0 X40.5 Y12.25 Z1
N60 G1 X41 F.6
";
const END: [f64; 3] = [41.0, 12.25, 1.0];

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn program_runs_through_grpc_within_limits_and_ends_exactly() {
    let cfg = tests::test_config();
    let limits: Vec<(f64, f64)> = cfg
        .axes
        .iter()
        .map(|a| (a.max_velocity_mm_min / 60.0, a.max_accel_mm_s2))
        .collect();
    let (mut client, ctl, record) = daemon(cfg, ClockKind::Monotonic).await;

    let loaded = client
        .load_program(named_program("skeleton.nc", PROGRAM))
        .await
        .unwrap()
        .into_inner();
    assert_eq!(loaded.blocks, 6);

    // Status stream at 50 Hz while the program runs.
    let mut stream = api_common::status_stream(&mut client).await;
    record.lock().unwrap().clear();
    let job = start_job(&mut client).await;
    let t0 = Instant::now();
    let mut count = 0u32;
    let mut saw_running = false;
    let mut last = None;
    while t0.elapsed() < Duration::from_secs(2) {
        let s = stream.message().await.unwrap().unwrap();
        saw_running |= s.state == pb::MachineState::Running as i32 && s.job == job;
        count += 1;
        last = Some(s);
    }
    let rate = count as f64 / t0.elapsed().as_secs_f64();
    // Never faster than asked; slower only when the machine running the tests is loaded
    // (missed ticks are skipped), so the lower bound is a liveness check, not a timing.
    assert!(
        (12.0..=60.0).contains(&rate),
        "status rate {rate} Hz, asked 50"
    );
    assert!(saw_running);
    assert_eq!(last.unwrap().axes.len(), 3);
    drop(stream);

    wait_job_finished(&ctl, job).await;
    let s = ctl.snapshot();
    for (i, e) in END.iter().enumerate() {
        assert!(
            (s.axes.commanded[i] - e).abs() < 1e-6,
            "axis {i}: {:?}",
            s.axes.commanded
        );
    }
    // The drives follow with a lag; they settle on the end point.
    let t0 = Instant::now();
    loop {
        let s = ctl.snapshot();
        if (0..3).all(|i| (s.axes.actual[i] - END[i]).abs() < 1e-3) {
            break;
        }
        assert!(
            t0.elapsed() < tests::PATIENCE,
            "drives did not settle: {s:?}"
        );
        tokio::time::sleep(Duration::from_millis(10)).await;
    }

    // The whole commanded setpoint stream stays within the configured limits. Speeds are
    // per-tick averages, so finite differences match the limits up to rounding (1e-6).
    let points = record.lock().unwrap().clone();
    assert!(points.len() > 100);
    let rates = max_rates(&points, 3, TS_S);
    for (i, ((vmax, amax), (vlim, alim))) in rates.iter().zip(&limits).enumerate() {
        if *amax > alim * (1.0 + 1e-6) + 1e-6 {
            let k = tests::worst_accel_at(&points, i, TS_S);
            let lo = k.saturating_sub(4);
            eprintln!(
                "axis {i} around tick {k}: {:?}",
                &points[lo..(k + 6).min(points.len())]
            );
        }
        assert!(
            *vmax <= vlim * (1.0 + 1e-6),
            "axis {i}: speed {vmax} > {vlim}"
        );
        assert!(
            *amax <= alim * (1.0 + 1e-6) + 1e-6,
            "axis {i}: accel {amax} > {alim}"
        );
    }
    // Every programmed point was reached exactly (G98: the path stops at each block end).
    for target in [
        [10.0, 5.0, 0.0],
        [30.0, 5.0, 0.0],
        [30.0, 20.0, -2.0],
        [25.0, 15.0, -2.0],
    ] {
        assert!(
            points.iter().any(|p| p[..3] == target),
            "block end {target:?} never commanded exactly"
        );
    }
    ctl.shutdown();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_program_is_rejected_with_block_number_and_nothing_moves() {
    let (mut client, ctl, record) = daemon(tests::test_config(), ClockKind::Monotonic).await;
    let before = ctl.snapshot().axes.commanded;
    for (text, block, code) in [
        ("N10 G1 X5 F100\nN20 Q7\n", 20, "unknown_address"),
        ("N10 G1 X5 F100\nN20 X\n", 20, "word_without_value"),
    ] {
        let err = client
            .load_program(named_program("bad.nc", text))
            .await
            .unwrap_err();
        assert_eq!(err.code(), tonic::Code::InvalidArgument);
        assert!(
            err.message().contains(&format!("N{block}")),
            "{}",
            err.message()
        );
        let details = pb::Diagnostics::decode(err.details()).unwrap();
        let first = &details.items[0];
        assert_eq!(first.block, Some(block));
        assert_eq!(first.line, 2);
        assert_eq!(first.code, code, "{}", first.message);
    }
    // No program is selected, so start is refused; nothing moved; the daemon still serves.
    let err = client.start(pb::StartRequest::default()).await.unwrap_err();
    assert_eq!(err.code(), tonic::Code::FailedPrecondition);
    tokio::time::sleep(Duration::from_millis(50)).await;
    assert_eq!(ctl.snapshot().axes.commanded, before);
    let moved = record
        .lock()
        .unwrap()
        .iter()
        .any(|p| p[..3] != before.0[..3]);
    assert!(!moved);
    let ok = client
        .load_program(named_program("good.nc", "G1 X1 F600"))
        .await
        .unwrap();
    assert_eq!(ok.into_inner().blocks, 1);
    ctl.shutdown();
}
