//! Issue #31, restart in the middle of a program (`start --from-block N`), through the gRPC
//! API and `cncctl` on the simulated machine: the blocks before N set the modal state without
//! motion, an approach leads to the start of N (on the equidistant when N is compensated), and
//! from there the tool path is the uninterrupted run's, setpoint for setpoint within 1 µm.

mod api_common;
mod vcan_support;

use std::process::Command;
use std::time::Duration;

use api_common::*;
use daemon::runtime::config::Role;
use daemon::runtime::rt::MachineState;
use proto::v1 as pb;
use proto::v1::machine_client::MachineClient;
use proto::v1::preview_client::PreviewClient;
use proto::v1::trajectory_client::TrajectoryClient;
use tonic::Code;
use tonic::transport::Channel;

const TABLE: &str = "$KOR\n01: R=3.0\n";

/// A compensated contour (D1, radius 3) with a corner arc, restarted inside it at N60.
const CONTOUR: &str = "N10 G0 X-10 Y-10 Z5\n\
N20 G1 Z-2 F300\n\
N30 D1 G41 X0 Y0 F500\n\
N40 X40\n\
N50 G3 X50 Y10 I0 J10\n\
N60 G1 Y40\n\
N70 X0\n\
N80 Y0\n\
N90 G40 X-10 Y-10\n\
N100 G0 Z5\n";

/// The setpoints (first 3 axes) and block numbers of the daemon's trajectory of CONTOUR.
async fn trajectory(ch: Channel, from_block: Option<u32>) -> Vec<([f64; 3], Option<u32>)> {
    trajectory_of(ch, CONTOUR, from_block).await
}

/// The setpoints (first 3 axes) and block numbers of the daemon's trajectory of `text` (the
/// selected program when empty).
async fn trajectory_of(
    ch: Channel,
    text: &str,
    from_block: Option<u32>,
) -> Vec<([f64; 3], Option<u32>)> {
    let mut t = TrajectoryClient::new(ch);
    let mut s = t
        .get_trajectory(pb::TrajectoryRequest {
            text: text.into(),
            from_block,
            dialect: String::new(),
        })
        .await
        .unwrap()
        .into_inner();
    let mut out = Vec::new();
    while let Some(c) = s.message().await.unwrap() {
        for k in c.ticks {
            let p = &k.position_mm;
            out.push(([p[0], p[1], p[2]], k.block));
        }
    }
    out
}

fn dist_to_segment(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let ab: Vec<f64> = (0..3).map(|i| b[i] - a[i]).collect();
    let ap: Vec<f64> = (0..3).map(|i| p[i] - a[i]).collect();
    let len2: f64 = ab.iter().map(|v| v * v).sum();
    let t = if len2 > 0.0 {
        (ab.iter().zip(&ap).map(|(x, y)| x * y).sum::<f64>() / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (0..3)
        .map(|i| (a[i] + t * ab[i] - p[i]).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// Distance from `p` to the polyline of `path` (the uninterrupted run's setpoints).
fn dist_to_path(p: [f64; 3], path: &[[f64; 3]]) -> f64 {
    path.windows(2)
        .map(|w| dist_to_segment(p, w[0], w[1]))
        .fold(f64::INFINITY, f64::min)
}

async fn daemon() -> Daemon {
    let d = start(config(Role::Admin)).await;
    d.ctl.replace_offsets_file(TABLE, None).unwrap();
    d
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn restart_inside_a_compensated_contour_follows_the_uninterrupted_path() {
    let d = daemon().await;
    let whole = trajectory(d.channel().await, None).await;
    let restart = trajectory(d.channel().await, Some(60)).await;
    // The approach: ticks without a block number, from where the axes are (the origin).
    let k = restart.iter().position(|(_, b)| b.is_some()).unwrap();
    assert!(k > 0, "an approach comes first");
    assert_eq!(restart[0].1, None);
    let start_n60 = restart[k - 1].0;
    // Retract first: Z never goes below where it starts until over the target.
    let z0 = restart[0].0[2];
    let over = restart[..k]
        .iter()
        .position(|(p, _)| (p[0] - start_n60[0]).abs() < 1e-6 && (p[1] - start_n60[1]).abs() < 1e-6)
        .unwrap();
    assert!(
        restart[..over]
            .iter()
            .all(|(p, _)| p[2] >= z0.min(start_n60[2]) - 1e-9),
        "the approach plunges before it is over the start"
    );
    // The start of N60 is on the equidistant: 3 mm right of X50 (G41 going +Y: the tool on
    // the left of the path, so X = 50 - 3 = 47), at the contour depth Z-2.
    assert!((start_n60[0] - 47.0).abs() < 1e-3, "{start_n60:?}");
    assert!((start_n60[1] - 10.0).abs() < 1e-3, "{start_n60:?}");
    assert!((start_n60[2] + 2.0).abs() < 1e-6, "{start_n60:?}");
    // From there on: every setpoint on the uninterrupted tool path within 1 µm, and the
    // same end.
    let path: Vec<[f64; 3]> = whole.iter().map(|(p, _)| *p).collect();
    let from = whole
        .iter()
        .position(|(_, b)| *b == Some(60))
        .expect("the uninterrupted run passes N60");
    let tail = &path[from.saturating_sub(2)..];
    let mut worst = 0.0f64;
    for (p, _) in &restart[k..] {
        worst = worst.max(dist_to_path(*p, tail));
    }
    assert!(worst <= 1e-3, "{worst} mm off the uninterrupted path");
    let (a, b) = (path.last().unwrap(), restart.last().unwrap().0);
    assert!((0..3).all(|i| (a[i] - b[i]).abs() <= 1e-3), "{a:?} {b:?}");
    // The blocks after the approach are N60 onwards only.
    assert!(restart[k..].iter().all(|(_, n)| n.is_none_or(|n| n >= 60)));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn start_from_block_runs_the_approach_and_the_rest_on_the_machine() {
    let (d, mut m) = daemon_with("contour.nc", CONTOUR).await;
    // A block the program does not have: refused with a code, nothing moves.
    let e = m
        .start(pb::StartRequest {
            from_block: Some(65),
        })
        .await
        .unwrap_err();
    assert_block_not_found(&e);
    run_from(&d, &mut m, 60).await;
    let whole = trajectory(d.channel().await, None).await;
    let end = whole.last().unwrap().0;
    let s = d.ctl.snapshot();
    for (i, e) in end.iter().enumerate() {
        assert!(
            (s.axes.commanded[i] - e).abs() < 1e-3,
            "{i}: {} vs {e}",
            s.axes.commanded[i]
        );
    }
}

/// Incremental moves before the restart block: their positions come from where the program's
/// run started, not from where the axes stand when it restarts.
const INCREMENTAL: &str = "N10 G91 G1 X10 Y5 F3000\n\
N20 X10\n\
N30 Y10\n\
N40 X-5 Y5\n\
N50 X-3\n";

/// Every setpoint of `restart` after its approach (from index `k`) lies on the uninterrupted
/// run `whole` from `from_n` on within 1 µm, and both end at the same point.
fn assert_follows(
    whole: &[([f64; 3], Option<u32>)],
    restart: &[([f64; 3], Option<u32>)],
    k: usize,
    from_n: u32,
) {
    let path: Vec<[f64; 3]> = whole.iter().map(|(p, _)| *p).collect();
    let from = whole
        .iter()
        .position(|(_, b)| *b == Some(from_n))
        .expect("the uninterrupted run passes the block");
    let tail = &path[from.saturating_sub(2)..];
    let worst = restart[k..]
        .iter()
        .map(|(p, _)| dist_to_path(*p, tail))
        .fold(0.0f64, f64::max);
    assert!(worst <= 1e-3, "{worst} mm off the uninterrupted path");
    let (a, b) = (path.last().unwrap(), restart.last().unwrap().0);
    assert!((0..3).all(|i| (a[i] - b[i]).abs() <= 1e-3), "{a:?} {b:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_restart_after_incremental_moves_follows_the_uninterrupted_run() {
    let (d, mut m) = daemon_with("g91.nc", INCREMENTAL).await;
    // The uninterrupted run from where it starts (the origin), then run: the axes end at
    // X12 Y20, away from where the program started.
    let whole = trajectory_of(d.channel().await, "", None).await;
    let job = start_job(&mut m).await;
    wait_job_done(&d, job).await;
    wait_at(&d, [12.0, 20.0, 0.0]).await;
    // Restarted from N30 there: the approach goes to where N30 starts in the run (X20 Y5),
    // and from there the setpoints are the uninterrupted run's.
    let restart = trajectory_of(d.channel().await, "", Some(30)).await;
    let k = restart.iter().position(|(_, b)| b.is_some()).unwrap();
    assert!(k > 0, "an approach comes first");
    // (The first tick has moved already: the setpoint at its end.)
    let p0 = restart[0].0;
    assert!(
        (p0[0] - 12.0).abs() < 0.1 && (p0[1] - 20.0).abs() < 0.1,
        "{p0:?}"
    );
    let at_n30 = restart[k - 1].0;
    assert!(
        (at_n30[0] - 20.0).abs() < 1e-6 && (at_n30[1] - 5.0).abs() < 1e-6,
        "the approach ends at {at_n30:?}, N30 starts at X20 Y5"
    );
    assert_follows(&whole, &restart, k, 30);
    // Loaded again (say after an edit), the program keeps where its last run started.
    m.load_program(named_program("g91.nc", INCREMENTAL))
        .await
        .unwrap();
    let reloaded = trajectory_of(d.channel().await, "", Some(30)).await;
    assert_eq!(reloaded[k - 1].0, at_n30, "the approach after a reload");
    // On the machine: the same end.
    run_from(&d, &mut m, 30).await;
    wait_at(&d, [12.0, 20.0, 0.0]).await;
}

/// Waits until the commanded position settles at `p` (within 1 µm).
async fn wait_at(d: &Daemon, p: [f64; 3]) {
    wait_until(&format!("the axes at {p:?}"), || {
        let c = d.ctl.snapshot().axes.commanded;
        (0..3).all(|i| (c[i] - p[i]).abs() < 1e-6)
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_preview_draws_a_restarts_approach_apart_from_the_program() {
    let (d, _m) = daemon_with("contour.nc", CONTOUR).await;
    let mut p = PreviewClient::new(d.channel().await);
    // Preview data: the approach legs from the origin, over at the height the axes are,
    // then down at feed to the start of N60 on the equidistant; the program's paths are the
    // whole program's, as without a restart.
    let plain = p
        .get_preview_data(pb::PreviewDataRequest::default())
        .await
        .unwrap()
        .into_inner();
    assert!(plain.approach.is_empty());
    let data = p
        .get_preview_data(pb::PreviewDataRequest {
            from_block: Some(60),
            ..Default::default()
        })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(data.programmed, plain.programmed);
    assert_eq!(data.compensated, plain.compensated);
    let legs = &data.approach;
    let near = |a: &[f64], b: [f64; 3]| (0..3).all(|i| (a[i] - b[i]).abs() < 1e-6);
    assert_eq!(legs.len(), 2, "{legs:?}");
    assert_eq!(legs[0].kind, pb::PathKind::Rapid as i32);
    assert!(
        near(&legs[0].start_mm, [0.0, 0.0, 0.0]) && near(&legs[0].end_mm, [47.0, 10.0, 0.0]),
        "{legs:?}"
    );
    assert_eq!(legs[1].kind, pb::PathKind::Line as i32);
    assert!(near(&legs[1].end_mm, [47.0, 10.0, -2.0]), "{legs:?}");
    assert!(
        legs.iter().all(|l| l.block.is_none()),
        "approach legs carry no block number"
    );
    // The outline (the browser's preview) on XZ: one polyline through the leg ends.
    let o = p
        .get_preview_outline(pb::PreviewOutlineRequest {
            plane: "xz".into(),
            from_block: Some(60),
            ..Default::default()
        })
        .await
        .unwrap()
        .into_inner();
    let a = o.approach.expect("an approach polyline");
    assert_eq!(a.starts, vec![0]);
    let pts: Vec<f32> = a.xy_mm;
    let want = [0.0f32, 0.0, 47.0, 0.0, 47.0, -2.0];
    assert_eq!(pts.len(), want.len(), "{pts:?}");
    assert!(
        pts.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-3),
        "{pts:?}"
    );
    let without = p
        .get_preview_outline(pb::PreviewOutlineRequest {
            plane: "xz".into(),
            ..Default::default()
        })
        .await
        .unwrap()
        .into_inner();
    assert!(without.approach.is_none());
    assert_eq!(without.feed, o.feed, "the program's paths do not change");
    // A block the program does not have: refused with the code, as Start refuses it.
    for e in [
        p.get_preview_data(pb::PreviewDataRequest {
            from_block: Some(65),
            ..Default::default()
        })
        .await
        .unwrap_err(),
        p.get_preview_outline(pb::PreviewOutlineRequest {
            from_block: Some(65),
            ..Default::default()
        })
        .await
        .unwrap_err(),
    ] {
        assert_block_not_found(&e);
    }
}

/// `e` refuses a restart block the program does not have, with its code.
fn assert_block_not_found(e: &tonic::Status) {
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    assert!(
        diagnostics(e)
            .iter()
            .any(|d| d.code == "restart_block_not_found"),
        "{e:?}"
    );
}

/// A daemon on the simulated machine with `text` loaded as `name`, and a Machine client.
async fn daemon_with(name: &str, text: &str) -> (Daemon, MachineClient<Channel>) {
    let d = daemon().await;
    let mut m = MachineClient::new(d.channel().await);
    m.load_program(named_program(name, text)).await.unwrap();
    (d, m)
}

/// Starts the selected program from block `n` and waits until that job has ended.
async fn run_from(d: &Daemon, m: &mut MachineClient<Channel>, n: u32) {
    let job = m
        .start(pb::StartRequest {
            from_block: Some(n),
        })
        .await
        .unwrap()
        .into_inner()
        .job;
    wait_job_done(d, job).await;
}

/// Waits until `job` ran to its end and the machine is idle.
async fn wait_job_done(d: &Daemon, job: u32) {
    wait_until("the restarted job to end", || {
        let s = d.ctl.snapshot();
        s.progress.finished_job == job && s.state == MachineState::Idle
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cncctl_start_from_block_shows_the_approach_and_needs_a_confirmation() {
    let d = daemon().await;
    let file = d.ctl.config().storage.dir.join("contour.nc");
    std::fs::write(&file, CONTOUR).unwrap();
    let addr = d.socket();
    let run = |args: Vec<String>| {
        tokio::task::spawn_blocking(move || {
            let mut cmd = Command::new(vcan_support::bin("cncctl"));
            cmd.args(&args)
                .env_remove("CNCCTL_ADDR")
                .stdin(std::process::Stdio::null());
            vcan_support::run_with_timeout(&mut cmd, Duration::from_secs(120))
        })
    };
    let a = |v: &[&str]| -> Vec<String> {
        let mut all = vec!["--addr".to_string(), addr.clone()];
        all.extend(v.iter().map(|s| s.to_string()));
        all
    };
    let (ok, out) = run(a(&["load", file.to_str().unwrap()])).await.unwrap();
    assert!(ok, "{out}");
    let (ok, out) = run(a(&["trajectory", "--from-block", "60"])).await.unwrap();
    assert!(ok, "{out}");
    assert!(out.contains("approach to X47.000 Y10.000 Z-2.000"), "{out}");
    // Without --yes and no terminal: shown, not started.
    let (ok, out) = run(a(&["start", "--from-block", "60"])).await.unwrap();
    assert!(!ok, "{out}");
    assert!(
        out.contains("restart from block N60: approach to X47.000"),
        "{out}"
    );
    assert!(out.contains("confirm the approach with --yes"), "{out}");
    assert_eq!(d.ctl.snapshot().state, MachineState::Idle);
    let (ok, out) = run(a(&["start", "--from-block", "60", "--yes"]))
        .await
        .unwrap();
    assert!(ok, "{out}");
    assert!(out.contains("started job"), "{out}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn after_a_stop_status_names_the_block_to_restart_from() {
    let d = daemon().await;
    let mut m = MachineClient::new(d.channel().await);
    let slow = "N10 G1 X5 F600\nN20 X10\nN30 X40\nN40 X0\n";
    let job = load_and_start(&mut m, "slow.nc", slow).await;
    wait_until("N30 to run", || {
        let s = d.ctl.snapshot();
        s.progress.job == job && s.progress.block_n == Some(30)
    })
    .await;
    m.stop(pb::StopRequest::default()).await.unwrap();
    wait_until("the stop to end", || {
        d.ctl.snapshot().state == MachineState::Idle
    })
    .await;
    let s = status_now(&mut m).await;
    assert_eq!(s.restart_block, Some(30), "{s:?}");
    // Restarted from there it ends where the program ends.
    run_from(&d, &mut m, 30).await;
    assert!(d.ctl.snapshot().axes.commanded[0].abs() < 1e-6);
    assert_eq!(status_now(&mut m).await.restart_block, None);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn block_delete_skips_slashed_blocks_only_while_on() {
    let d = daemon().await;
    let mut m = MachineClient::new(d.channel().await);
    let text = "N10 G1 X10 F3000\n/N20 X20\n";
    m.load_program(named_program("bd.nc", text)).await.unwrap();
    for (on, end) in [(true, 10.0), (false, 20.0)] {
        m.set_block_delete(pb::SetBlockDeleteRequest { on })
            .await
            .unwrap();
        assert_eq!(status_now(&mut m).await.block_delete, on);
        let job = start_job(&mut m).await;
        wait_job_done(&d, job).await;
        let x = d.ctl.snapshot().axes.commanded[0];
        assert!((x - end).abs() < 1e-6, "block delete {on}: X{x}");
        m.mdi(mdi_block("G0 X0")).await.unwrap();
        wait_until("back at X0", || {
            let s = d.ctl.snapshot();
            s.state == MachineState::Idle && s.axes.commanded[0].abs() < 1e-9
        })
        .await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn one_jog_at_a_time_and_no_step_beyond_any_travel() {
    let d = daemon().await;
    let mut m = MachineClient::new(d.channel().await);
    let step = |axis: &str, step_mm: f64| pb::JogStepRequest {
        axis: axis.into(),
        step_mm,
        speed_mm_min: 60.0,
    };
    // No soft limits on the test machine: a step longer than any travel is refused.
    let e = m.jog_step(step("X", 1e12)).await.unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    assert_eq!(diagnostics(&e)[0].code, "jog_beyond_travel");
    // A slow step runs; a continuous jog and a second step meanwhile are refused, and the
    // step ends where it should.
    m.jog_step(step("X", 2.0)).await.unwrap();
    wait_until("the step to move", || {
        d.ctl.snapshot().state == MachineState::Jog
    })
    .await;
    let e = m.jog_step(step("Y", 1.0)).await.unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition, "{e:?}");
    assert_eq!(diagnostics(&e)[0].code, "jog_busy");
    let msg = pb::JogRequest {
        axis: "Y".into(),
        direction: 1,
        speed_mm_min: 600.0,
    };
    let e = m.jog(tokio_stream::iter(vec![msg])).await.unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition, "{e:?}");
    assert_eq!(diagnostics(&e)[0].code, "jog_busy");
    wait_until("the step to end", || {
        let s = d.ctl.snapshot();
        s.state == MachineState::Idle && (s.axes.commanded[0] - 2.0).abs() < 1e-9
    })
    .await;
    assert_eq!(d.ctl.snapshot().axes.commanded[1], 0.0, "Y never moved");
}
