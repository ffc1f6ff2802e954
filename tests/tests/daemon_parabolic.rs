//! Issue #16, parabolic profile (SPEC §7.3) through the daemon: the pipeline and RT core of
//! `cncd` (the single-threaded harness, virtual time) on the simulated bus, the profile and
//! the ramp P from the machine's constants file (2.R338 = 2, set 1: R406..R408). Every
//! commanded setpoint is recorded.
//!
//! - The ramp from rest to F in the pure-parabola regime takes the manual's
//!   T = 1.478·√(F/P) (F in mm/min) within 5 %.
//! - A move from rest to F and back to rest takes the ideal jerk-limited (7-phase S-curve)
//!   time for the same J and A within 3 % (`kernel::interp::ideal_jerk_limited_move_s`, the
//!   closed form, independent of the interpolator).
//! - No axis exceeds its acceleration or jerk limit.

use daemon::runtime::config::Config;
use daemon::runtime::harness::{Harness, JobEnd};
use tests::Recording;

const TS_S: f64 = 0.004;
/// The daemon's default axes (`DEFAULT_AXIS_LIMITS`): 800 mm/s², jerk 50·a.
const AXIS_A_MM_S2: f64 = 800.0;

struct Machine {
    h: Harness,
    record: Recording,
}

/// The daemon with the constants file `rek` in its storage directory.
fn machine(rek: &str) -> Machine {
    let cfg: Config = tests::test_config();
    std::fs::create_dir_all(&cfg.storage.dir).unwrap();
    std::fs::write(cfg.storage.constants_path(), rek).unwrap();
    let (h, record) = tests::recorded_harness(cfg, &[0.0; 3]);
    Machine { h, record }
}

/// Constants file: parabolic profile, accuracy Lm = 8 µm (R384, as the bench's
/// `parabolic.rek`), set 1 in use with ramp `p` (digit reading, SPEC §7.3) and acceleration
/// `a_mm_s2`. Lm sets the axis smoothing filter to n = 2 ticks per stage, which adds 2(n−1)
/// ticks to every ramp (without Lm n = 4: 6 ticks, docs/planner.md).
fn parabolic_rek(p: f64, a_mm_s2: f64) -> String {
    format!(
        "R338=0.020\nR384=0.008\nR406=0.001\nR407={:.3}\nR408={:.3}\n",
        p / 1000.0,
        a_mm_s2 / 1000.0
    )
}

/// X setpoints of one program, from the tick before the first motion to the end.
fn run_x(m: &mut Machine, text: &str) -> Vec<f64> {
    m.record.lock().unwrap().clear();
    let end = m.h.run_program(text, 1_000_000).unwrap();
    assert_eq!(end, JobEnd::Finished, "{text}");
    let x: Vec<f64> = m.record.lock().unwrap().iter().map(|p| p[0]).collect();
    let first = x.iter().position(|p| *p != x[0]).expect("no motion");
    let last = x.iter().rposition(|p| *p != x[x.len() - 1]).unwrap() + 1;
    x[first - 1..=last].to_vec()
}

fn diffs(x: &[f64]) -> Vec<f64> {
    x.windows(2).map(|w| (w[1] - w[0]) / TS_S).collect()
}

fn check_axis_limits(what: &str, x: &[f64]) {
    let v = diffs(x);
    let a = diffs(&v);
    let j = diffs(&a);
    let a_max = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let j_max = j.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let j_lim = kernel::plan::AXIS_JERK_PER_ACCEL_PER_S * AXIS_A_MM_S2;
    assert!(
        a_max <= AXIS_A_MM_S2 * (1.0 + 1e-6),
        "{what}: accel {a_max}"
    );
    assert!(j_max <= j_lim * (1.0 + 1e-6), "{what}: jerk {j_max}");
}

#[test]
fn pure_parabola_ramp_takes_the_manuals_time() {
    // F300, P = 50000: T = 1.478·√(300/50000) = 0.1145 s. A = 600 mm/s² is far above √(F·J).
    let mut m = machine(&parabolic_rek(50_000.0, 600.0));
    let x = run_x(&mut m, "G90 G1 X20 F300");
    let v = diffs(&x);
    let f_mm_s = 5.0;
    let reached = v.iter().position(|s| *s >= f_mm_s * (1.0 - 1e-9)).unwrap() + 1;
    let t = reached as f64 * TS_S;
    let manual = 1.478 * (300.0f64 / 50_000.0).sqrt();
    assert!(
        (t - manual).abs() <= 0.05 * manual,
        "ramp {t} s, manual {manual} s"
    );
    // The whole move: the same ramp down, the rest at F.
    let j = kernel::plan::jerk_from_p_mm_s3(50_000.0);
    let ideal = kernel::interp::ideal_jerk_limited_move_s(20.0, f_mm_s, 600.0, j);
    let total = (x.len() - 1) as f64 * TS_S;
    assert!(total <= ideal * 1.03, "move {total} s, ideal {ideal} s");
    check_axis_limits("F300", &x);
}

#[test]
fn move_reaching_the_acceleration_takes_the_ideal_jerk_limited_time() {
    // P = 150000 (J = 4578 mm/s³), A = 100 mm/s²: the ramp to F3000 has a constant-acceleration
    // phase (a²/J = 2.2 mm/s < 50 mm/s).
    let mut m = machine(&parabolic_rek(150_000.0, 100.0));
    let x = run_x(&mut m, "G90 G1 X100 F3000");
    let j = kernel::plan::jerk_from_p_mm_s3(150_000.0);
    let ideal = kernel::interp::ideal_jerk_limited_move_s(100.0, 50.0, 100.0, j);
    let total = (x.len() - 1) as f64 * TS_S;
    assert!(
        total <= ideal * 1.03 && total >= ideal * 0.97,
        "move {total} s, ideal {ideal} s"
    );
    check_axis_limits("F3000", &x);
}
