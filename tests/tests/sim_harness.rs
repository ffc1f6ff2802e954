//! The daemon's pipeline and RT core in the single-threaded simulation harness
//! (`daemon::runtime::harness`): a seeded clock with jitter, late ticks and missed deadlines,
//! the simulated machine, everything stepped in one thread. No wall clock, no other threads:
//! these tests give the same result on an idle laptop and on a loaded CI machine.

use std::sync::atomic::Ordering;

use daemon::runtime::clock::SimClock;
use daemon::runtime::config::Config;
use daemon::runtime::harness::{Harness, JobEnd};
use daemon::runtime::rt::{MachineState, RtCommand};
use kernel::units::TS_NS;
use tests::{FaultableBus, PART, Recording, RecordingBus, max_rates};

const TS_S: f64 = 0.004;
/// A bound on the ticks of any run here (about 3.3 hours of machining): not a timing.
const MAX_TICKS: u64 = 3_000_000;

fn sim_bus(cfg: &Config) -> sim::SimBus {
    sim::SimBus::new(sim::SimDriveParams::default(), &vec![0.0; cfg.axes.len()])
}

fn recorded(clock: SimClock) -> (Harness, Recording, Config) {
    let cfg = tests::test_config();
    let (bus, record) = RecordingBus::new(sim_bus(&cfg));
    let h = Harness::new(cfg.clone(), Box::new(bus), clock).unwrap();
    (h, record, cfg)
}

/// About 3 hours of machining (120 zig-zag passes of 300 mm at 200 mm/min) on a clock that
/// jitters and misses deadlines: every tick executed, the end exact, the overruns those the
/// clock caused.
#[test]
fn hours_of_machining_in_seconds() {
    let mut text = String::from("G0 X0 Y0\nG1 F200\n");
    for i in 0..120 {
        let x = if i % 2 == 0 { 300 } else { 0 };
        text.push_str(&format!("N{} X{x} Y{:.2}\n", i + 1, i as f64 * 0.1));
    }
    let mut h = Harness::new(
        tests::test_config(),
        Box::new(sim_bus(&tests::test_config())),
        SimClock::seeded(3, 800_000, 1000),
    )
    .unwrap();
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    let (t0, seq0, deadline0) = (
        h.snapshot().tick.time_ns,
        h.snapshot().tick.sequence,
        h.core().next_deadline_ns(),
    );
    let overruns0 = h.snapshot().tick.stats.overruns;
    let end = h.run_program(&text, MAX_TICKS).unwrap();
    assert_eq!(end, JobEnd::Finished);
    let s = h.snapshot();
    let machining_s = (s.tick.time_ns - t0) as f64 * 1e-9;
    assert!(
        machining_s > 3.0 * 3600.0 * 0.95,
        "machined {machining_s} s"
    );
    assert!(s.axes.commanded[0].abs() < 1e-9 && (s.axes.commanded[1] - 11.9).abs() < 1e-9);
    // The clock was late now and then: the grid skipped those periods and did not drift. The
    // deadlines advanced by one period per tick executed plus one per period skipped.
    let overruns = s.tick.stats.overruns - overruns0;
    assert!(overruns > 100, "{:?}", s.tick.stats);
    let ticks = s.tick.sequence - seq0;
    assert_eq!(
        h.core().next_deadline_ns() - deadline0,
        (ticks + overruns) * TS_NS
    );
}

/// Late ticks, exactly as late as the test says: each skips `lateness / Ts` grid points
/// (counted as overruns, exactly), the next deadline is the next grid point after the wake-up,
/// and the setpoints do not jump (the trajectory advances one Ts per executed tick).
#[test]
fn late_ticks_skip_grid_points_counted_exactly_without_setpoint_jump() {
    let mut clock = SimClock::exact();
    // (wake-up, lateness): under a period, 2.5 periods, exactly 7 periods, 1 ns short of 1.
    let forced = [
        (100, TS_NS / 2),
        (150, 5 * TS_NS / 2),
        (200, 7 * TS_NS),
        (250, TS_NS - 1),
        (300, 40 * TS_NS + 3),
    ];
    clock.forced = forced.to_vec();
    let expected_overruns: u64 = forced.iter().map(|&(_, l)| l / TS_NS).sum();
    assert_eq!(expected_overruns, 2 + 7 + 40);
    let (mut h, record, cfg) = recorded(clock);
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    let job = h.start_program("G1 X200 Y100 F6000").unwrap();
    let max_lateness_ns = tests::run_on_the_grid(&mut h, job, TS_NS);
    let s = h.snapshot();
    assert!(
        h.clock().wakeups() > 300,
        "the run ended before the late ticks"
    );
    assert_eq!(s.tick.stats.overruns, expected_overruns);
    assert_eq!(s.tick.stats.ticks, s.tick.sequence);
    assert_eq!(max_lateness_ns, 40 * TS_NS + 3);
    assert_eq!(
        u64::from(s.tick.stats.lateness_max_us),
        (40 * TS_NS + 3) / 1000
    );
    // No setpoint jump anywhere: every step within the axis limits.
    let points = record.lock().unwrap().clone();
    for (i, (vmax, amax)) in max_rates(&points, 3, TS_S).into_iter().enumerate() {
        let a = &cfg.axes[i];
        assert!(
            vmax <= a.max_velocity_mm_min / 60.0 * (1.0 + 1e-6),
            "axis {i}: {vmax}"
        );
        assert!(
            amax <= a.max_accel_mm_s2 * (1.0 + 1e-6) + 1e-6,
            "axis {i}: {amax}"
        );
    }
    assert_eq!(&s.axes.commanded.0[..2], &[200.0, 100.0]);
}

/// Runs `PART` with override changes and a hold on `clock`; returns (setpoint hash, timeline
/// hash, overruns).
fn part_run(clock: SimClock) -> (u64, u64, u64) {
    let (mut h, _, _) = recorded(clock);
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    let start = h.snapshot().tick.sequence;
    h.at_tick(start + 200, RtCommand::Override(60.0));
    h.at_tick(start + 500, RtCommand::Hold);
    h.at_tick(start + 700, RtCommand::Resume);
    h.at_tick(start + 900, RtCommand::Override(120.0));
    let job = h.start_program(PART).unwrap();
    assert_eq!(h.finish_job(job, 1_000_000).unwrap(), JobEnd::Finished);
    let s = h.snapshot();
    assert_eq!(&s.axes.commanded.0[..3], &[0.0, 0.0, 5.0]);
    (h.setpoint_hash(), h.timeline_hash(), s.tick.stats.overruns)
}

/// Same seed, same run, bit for bit (every setpoint, every tick time). Another seed changes
/// the timing but not one setpoint: late ticks never change the trajectory.
#[test]
fn replay_with_the_same_seed_is_bit_identical() {
    let a = part_run(SimClock::seeded(42, 1_500_000, 50));
    let b = part_run(SimClock::seeded(42, 1_500_000, 50));
    assert_eq!(a, b);
    assert!(a.2 > 0, "the clock missed no deadline: {a:?}");
    let c = part_run(SimClock::seeded(43, 1_500_000, 50));
    assert_ne!(a.1, c.1, "another seed, another timeline");
    assert_eq!(a.0, c.0, "another seed, the same setpoints");
    let exact = part_run(SimClock::exact());
    assert_eq!(exact.2, 0);
    assert_eq!(a.0, exact.0, "late ticks changed the setpoints");
}

/// Shutdown mid-motion: the axes brake on the path within the acceleration limit, come to
/// rest, the drives settle on the last setpoint, and only then the loop may end.
#[test]
fn shutdown_ramps_axes_down_before_exit() {
    let (mut h, record, cfg) = recorded(SimClock::seeded(5, 500_000, 100));
    let a_lim = cfg.axes[0].max_accel_mm_s2;
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    h.start_program("G1 X500 F6000").unwrap();
    h.run_until(100_000, |s| s.axes.path_v_mm_s > 50.0).unwrap();
    h.send(RtCommand::Shutdown).unwrap();
    let mut ticks = 0;
    while !h.core().finished() {
        let s = h.step();
        assert_eq!(s.state, MachineState::Shutdown);
        ticks += 1;
        assert!(ticks < 100_000, "{s:?}");
    }
    let s = h.snapshot();
    assert!(s.axes.commanded[0] < 500.0);
    let points = record.lock().unwrap().clone();
    let (_, amax) = max_rates(&points, 1, TS_S)[0];
    assert!(amax <= a_lim * (1.0 + 1e-6), "braking at {amax} mm/s²");
    let tail = &points[points.len() - 3..];
    assert!(tail.iter().all(|p| p[0] == tail[0][0]));
    assert!((s.axes.actual[0] - s.axes.commanded[0]).abs() < 1e-3);
}

/// The simulated machine with Y's drive faulted while a job moves at over 50 mm/s: the
/// harness in FAULT, and the job that was running.
fn faulted_while_moving() -> (Harness, u32) {
    let cfg = tests::test_config();
    let (bus, fault_axis) = FaultableBus::new(sim_bus(&cfg));
    let mut h = Harness::new(cfg, Box::new(bus), SimClock::seeded(9, 500_000, 100)).unwrap();
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    let job = h.start_program("N10 G1 X200 Y100 F6000").unwrap();
    h.run_until(100_000, |s| s.axes.path_v_mm_s > 50.0).unwrap();
    fault_axis.store(1, Ordering::Relaxed);
    h.wait_state(MachineState::Fault, 10).unwrap();
    (h, job)
}

/// A drive fault mid-motion aborts the job; the faulted drive stops following; Reset
/// re-enables where the drives are (no jump back to the old setpoint) and the next job runs.
#[test]
fn drive_fault_stops_and_reset_resumes_from_where_the_drives_are() {
    let (mut h, job) = faulted_while_moving();
    let s = h.snapshot();
    assert_eq!(s.progress.aborted_job, job);
    let f = s.alarm.fault.unwrap();
    assert_eq!((f.axis, f.node), (Some(1), Some(2)));
    // The faulted drive no longer follows: its setpoint stays where it stands (fault
    // reaction, issue #15) while the healthy X brakes to rest on its own.
    for _ in 0..75 {
        h.step();
    }
    let s = h.snapshot();
    assert_eq!(s.axes.commanded[1], s.axes.actual[1], "{s:?}");
    assert!(s.axes.actual[0] > 0.0, "{s:?}");
    h.send(RtCommand::Reset).unwrap();
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    // The tick that enables reports the setpoint it sent; from the next one on, the drives'
    // positions.
    let s = h.step();
    for i in 0..3 {
        assert!(
            (s.axes.commanded[i] - s.axes.actual[i]).abs() < 1e-3,
            "axis {i}: {s:?}"
        );
    }
    let end = h.run_program("N20 G1 X0 Y0 F6000", 100_000).unwrap();
    assert_eq!(end, JobEnd::Finished);
    assert_eq!(&h.snapshot().axes.commanded.0[..2], &[0.0, 0.0]);
}

/// A Reset pressed right after a fault, while the axes still brake, is not lost: the machine
/// stays faulted until they are at rest, then enables again on its own, and nothing moves.
#[test]
fn a_reset_while_the_axes_brake_takes_effect_at_rest() {
    let (mut h, _) = faulted_while_moving();
    h.send(RtCommand::Reset).unwrap();
    let s = h.step();
    assert_eq!(s.state, MachineState::Fault, "still braking: {s:?}");
    assert!(
        s.axes.path_v_mm_s > 0.0 || s.axes.commanded[0] != s.axes.actual[0],
        "{s:?}"
    );
    let s = h.wait_state(MachineState::Idle, 10_000).unwrap();
    assert!(s.alarm.fault.is_none(), "{s:?}");
    let rest = h.step().axes.commanded;
    for _ in 0..250 {
        assert_eq!(h.step().axes.commanded, rest, "moved after the reset");
    }
}

/// Override, feed hold at rest (no motion while held), resume, stop: the RT logic behind the
/// Hold/Resume/Stop/SetOverride RPCs (their door is tested in api_rpcs), tick by tick.
#[test]
fn override_hold_resume_stop() {
    let (mut h, _, _) = recorded(SimClock::seeded(17, 1_000_000, 100));
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    let job = h.start_program("N10 G1 X80 F600\nN20 X0\n").unwrap();
    h.wait_state(MachineState::Running, 100).unwrap();
    let full = h
        .run_until(10_000, |s| s.axes.path_v_mm_s >= 10.0 - 1e-9)
        .unwrap();
    assert!((full.axes.path_v_mm_s - 10.0).abs() < 1e-6, "{full:?}");
    h.send(RtCommand::Override(50.0)).unwrap();
    let s = h.step();
    assert_eq!(s.operator.feed_override_pct, 50.0);
    let half = h
        .run_until(10_000, |s| s.axes.path_v_mm_s <= 5.0 + 1e-9)
        .unwrap();
    assert!(half.axes.commanded[0] < 80.0);
    h.send(RtCommand::Hold).unwrap();
    let held = h
        .run_until(10_000, |s| {
            s.state == MachineState::Hold && s.axes.path_v_mm_s == 0.0
        })
        .unwrap();
    for _ in 0..500 {
        assert_eq!(
            h.step().axes.commanded,
            held.axes.commanded,
            "moved while held"
        );
    }
    h.send(RtCommand::Resume).unwrap();
    h.run_until(10_000, |s| s.axes.commanded[0] > held.axes.commanded[0])
        .unwrap();
    h.send(RtCommand::Stop).unwrap();
    let stopped = h
        .run_until(10_000, |s| {
            s.progress.aborted_job == job && s.state == MachineState::Idle
        })
        .unwrap();
    assert!(stopped.axes.commanded[0] < 80.0, "{stopped:?}");
    assert_ne!(stopped.progress.finished_job, job);
}

/// Single block: the path holds exactly at every block end,
/// and runs on at each resume to the program's end.
#[test]
fn single_block_holds_at_every_block() {
    let (mut h, _, _) = recorded(SimClock::seeded(23, 1_000_000, 100));
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    h.send(RtCommand::SingleBlock(true)).unwrap();
    // As the API starts a program in single-block mode: every block ends at rest.
    let job = h
        .start_job("N10 G1 X5 F3000\nN20 G23 X10\nN30 X15\n", true)
        .unwrap();
    let mut stops = Vec::new();
    for _ in 0..2 {
        let s = h
            .run_until(10_000, |s| {
                s.state == MachineState::Hold && s.axes.path_v_mm_s == 0.0
            })
            .unwrap();
        assert!(s.operator.single_block);
        stops.push(s.axes.commanded[0]);
        h.send(RtCommand::Resume).unwrap();
        h.run_until(10, |s| s.state != MachineState::Hold).unwrap();
    }
    assert_eq!(h.finish_job(job, 10_000).unwrap(), JobEnd::Finished);
    assert!((stops[0] - 5.0).abs() < 1e-6, "{stops:?}");
    assert!((stops[1] - 10.0).abs() < 1e-6, "{stops:?}");
    assert!((h.snapshot().axes.commanded[0] - 15.0).abs() < 1e-6);
}

/// A program longer than the segment ring: the inline planner ticks the RT core whenever the
/// ring is full (the RT core never starves), and a stop cancels the planning.
#[test]
fn planning_beyond_the_ring_ticks_the_core_and_a_stop_cancels_it() {
    let mut text = String::from("G1 F3000\n");
    for i in 1..=6000 {
        text.push_str(&format!("X{} Y{:.2}\n", i % 2, i as f64 * 0.01));
    }
    let (mut h, _, _) = recorded(SimClock::seeded(31, 1_000_000, 100));
    h.wait_state(MachineState::Idle, 10_000).unwrap();
    let t0 = h.snapshot().tick.sequence;
    let job = h.start_program(&text).unwrap();
    // The ring (4096) could not hold the program: the core ran while it was planned.
    assert!(h.snapshot().tick.sequence > t0, "no tick during planning");
    assert_eq!(h.finish_job(job, 1_000_000).unwrap(), JobEnd::Finished);
    assert!((h.snapshot().axes.commanded[1] - 60.0).abs() < 1e-9);

    let back = h.snapshot().tick.sequence;
    h.at_tick(back + 100, RtCommand::Stop);
    let job = h.start_program(&text.replace("Y", "Y-")).unwrap();
    // Returned at the stop, long before the program could have been planned to its end.
    assert!(
        h.snapshot().tick.sequence < back + 200,
        "{:?}",
        h.snapshot()
    );
    assert_eq!(h.finish_job(job, 10_000).unwrap(), JobEnd::Aborted);
    h.wait_state(MachineState::Idle, 10_000).unwrap();
}
