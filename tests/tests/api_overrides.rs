//! HMI overrides and axis state (issue #19) through `cncctl` and gRPC: spindle override
//! (50..120 %, within the gear range), rapid override (0..100 %, G0 only, no jump), homed and
//! soft-limit state in the status stream. The setpoint checks run the daemon's pipeline and
//! RT core in the single-threaded harness (no wall clock).

mod api_common;
mod vcan_support;

use std::process::Command;
use std::time::Duration;

use api_common::*;
use daemon::runtime::clock::SimClock;
use daemon::runtime::config::Role;
use daemon::runtime::harness::{Harness, JobEnd};
use daemon::runtime::rt::{MachineState, RtCommand};
use proto::v1::machine_client::MachineClient;
use tests::{RecordingBus, max_rates};

const TS_S: f64 = 0.004;
/// A bound on the ticks of a run (not a timing).
const MAX_TICKS: u64 = 500_000;

/// Runs the real `cncctl --addr ADDR args..`.
async fn cncctl(addr: &str, args: &[&str]) -> (bool, String) {
    let mut all: Vec<String> = vec!["--addr".into(), addr.into()];
    all.extend(args.iter().map(|s| s.to_string()));
    tokio::task::spawn_blocking(move || {
        let mut cmd = Command::new(vcan_support::bin("cncctl"));
        cmd.args(&all)
            .current_dir(std::env::temp_dir())
            .env_remove("CNCCTL_ADDR");
        vcan_support::run_with_timeout(&mut cmd, Duration::from_secs(60))
    })
    .await
    .unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn spindle_override_scales_the_spindle_within_the_gear_range() {
    let d = start(config(Role::Admin)).await;
    let addr = d.socket();
    let mut m = MachineClient::new(d.channel().await);
    let (ok, out) = cncctl(&addr, &["spindle-override", "80"]).await;
    assert!(ok, "{out}");
    // Outside 50..120: refused, nothing changes.
    let (ok, out) = cncctl(&addr, &["spindle-override", "130"]).await;
    assert!(!ok && out.contains("InvalidArgument"), "{out}");
    let (ok, out) = cncctl(&addr, &["spindle-override", "40"]).await;
    assert!(!ok && out.contains("InvalidArgument"), "{out}");
    wait_until("spindle override 80 %", || {
        d.ctl.snapshot().operator.spindle_override_pct == 80.0
    })
    .await;
    start_mdi(&mut m, "S1000 M3").await;
    // S1000 at 80 %: the spindle is commanded 800 rpm, and gets there.
    wait_until("800 rpm commanded", || {
        (d.ctl.snapshot().spindle.kr.spindle_rpm - 800.0).abs() < 1e-9
    })
    .await;
    wait_until("800 rpm actual", || {
        (d.ctl.snapshot().spindle.rpm - 800.0).abs() < 1.0
    })
    .await;
    let s = api_common::status_now(&mut m).await;
    assert_eq!(s.spindle_override_percent, 80.0);
    assert!((s.spindle_rpm - 800.0).abs() < 1.0, "{}", s.spindle_rpm);
    // 120 % of S5500 would be 6600 rpm: the gear range (P = 6000 rpm) caps it.
    let (ok, out) = cncctl(&addr, &["spindle-override", "120"]).await;
    assert!(ok, "{out}");
    wait_until("idle", || d.ctl.snapshot().state == MachineState::Idle).await;
    start_mdi(&mut m, "S5500").await;
    wait_until("6000 rpm commanded", || {
        (d.ctl.snapshot().spindle.kr.spindle_rpm - 6000.0).abs() < 1e-9
    })
    .await;
    let (ok, out) = cncctl(&addr, &["status", "--json"]).await;
    assert!(ok, "{out}");
    assert!(out.contains("\"spindle_override_percent\":120.0"), "{out}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn rapid_override_homed_and_soft_limits_in_status_and_cncctl() {
    let mut cfg = config(Role::Admin);
    cfg.axes[0].soft_min_mm = Some(0.0);
    cfg.axes[0].soft_max_mm = Some(50.0);
    let d = start(cfg).await;
    let addr = d.socket();
    let (ok, out) = cncctl(&addr, &["rapid-override", "25"]).await;
    assert!(ok, "{out}");
    let (ok, out) = cncctl(&addr, &["rapid-override", "101"]).await;
    assert!(!ok && out.contains("InvalidArgument"), "{out}");
    wait_until("rapid override 25 %", || {
        d.ctl.snapshot().operator.rapid_override_pct == 25.0
    })
    .await;
    let mut m = MachineClient::new(d.channel().await);
    // X starts at 0: at its lower soft limit.
    let s = api_common::status_now(&mut m).await;
    assert_eq!(s.rapid_override_percent, 25.0);
    let x = &s.axes[0];
    assert_eq!(
        (x.at_soft_limit, x.soft_min_mm, x.soft_max_mm),
        (-1, Some(0.0), Some(50.0))
    );
    assert!(x.homed && !x.homing_required, "{x:?}");
    assert_eq!(s.axes[1].at_soft_limit, 0);
    start_mdi(&mut m, "G0 X50").await;
    wait_until("idle at X50", || {
        let s = d.ctl.snapshot();
        s.state == MachineState::Idle && s.axes.commanded[0] == 50.0
    })
    .await;
    let (ok, out) = cncctl(&addr, &["status", "--json"]).await;
    assert!(ok, "{out}");
    assert!(out.contains("\"rapid_override_percent\":25.0"), "{out}");
    assert!(out.contains("\"at_soft_limit\":1"), "{out}");
    assert!(!out.contains("\"homed\":false"), "{out}");
    let (ok, out) = cncctl(&addr, &["status"]).await;
    assert!(
        ok && out.contains("rapid 25%") && out.contains("(at soft max)"),
        "{out}"
    );
}

/// A rapid with the override changed while it moves (RT core and pipeline as cncd runs them):
/// the speed follows the override within the axis limits, the path and the end point hold.
#[test]
fn rapid_override_changes_speed_without_a_jump() {
    let run = |overrides: &[(u64, f64)]| {
        let cfg = tests::test_config();
        let bus = sim::SimBus::new(sim::SimDriveParams::default(), &[0.0; 3]);
        let (bus, record) = RecordingBus::new(bus);
        let mut h = Harness::new(cfg, Box::new(bus), SimClock::exact()).unwrap();
        h.wait_state(MachineState::Idle, 10_000).unwrap();
        let t0 = h.snapshot().tick.sequence;
        let skip = record.lock().unwrap().len();
        for &(tick, pct) in overrides {
            h.at_tick(t0 + tick, RtCommand::RapidOverride(pct));
        }
        let end = h.run_program("G0 X200 Y100\n", MAX_TICKS).unwrap();
        assert!(matches!(end, JobEnd::Finished), "{end:?}");
        let points = record.lock().unwrap()[skip..].to_vec();
        let ticks = h.snapshot().tick.sequence - t0;
        (points, ticks)
    };
    let (full, full_ticks) = run(&[]);
    let (slow, slow_ticks) = run(&[(1, 20.0), (600, 100.0)]);
    let lim_full = max_rates(&full, 3, TS_S);
    let lim_slow = max_rates(&slow, 3, TS_S);
    for i in 0..2 {
        // Never faster or harder than the rapid at 100 % (which runs at the axis limits).
        assert!(
            lim_slow[i].0 <= lim_full[i].0 * (1.0 + 1e-9),
            "{lim_slow:?} {lim_full:?}"
        );
        assert!(
            lim_slow[i].1 <= lim_full[i].1 * (1.0 + 1e-6),
            "{lim_slow:?} {lim_full:?}"
        );
    }
    // At 20 % the first 600 ticks stay near a fifth of the full rapid's speed (20 % of the
    // rapid speed; at 100 % the axis limit caps it a little below that).
    let early = max_rates(&slow[..600.min(slow.len())], 3, TS_S);
    assert!(
        early[0].0 <= 0.25 * lim_full[0].0 && early[0].0 >= 0.15 * lim_full[0].0,
        "{early:?} {lim_full:?}"
    );
    assert!(slow_ticks > full_ticks, "{slow_ticks} {full_ticks}");
    // On the line from the start to X200 Y100 all the way, and exactly at its end.
    for p in &slow {
        assert!((p[1] * 2.0 - p[0]).abs() < 1e-6, "off the line: {p:?}");
    }
    let last = slow.last().unwrap();
    assert_eq!((last[0], last[1]), (200.0, 100.0));
}
