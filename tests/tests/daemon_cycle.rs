//! Issue #23: `[bus] cycle_ms` of 1..10 ms beside the kernel's 4 ms interpolation period.
//!
//! The daemon's pipeline and RT core in the single-threaded harness (virtual time, seeded
//! clock) on the bus the daemon builds from `[bus] kind = "sim"` with `cycle_ms`, every bus
//! setpoint recorded. The same program at 1, 2, 4, 5 and 10 ms follows the same path: every
//! bus setpoint lies on the 4 ms run's setpoint polyline within the bound of the resampling
//! (a moving average over 4 ms: |P[j−1] − 2·P[j] + P[j+1]| / 8), with no jump and with the
//! velocity and acceleration of the bus setpoints (finite differences at the bus period)
//! within the axis limits. Late ticks at 2 ms keep the 2 ms grid, count overruns exactly and
//! change no setpoint.

mod api_common;

use std::sync::{Arc, Mutex};

use daemon::runtime::buses::{BusConfig, open_bus};
use daemon::runtime::clock::SimClock;
use daemon::runtime::config::Config;
use daemon::runtime::harness::{Harness, JobEnd};
use daemon::runtime::rt::{MachineState, RtCommand};
use hal::{BusFault, CycleCommand, CycleFeedback, DriveBus, MAX_AXES};
use kernel::jog::JogRequest;
use tests::PART;

const TS_NS: u64 = 4_000_000;
const MAX_TICKS: u64 = 2_000_000;
const PERIODS_MS: [u64; 5] = [1, 2, 4, 5, 10];

type Points = Arc<Mutex<Vec<[f64; MAX_AXES]>>>;

/// The daemon's bus, every setpoint it is sent recorded.
struct Recorded {
    inner: Box<dyn DriveBus>,
    points: Points,
}

impl DriveBus for Recorded {
    daemon::delegate_drive_bus!(
        inner: name, axes, has_spindle, enable, reset, safe_state, supports_homing, home_switch,
        set_home
    );
    fn cycle(&mut self, cmd: &CycleCommand, fb: &mut CycleFeedback) -> Result<(), BusFault> {
        self.points.lock().unwrap().push(cmd.positions_mm);
        self.inner.cycle(cmd, fb)
    }
}

fn config(cycle_ms: u64) -> Config {
    let mut cfg = tests::test_config();
    cfg.bus = BusConfig::Sim {
        cycle_ms: cycle_ms as f64,
    };
    cfg.validate().unwrap();
    cfg
}

/// The daemon at `cycle_ms` on the bus it builds, idle.
fn machine(cycle_ms: u64, clock: SimClock) -> (Harness, Points, Config) {
    let cfg = config(cycle_ms);
    let inner = open_bus(
        &cfg.bus,
        &cfg.axes,
        &cfg.sim,
        &daemon::runtime::buses::IoWiring::of(&cfg),
    )
    .unwrap();
    let points = Points::default();
    let bus = Recorded {
        inner,
        points: points.clone(),
    };
    let mut h = Harness::new(cfg.clone(), Box::new(bus), clock).unwrap();
    h.wait_state(MachineState::Idle, 100_000).unwrap();
    (h, points, cfg)
}

fn dist(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt()
}

/// Distance of `p` from the segment `a`-`b`.
fn seg_dist(p: &[f64], a: &[f64], b: &[f64]) -> f64 {
    let ab: Vec<f64> = a.iter().zip(b).map(|(x, y)| y - x).collect();
    let len2: f64 = ab.iter().map(|x| x * x).sum();
    let t = if len2 == 0.0 {
        0.0
    } else {
        let ap: f64 = a
            .iter()
            .zip(p)
            .zip(&ab)
            .map(|((x, y), d)| (y - x) * d)
            .sum();
        (ap / len2).clamp(0.0, 1.0)
    };
    let q: Vec<f64> = a.iter().zip(&ab).map(|(x, d)| x + t * d).collect();
    dist(p, &q)
}

/// Largest |P[j−1] − 2·P[j] + P[j+1]| of a 4 ms setpoint stream, mm.
fn max_second_difference(points: &[[f64; MAX_AXES]], axes: usize) -> f64 {
    points
        .windows(3)
        .map(|w| {
            let d: Vec<f64> = (0..axes)
                .map(|i| w[0][i] - 2.0 * w[1][i] + w[2][i])
                .collect();
            dist(&d, &vec![0.0; axes])
        })
        .fold(0.0, f64::max)
}

/// Walks `points` along the polyline `reference` with a cursor that only moves forward (at
/// most `window` segments per point) and stops at the first segment within `tol_mm` (the path
/// retraces itself: an arc back along the arc it came on): the largest distance of a point
/// from the polyline, and whether the walk reached the polyline's end.
fn walk(
    points: &[[f64; MAX_AXES]],
    reference: &[[f64; MAX_AXES]],
    axes: usize,
    tol_mm: f64,
) -> (f64, bool) {
    let window = 64;
    let last = reference.len() - 1;
    let mut cursor = 0;
    let mut worst = 0.0f64;
    for p in points {
        let mut best = (f64::INFINITY, cursor);
        for k in cursor..(cursor + window).min(last) {
            let d = seg_dist(&p[..axes], &reference[k][..axes], &reference[k + 1][..axes]);
            if d < best.0 {
                best = (d, k);
            }
            if d <= tol_mm {
                break;
            }
        }
        worst = worst.max(best.0);
        cursor = best.1;
    }
    // The end: the segment the walk ended on leads to where the reference ends (it ends at
    // rest, on a run of equal points).
    let end = &reference[last][..axes];
    (worst, dist(&reference[cursor + 1][..axes], end) < 1e-9)
}

/// (max |v|, max |a|) per axis of a setpoint stream sampled every `dt_s`.
fn rates(points: &[[f64; MAX_AXES]], axes: usize, dt_s: f64) -> Vec<(f64, f64)> {
    tests::max_rates(points, axes, dt_s)
}

/// The recorded setpoints of one run of `PART` at `cycle_ms`, from the start of the job.
fn run_part(cycle_ms: u64) -> (Vec<[f64; MAX_AXES]>, Config, u64) {
    let (mut h, points, cfg) = machine(cycle_ms, SimClock::exact());
    let from = points.lock().unwrap().len();
    let t0 = h.snapshot().tick.time_ns;
    assert_eq!(h.run_program(PART, MAX_TICKS).unwrap(), JobEnd::Finished);
    // Let the drives and the smoothing come to rest.
    for _ in 0..(40 / cycle_ms) {
        h.step();
    }
    let s = h.snapshot();
    assert_eq!(s.tick.cycle_ns, cycle_ms * 1_000_000);
    let duration_ms = (s.tick.time_ns - t0) / 1_000_000;
    // From the setpoint before the job's first (where the machine stood).
    let p = points.lock().unwrap()[from - 1..].to_vec();
    if std::env::var("CYCLE_DEBUG").is_ok() {
        let text: String = p
            .iter()
            .map(|q| format!("{} {} {}\n", q[0], q[1], q[2]))
            .collect();
        std::fs::write(format!("/tmp/cycle_{cycle_ms}.txt"), text).unwrap();
    }
    (p, cfg, duration_ms)
}

#[test]
fn the_same_program_follows_the_same_path_at_every_bus_period() {
    let (reference, cfg, ref_ms) = run_part(4);
    let axes = cfg.axes.len();
    // The resampling's bound, from the 4 ms run's own setpoints ...
    let bound_mm = max_second_difference(&reference, axes) / 8.0;
    // ... which the axis limits bound in turn: a·Ts²/8 per axis.
    let ts_s = TS_NS as f64 * 1e-9;
    let limit_bound: f64 = cfg
        .axes
        .iter()
        .map(|a| (a.max_accel_mm_s2 * ts_s * ts_s / 8.0).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(
        bound_mm <= limit_bound * (1.0 + 1e-6),
        "{bound_mm} > {limit_bound}"
    );
    assert!(bound_mm > 0.0);
    let ref_rates = rates(&reference, axes, ts_s);
    for ms in PERIODS_MS {
        let (points, _, duration_ms) = if ms == 4 {
            (reference.clone(), cfg.clone(), ref_ms)
        } else {
            run_part(ms)
        };
        // Same path: every bus setpoint on the 4 ms polyline within the bound, the walk
        // along it reaching its end, the same end point.
        let (worst_mm, reached_end) = walk(&points, &reference, axes, bound_mm + 1e-9);
        assert!(
            worst_mm <= bound_mm + 1e-9,
            "{ms} ms: {worst_mm} mm off the 4 ms path (bound {bound_mm})"
        );
        assert!(reached_end, "{ms} ms: the path did not reach its end");
        let last = points.last().unwrap();
        let end = reference.last().unwrap();
        assert!(
            dist(&last[..axes], &end[..axes]) < 1e-9,
            "{ms} ms: {last:?}"
        );
        assert!((end[0], end[1], end[2]) == (0.0, 0.0, 5.0), "{end:?}");
        // Same speed: the same machining time within the block-end waits (a few ticks each).
        assert!(
            duration_ms.abs_diff(ref_ms) <= 100,
            "{ms} ms: {duration_ms} ms, 4 ms: {ref_ms} ms"
        );
        // No jump, no overshoot of the axis limits, at the bus period.
        let dt_s = ms as f64 * 1e-3;
        for (i, ((v, a), (v4, a4))) in rates(&points, axes, dt_s)
            .into_iter()
            .zip(&ref_rates)
            .enumerate()
        {
            let ax = &cfg.axes[i];
            let (v_lim, a_lim) = (ax.max_velocity_mm_min / 60.0, ax.max_accel_mm_s2);
            assert!(
                v <= v4 * (1.0 + 1e-6) + 1e-6,
                "{ms} ms axis {i}: v {v} > {v4}"
            );
            assert!(
                a <= a4 * (1.0 + 1e-6) + 1e-6,
                "{ms} ms axis {i}: a {a} > {a4}"
            );
            assert!(
                v <= v_lim * (1.0 + 1e-6),
                "{ms} ms axis {i}: v {v} > {v_lim}"
            );
            assert!(
                a <= a_lim * (1.0 + 1e-6),
                "{ms} ms axis {i}: a {a} > {a_lim}"
            );
            assert!(v > 0.5 * v4, "{ms} ms axis {i}: v {v} of {v4}");
        }
    }
}

/// Late ticks at 2 ms, exactly as late as the test says: each skips `lateness / 2 ms` grid
/// points, counted as overruns exactly; the next deadline is the next point of the 2 ms grid;
/// and the setpoints are those of a run on an exact clock, bit for bit (trajectory time is one
/// bus period per executed tick).
#[test]
fn late_ticks_at_2ms_keep_the_grid_and_count_overruns_exactly() {
    const CYCLE_NS: u64 = 2_000_000;
    let mut clock = SimClock::exact();
    let forced = [
        (300, CYCLE_NS / 2),
        (350, 5 * CYCLE_NS / 2),
        (400, 7 * CYCLE_NS),
        (450, CYCLE_NS - 1),
        (500, 40 * CYCLE_NS + 3),
        // Late by one 4 ms interpolation period: two bus periods.
        (550, TS_NS),
    ];
    clock.forced = forced.to_vec();
    let expected: u64 = forced.iter().map(|&(_, l)| l / CYCLE_NS).sum();
    assert_eq!(expected, 2 + 7 + 40 + 2);
    let program = "G1 X200 Y100 F6000\n";
    let (mut h, points, _) = machine(2, clock);
    let overruns0 = h.snapshot().tick.stats.overruns;
    let job = h.start_program(program).unwrap();
    tests::run_on_the_grid(&mut h, job, CYCLE_NS);
    assert_eq!(h.snapshot().tick.stats.overruns - overruns0, expected);
    assert!(h.clock().wakeups() > 550);

    let (mut exact, exact_points, _) = machine(2, SimClock::exact());
    let job = exact.start_program(program).unwrap();
    exact
        .run_until(100_000, |s| s.progress.finished_job == job)
        .unwrap();
    assert_eq!(h.setpoint_hash(), exact.setpoint_hash());
    let (a, b) = (points.lock().unwrap(), exact_points.lock().unwrap());
    assert_eq!(a.len(), b.len());
    assert!(a.iter().zip(b.iter()).all(|(x, y)| x == y));
}

/// A jog at 1 and 10 ms: the same travel as at 4 ms, within the axis limits at the bus period,
/// and the lease (0.5 s) counts time, not bus ticks.
#[test]
fn jog_and_its_lease_count_time_at_every_bus_period() {
    for ms in [1, 4, 10] {
        let (mut h, points, cfg) = machine(ms, SimClock::exact());
        let from = points.lock().unwrap().len();
        let a = &cfg.axes[0];
        h.send(RtCommand::Jog(JogRequest {
            axis: 0,
            target_mm: 1000.0,
            speed_mm_s: 50.0,
            accel_mm_s2: a.max_accel_mm_s2,
            // Lease of 125 interpolator steps: 0.5 s whatever the bus period.
            lease_ticks: 125,
        }))
        .unwrap();
        h.wait_state(MachineState::Jog, 100).unwrap();
        let s = h.wait_state(MachineState::Idle, 100_000).unwrap();
        let travel = s.axes.commanded[0];
        // The jog ends where the axis stands: no setpoint goes back (the path resumes there).
        for _ in 0..20 {
            let t = h.step();
            assert!(
                (t.axes.commanded[0] - travel).abs() < 0.01,
                "{ms} ms: {t:?}"
            );
        }
        // 0.5 s of lease at ≤ 50 mm/s plus the braking: about 25 mm whatever the period.
        assert!((20.0..=27.0).contains(&travel), "{ms} ms: {travel} {s:?}");
        let p = points.lock().unwrap()[from..].to_vec();
        let (v, acc) = rates(&p, 1, ms as f64 * 1e-3)[0];
        assert!(v <= 50.0 * (1.0 + 1e-6), "{ms} ms: v {v}");
        assert!(acc <= a.max_accel_mm_s2 * (1.0 + 1e-6), "{ms} ms: a {acc}");
    }
}

/// Through the door: the threaded daemon (controller, RT thread on the monotonic clock, gRPC)
/// configured with `[bus] kind = "sim"`, `cycle_ms = 2` runs a program over the API to its
/// exact end; the status reports the 2 ms tick; the whole bus setpoint stream, at 2 ms, stays
/// within the axis limits. No timing is asserted (trajectory time is one bus period per
/// executed tick, whatever the machine's load).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_program_runs_through_grpc_at_a_2ms_bus_period() {
    use daemon::runtime::controller::{ClockKind, Controller};
    use proto::v1 as pb;
    use proto::v1::machine_client::MachineClient;

    let cfg = config(2);
    let limits: Vec<(f64, f64)> = cfg
        .axes
        .iter()
        .map(|a| (a.max_velocity_mm_min / 60.0, a.max_accel_mm_s2))
        .collect();
    let points = Points::default();
    let bus = Recorded {
        inner: open_bus(
            &cfg.bus,
            &cfg.axes,
            &cfg.sim,
            &daemon::runtime::buses::IoWiring::of(&cfg),
        )
        .unwrap(),
        points: points.clone(),
    };
    let ctl = Controller::start_with_bus(cfg, ClockKind::Monotonic, Box::new(bus)).unwrap();
    // The Unix socket gives local control (loopback TCP only observes).
    let mut client = MachineClient::new(api_common::serve_unix_channel(&ctl).await);
    tests::wait_state(&ctl, MachineState::Idle).await;
    client
        .load_program(api_common::named_program("part.nc", PART))
        .await
        .unwrap();
    let from = points.lock().unwrap().len();
    let job = api_common::start_job(&mut client).await;
    tests::wait_job_finished(&ctl, job).await;
    let status = client
        .stream_status(pb::StatusRequest { rate_hz: 50 })
        .await
        .unwrap()
        .into_inner()
        .message()
        .await
        .unwrap()
        .unwrap();
    assert_eq!(status.ticks.unwrap().cycle_us, 2000);
    assert_eq!(ctl.snapshot().axes.commanded.0[..3], [0.0, 0.0, 5.0]);
    let p = points.lock().unwrap()[from..].to_vec();
    for (i, ((v, a), (v_lim, a_lim))) in rates(&p, 3, 0.002).into_iter().zip(&limits).enumerate() {
        assert!(v <= v_lim * (1.0 + 1e-6), "axis {i}: v {v} > {v_lim}");
        assert!(a <= a_lim * (1.0 + 1e-6), "axis {i}: a {a} > {a_lim}");
        assert!(v > 0.0);
    }
    ctl.shutdown();
}

/// A bus whose drives never become operational, with its own enable deadline of 500 of its
/// ticks.
struct NeverEnabled;

impl DriveBus for NeverEnabled {
    fn name(&self) -> &str {
        "never"
    }
    fn axes(&self) -> usize {
        3
    }
    fn cycle(&mut self, _cmd: &CycleCommand, fb: &mut CycleFeedback) -> Result<(), BusFault> {
        for a in &mut fb.axes[..3] {
            a.state = hal::DriveState::Enabling;
        }
        Ok(())
    }
    fn enable(&mut self) {}
    fn reset(&mut self) {}
    fn enable_timeout_ticks(&self) -> u32 {
        500
    }
}

/// The enabling window is time: the bus's deadline (500 of its ticks) at its period plus 1 s,
/// whatever the period.
#[test]
fn the_enabling_window_is_the_bus_deadline_in_time_plus_one_second() {
    for ms in [1, 2, 4, 10] {
        let mut h = Harness::new(config(ms), Box::new(NeverEnabled), SimClock::exact()).unwrap();
        let s = h.wait_state(MachineState::Fault, 100_000).unwrap();
        assert_eq!(s.alarm.fault.unwrap().reason, hal::FaultReason::Timeout);
        let window_ms = 500 * ms + 1000;
        let at_ms = s.tick.time_ns / 1_000_000;
        assert!(
            at_ms > window_ms && at_ms <= window_ms + 2 * 4 + ms,
            "{ms} ms: alarm at {at_ms} ms, window {window_ms} ms"
        );
    }
}

/// A drive fault mid-motion at 2 ms: the machine stops, the healthy axes brake within their
/// stop deceleration measured at the bus period, the faulted axis holds, and a reset brings
/// the machine back to idle from where the drives stand.
#[test]
fn a_drive_fault_at_2ms_brakes_within_the_limits_and_resets() {
    let cfg = config(2);
    let sim = sim::SimBus::new(sim::SimDriveParams::default(), &[0.0; 3]).with_cycle_s(0.002);
    let (faultable, fault_axis) = tests::FaultableBus::new(sim);
    let points = Points::default();
    let bus = Recorded {
        inner: Box::new(faultable),
        points: points.clone(),
    };
    let mut h = Harness::new(cfg.clone(), Box::new(bus), SimClock::exact()).unwrap();
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    let job = h.start_program("G1 X200 Y100 F6000").unwrap();
    h.run_until(100_000, |s| s.axes.path_v_mm_s > 50.0).unwrap();
    let from = points.lock().unwrap().len();
    fault_axis.store(1, std::sync::atomic::Ordering::Relaxed);
    let s = h.wait_state(MachineState::Fault, 10).unwrap();
    assert_eq!(s.alarm.fault.unwrap().axis, Some(1));
    // 0.5 s: the brake ends at rest.
    for _ in 0..250 {
        h.step();
    }
    assert_eq!(h.snapshot().progress.aborted_job, job);
    let p = points.lock().unwrap()[from.saturating_sub(2)..].to_vec();
    let (v, a) = rates(&p, 1, 0.002)[0];
    let decel = cfg.axes[0].stop_decel();
    assert!(a <= decel * (1.0 + 1e-6), "X: a {a} > {decel}");
    assert!(v > 0.0);
    let last = p.last().unwrap();
    assert!(
        p[p.len() - 20..].iter().all(|q| q[0] == last[0]),
        "X at rest: {:?}",
        &p[p.len() - 20..]
    );
    h.send(RtCommand::Reset).unwrap();
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    assert_eq!(
        h.run_program("G0 X0 Y0", 100_000).unwrap(),
        JobEnd::Finished
    );
}

/// A reference run at 1 and 10 ms on the simulated bus's home switch: the axis is homed, its
/// setpoint becomes the reference without a jump, and the bus setpoints stay within the axis
/// limits at the bus period.
#[test]
fn homing_at_1ms_and_10ms_takes_the_reference_without_a_jump() {
    use daemon::runtime::rt_core::HomeRequest;
    for ms in [1, 10] {
        let mut cfg = config(ms);
        cfg.axes[0].sim_home_switch_mm = Some(-12.0);
        cfg.axes[0].reference_mm = 100.0;
        let points = Points::default();
        let bus = Recorded {
            inner: open_bus(
                &cfg.bus,
                &cfg.axes,
                &cfg.sim,
                &daemon::runtime::buses::IoWiring::of(&cfg),
            )
            .unwrap(),
            points: points.clone(),
        };
        let mut h = Harness::new(cfg.clone(), Box::new(bus), SimClock::exact()).unwrap();
        h.wait_state(MachineState::Idle, 100_000).unwrap();
        let from = points.lock().unwrap().len();
        let a = &cfg.axes[0];
        h.send(RtCommand::Home(HomeRequest {
            axis: 0,
            direction: -1.0,
            speed_mm_s: 20.0,
            accel_mm_s2: a.max_accel_mm_s2,
            reference_mm: 100.0,
            max_travel_mm: 50.0,
        }))
        .unwrap();
        h.wait_state(MachineState::Homing, 100).unwrap();
        let s = h.wait_state(MachineState::Idle, 100_000).unwrap();
        assert_eq!(s.axes.homed & 1, 1, "{ms} ms: {s:?}");
        // The setpoint shifted with the drive's position: the axis stands at about the
        // reference (the braking distance past the switch at 20 mm/s).
        for _ in 0..(100 / ms) {
            h.step();
        }
        let s = h.snapshot();
        assert!((s.axes.commanded[0] - 100.0).abs() < 1.0, "{ms} ms: {s:?}");
        assert!(
            (s.axes.commanded[0] - s.axes.actual[0]).abs() < 0.05,
            "{ms} ms: {s:?}"
        );
        // Within the limits up to the shift (the shift moves drive and setpoint together).
        let p = points.lock().unwrap()[from..].to_vec();
        let shift_at = p.iter().position(|q| q[0] > 50.0).unwrap();
        let (v, acc) = rates(&p[..shift_at], 1, ms as f64 * 1e-3)[0];
        assert!(v <= 20.0 * (1.0 + 1e-6), "{ms} ms: v {v}");
        assert!(acc <= a.max_accel_mm_s2 * (1.0 + 1e-6), "{ms} ms: a {acc}");
        let (v, _) = rates(&p[shift_at..], 1, ms as f64 * 1e-3)[0];
        assert!(v <= 20.0 * (1.0 + 1e-6), "{ms} ms: after the shift v {v}");
    }
}
