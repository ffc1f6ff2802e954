//! The browser's jog dead-man over grpc-web (issue #30): `Machine.JogLease` moves an axis while
//! the client renews it and the axis brakes to rest when the renewals stop; `JogStop` brakes at
//! once. Distances, not wall-clock times, are checked: the lease runs in RT ticks, so "at rest
//! within lease + braking" is "no further than the lease's travel plus the braking distance".

mod api_common;
mod hmi_common;

use std::time::Duration;

use api_common::{OPERATOR_TOKEN, config, wait_until, with_token};
use daemon::runtime::config::Role;
use daemon::runtime::rt::MachineState;
use hmi_common::wait_state;
use proto::v1 as pb;
use tonic::Code;

const TS_S: f64 = kernel::units::TS_S;
const SPEED_MM_MIN: f64 = 600.0;

fn lease(axis: &str, direction: i32, lease_ms: u32) -> tonic::Request<pb::JogLeaseRequest> {
    with_token(
        pb::JogLeaseRequest {
            axis: axis.into(),
            direction,
            speed_mm_min: SPEED_MM_MIN,
            lease_ms,
        },
        OPERATOR_TOKEN,
    )
}

/// Jog speed (mm/s) and braking distance (mm) of axis X.
fn speed_and_brake(h: &hmi_common::Hmi) -> (f64, f64) {
    let a = &h.ctl.config().axes[0];
    let v = SPEED_MM_MIN.min(a.max_velocity_mm_min) / 60.0;
    (v, v * v / (2.0 * a.max_accel_mm_s2))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_leased_jog_moves_while_renewed_and_rests_within_lease_and_braking() {
    let h = hmi_common::start(config(Role::Admin)).await;
    let mut m = h.machine();
    let (v, brake_mm) = speed_and_brake(&h);
    let lease_ms = 500;
    // Renewed well inside the lease, as the HMI does while the button is held.
    let (mut before, mut after) = (0.0, 0.0);
    for i in 0..20 {
        if i > 0 {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        before = h.ctl.snapshot().axes.commanded[0];
        let r = m
            .jog_lease(lease("X", 1, lease_ms))
            .await
            .unwrap()
            .into_inner();
        after = h.ctl.snapshot().axes.commanded[0];
        assert!(r.target_mm > 1e6, "no soft limit: far away, {r:?}");
        if i == 0 {
            wait_state(&h.ctl, MachineState::Jog).await;
        }
    }
    let moving = h.ctl.snapshot();
    assert_eq!(moving.state, MachineState::Jog);
    assert!(moving.axes.commanded[0] > 0.1, "{moving:?}");
    // No renewal any more: the axis brakes to rest by itself.
    wait_state(&h.ctl, MachineState::Idle).await;
    let rest = h.ctl.snapshot().axes.commanded[0];
    let lease_mm = v * f64::from(lease_ms) / 1000.0;
    // The last renewal was taken no earlier than `before` was read, and within two ticks of
    // the read after it: the lease's travel and the braking distance after it, a few ticks.
    let slack_mm = 3.0 * v * TS_S + 1e-6;
    assert!(
        rest <= after + 2.0 * v * TS_S + lease_mm + brake_mm + slack_mm,
        "ran on too far: rest {rest}, last renewal at {before}..{after}, lease {lease_mm} mm, \
         brake {brake_mm} mm"
    );
    assert!(
        rest >= before + lease_mm + brake_mm - slack_mm,
        "stopped before the lease ran out: rest {rest}, renewal at {before}"
    );
    let c = h.ctl.clone();
    wait_until("the axis at rest", || c.snapshot().axes.path_v_mm_s == 0.0).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn jog_stop_brakes_at_once() {
    let h = hmi_common::start(config(Role::Admin)).await;
    let mut m = h.machine();
    let (v, brake_mm) = speed_and_brake(&h);
    m.jog_lease(lease("Y", -1, 1000)).await.unwrap();
    let c = h.ctl.clone();
    wait_until("Y moving", || c.snapshot().axes.commanded[1] < -0.05).await;
    m.jog_stop(with_token(pb::JogStopRequest {}, OPERATOR_TOKEN))
        .await
        .unwrap();
    let at_stop = h.ctl.snapshot().axes.commanded[1];
    wait_state(&h.ctl, MachineState::Idle).await;
    let rest = h.ctl.snapshot().axes.commanded[1];
    // The braking distance (two ticks until the RT thread takes the stop), not the lease's
    // second of travel.
    assert!(
        at_stop - rest <= brake_mm + 3.0 * v * TS_S + 1e-6,
        "ran on {} mm after JogStop (brake {brake_mm} mm)",
        at_stop - rest
    );
    // A no-op when nothing runs.
    m.jog_stop(with_token(pb::JogStopRequest {}, OPERATOR_TOKEN))
        .await
        .unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn another_axis_or_direction_while_jogging_is_refused() {
    let h = hmi_common::start(config(Role::Admin)).await;
    let mut m = h.machine();
    m.jog_lease(lease("X", 1, 1000)).await.unwrap();
    wait_state(&h.ctl, MachineState::Jog).await;
    for (axis, dir) in [("Y", 1), ("X", -1)] {
        let e = m.jog_lease(lease(axis, dir, 1000)).await.unwrap_err();
        assert_eq!(e.code(), Code::FailedPrecondition, "{axis}{dir}: {e:?}");
        assert!(e.message().contains("X+"), "{e:?}");
    }
    // The same axis and direction renews (lower case letters too).
    m.jog_lease(lease("x", 1, 1000)).await.unwrap();
    m.jog_stop(with_token(pb::JogStopRequest {}, OPERATOR_TOKEN))
        .await
        .unwrap();
    wait_state(&h.ctl, MachineState::Idle).await;
    // At rest another axis may go.
    m.jog_lease(lease("Y", 1, 100)).await.unwrap();
    wait_state(&h.ctl, MachineState::Idle).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_lease_outside_its_bounds_or_a_bad_direction_is_invalid() {
    let h = hmi_common::start(config(Role::Admin)).await;
    let mut m = h.machine();
    for (dir, ms) in [(1, 99), (1, 1001), (0, 500), (2, 500)] {
        let e = m.jog_lease(lease("X", dir, ms)).await.unwrap_err();
        assert_eq!(e.code(), Code::InvalidArgument, "{dir} {ms}: {e:?}");
    }
    let e = m.jog_lease(lease("Q", 1, 500)).await.unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    assert_eq!(h.ctl.snapshot().state, MachineState::Idle);
}
