//! The assembled real-time tick (`RtCore::tick`: commands, PLC, segments, interpolator,
//! KŘR, bus exchange, state machine, tick statistics, snapshot) must not allocate: the RT
//! thread runs it (ARCHITECTURE.md, threads). Run in the single-threaded harness over a
//! program with arcs, cutter compensation and constant cutting speed, with feed override
//! changes, a feed hold, a PLC write, late ticks, then a drive fault and its reset. Counted
//! per thread (shared counting allocator): only the ticks are counted, not the planning (which
//! runs on its own thread in the daemon).

#[global_allocator]
static ALLOC: alloc_count::Counting = alloc_count::Counting;

use std::sync::atomic::Ordering;

use daemon::runtime::clock::SimClock;
use daemon::runtime::harness::{Harness, JobEnd};
use daemon::runtime::rt::{MachineState, RtCommand};
use kernel::plc::PlcWrite;
use tests::FaultableBus;

/// The MIKROPROG template (G41 round arcs and corners) with G96 (KŘR) and a faster feed.
const PROGRAM: &str = "\
N10 G92 D1 R0=5.0
N20 G17 D1 M3 M41 S1000
N25 G96 S900
N30 G41
N40 G1 X0 F1500
N50 G1 Y20
N60 G2 X20 Y40 I20 J0
N70 G1 X40
N80 G1 Y25
N90 G3 X55 Y10 I15 J0
N100 G1 X80 Y0
N110 G1 X0
N120 G40 G1 X-10
N125 G94 S500
N130 G0 X-30
N140 M5
";

#[test]
fn the_assembled_tick_does_not_allocate() {
    assembled_tick(4);
}

/// At bus periods beside the 4 ms interpolation period (issue #23): several bus ticks per
/// interpolator step (1 ms), several steps per bus tick (10 ms).
#[test]
fn the_assembled_tick_does_not_allocate_at_1ms_and_10ms() {
    assembled_tick(1);
    assembled_tick(10);
}

fn assembled_tick(cycle_ms: u64) {
    let mut cfg = tests::test_config();
    cfg.axes[0].home_mm = -30.0;
    cfg.bus = daemon::runtime::buses::BusConfig::Sim {
        cycle_ms: cycle_ms as f64,
    };
    let sim = sim::SimBus::new(sim::SimDriveParams::default(), &[-30.0, 0.0, 0.0])
        .with_cycle_s(cycle_ms as f64 * 1e-3);
    let (bus, fault_axis) = FaultableBus::new(sim);
    let mut h = Harness::new(cfg, Box::new(bus), SimClock::seeded(11, 1_500_000, 40)).unwrap();

    let (idle, n) = alloc_count::count(|| h.wait_state(MachineState::Idle, 10_000).is_ok());
    assert!(idle);
    assert_eq!(n, 0, "allocations while enabling");

    // Plan (allocates, as the planner thread does); the whole job fits on the segment ring.
    let (job, planning) = alloc_count::count(|| h.start_program(PROGRAM).unwrap());
    assert!(planning > 0, "the counter counts nothing");
    let t = h.snapshot().tick.sequence;
    h.at_tick(
        t + 50,
        RtCommand::Plc(PlcWrite::by_name("AKRR_V", 80_000).unwrap()),
    );
    h.at_tick(t + 100, RtCommand::Override(50.0));
    h.at_tick(t + 300, RtCommand::Hold);
    h.at_tick(t + 450, RtCommand::Resume);
    h.at_tick(t + 600, RtCommand::Override(130.0));
    let (mut kr, mut held, mut compensated) = (false, false, false);
    let (end, n) = alloc_count::count(|| {
        h.run_until(1_000_000, |s| {
            kr |= s.spindle.kr.active && s.spindle.kr.spindle_rpm > 0.0;
            held |= s.state == MachineState::Hold;
            compensated |= s.axes.commanded[1] > 2.0
                && s.axes.commanded[1] < 18.0
                && s.axes.commanded[0] < 0.0;
            s.progress.finished_job == job || s.progress.aborted_job == job
        })
        .map(|s| s.progress.finished_job == job)
    });
    assert_eq!(n, 0, "allocations in the ticks of the program");
    assert_eq!(end.ok(), Some(true), "{:?}", h.snapshot());
    assert!(
        kr && held && compensated,
        "kr {kr}, held {held}, compensated {compensated}"
    );
    assert!(
        h.snapshot().tick.stats.overruns > 0,
        "the clock missed no deadline"
    );

    // A drive fault mid-motion, the stop, the reset and the re-enable allocate nothing either.
    let job = h.start_program("G1 X200 Y100 F6000").unwrap();
    let (faulted, n) = alloc_count::count(|| {
        let moving = h.run_until(100_000, |s| s.axes.path_v_mm_s > 50.0).is_ok();
        fault_axis.store(1, Ordering::Relaxed);
        let fault = h.wait_state(MachineState::Fault, 10).is_ok();
        // Reset acts once the path has braked to rest (400 ms).
        for _ in 0..400 / cycle_ms {
            h.step();
        }
        let _ = h.send(RtCommand::Reset);
        let idle = h.wait_state(MachineState::Idle, 10_000).is_ok();
        moving && fault && idle
    });
    assert!(faulted, "{:?}", h.snapshot());
    assert_eq!(n, 0, "allocations in fault, stop and reset");
    assert_eq!(h.snapshot().progress.aborted_job, job);
    assert_eq!(
        h.run_program("G0 X0 Y0", 100_000).ok(),
        Some(JobEnd::Finished)
    );
}
