//! The manual's lathe example (seed 002, SPEC §5-§6) checked the same way on every bus: the
//! bus tests build their harness, this module runs the example and checks it tick by tick.

use daemon::runtime::harness::Harness;
use daemon::runtime::rt::MachineState;

/// Cutting speed of `S90` under G96 (m/min), in mm/min.
const V_MM_MIN: f64 = 90_000.0;
/// `F200` under R329 d3 = 3: 0.2 mm per revolution.
const BETA_MM_REV: f64 = 0.2;

fn within(a: f64, b: f64, share: f64) -> bool {
    (a - b).abs() <= share * b.abs()
}

/// `N10 G0 X300 Z100 M44 M3 S100` / `N15 Z-1` / `N20 G96 G1 F200 S90 X50`: along the cut
/// v = 2π·n·r within 1 % (n the speed the spindle drive reports) and the feed = n · 0.2 mm/rev
/// within 1 % (n of the tick the RT core fed from), every tick from Ø290 to Ø60.
pub fn run_manual_example(mut h: Harness) {
    h.wait_state(MachineState::Idle, 100_000).unwrap();
    let job = h
        .start_program("N10 G0 X300 Z100 M44 M3 S100\nN15 Z-1\nN20 G96 G1 F200 S90 X50\n")
        .unwrap();
    let mut prev = h.snapshot();
    let mut checked = 0;
    for _ in 0..1_000_000 {
        let s = h.step();
        let d = 2.0 * s.axes.commanded[0];
        if s.progress.block_n == Some(20) && (60.0..290.0).contains(&d) {
            let n = s.spindle.rpm;
            let v = 2.0 * std::f64::consts::PI * n * s.axes.commanded[0];
            assert!(within(v, V_MM_MIN, 0.01), "Ø{d}: n {n} rpm gives v {v}");
            let feed = s.axes.path_v_mm_s * 60.0;
            assert!(
                within(feed, prev.spindle.rpm * BETA_MM_REV, 0.01),
                "Ø{d}: feed {feed} mm/min at {} rpm",
                prev.spindle.rpm
            );
            checked += 1;
        }
        prev = s;
        if s.progress.finished_job == job || s.progress.aborted_job == job {
            assert_eq!(s.progress.finished_job, job, "aborted: {s:?}");
            break;
        }
    }
    assert!(checked > 10_000, "only {checked} ticks checked");
    let s = h.snapshot();
    assert!((s.axes.commanded[0] - 25.0).abs() < 1e-9 && (s.axes.commanded[1] + 1.0).abs() < 1e-9);
}
