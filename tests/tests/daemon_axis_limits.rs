//! Issue #24: a move is limited by the axes it moves, never by an axis that stands still.
//!
//! The daemon's pipeline and RT core (the single-threaded harness) on the simulated bus, virtual time, a machine with X and Y at 800 mm/s²
//! and Z at 500 mm/s². Every commanded setpoint is recorded; the path acceleration measured
//! from them must reach A = min over moving axes of a_i/|u_i| (and never exceed it), in the
//! linear and the parabolic profile, for feed moves, rapids and a stop.

use daemon::runtime::config::{AxisConfig, Config};
use daemon::runtime::harness::{Harness, JobEnd};
use daemon::runtime::rt::{MachineState, RtCommand};
use tests::Recording;

const TS_S: f64 = 0.004;
const A_MM_S2: [f64; 3] = [800.0, 800.0, 500.0];
const V_MM_S: f64 = 200.0;

/// Where the stop tests ask for the stop: the first tick commanded past this X.
const PAUSE_AT_X_MM: f64 = 60.0;

/// The daemon's pipeline and RT core in the single-threaded harness (virtual time), on the
/// simulated bus with every setpoint recorded.
struct Machine {
    h: Harness,
    record: Recording,
}

fn machine() -> Machine {
    let mut cfg: Config = tests::test_config();
    cfg.axes = ['X', 'Y', 'Z']
        .iter()
        .zip(A_MM_S2)
        .map(|(n, a)| AxisConfig {
            max_velocity_mm_min: V_MM_S * 60.0,
            max_accel_mm_s2: a,
            ..AxisConfig::new(*n)
        })
        .collect();
    let (h, record) = tests::recorded_harness(cfg, &[0.0; 3]);
    Machine { h, record }
}

#[derive(Debug)]
struct Measured {
    /// Unit direction of the move (start to end of the recording).
    dir: [f64; 3],
    /// Largest path acceleration (speed increase per tick / Ts), mm/s².
    path_accel: f64,
    /// Largest path deceleration, mm/s².
    path_decel: f64,
    /// Largest per-axis |acceleration| and |jerk|.
    axis_accel: [f64; 3],
    axis_jerk: [f64; 3],
}

fn measure(points: &[[f64; hal::MAX_AXES]]) -> Measured {
    let (first, last) = (points[0], points[points.len() - 1]);
    let d: Vec<f64> = (0..3).map(|i| last[i] - first[i]).collect();
    let len = d.iter().map(|x| x * x).sum::<f64>().sqrt();
    let dir = [d[0] / len, d[1] / len, d[2] / len];
    let vel: Vec<[f64; 3]> = points
        .windows(2)
        .map(|w| [0, 1, 2].map(|i| (w[1][i] - w[0][i]) / TS_S))
        .collect();
    let acc: Vec<[f64; 3]> = vel
        .windows(2)
        .map(|w| [0, 1, 2].map(|i| (w[1][i] - w[0][i]) / TS_S))
        .collect();
    let speed: Vec<f64> = vel
        .iter()
        .map(|v| v.iter().map(|x| x * x).sum::<f64>().sqrt())
        .collect();
    let mut m = Measured {
        dir,
        path_accel: 0.0,
        path_decel: 0.0,
        axis_accel: [0.0; 3],
        axis_jerk: [0.0; 3],
    };
    for w in speed.windows(2) {
        m.path_accel = m.path_accel.max((w[1] - w[0]) / TS_S);
        m.path_decel = m.path_decel.max((w[0] - w[1]) / TS_S);
    }
    for a in &acc {
        for (worst, x) in m.axis_accel.iter_mut().zip(a) {
            *worst = worst.max(x.abs());
        }
    }
    for w in acc.windows(2) {
        for (i, worst) in m.axis_jerk.iter_mut().enumerate() {
            *worst = worst.max(((w[1][i] - w[0][i]) / TS_S).abs());
        }
    }
    m
}

/// A = min over the axes the move moves of a_i/|u_i| (docs/planner.md, issue #24).
fn expected_accel(dir: &[f64; 3]) -> f64 {
    (0..3)
        .filter(|i| dir[*i].abs() > 1e-9)
        .map(|i| A_MM_S2[i] / dir[i].abs())
        .fold(f64::INFINITY, f64::min)
}

impl Machine {
    fn run(&mut self, text: &str) -> Vec<[f64; hal::MAX_AXES]> {
        self.record.lock().unwrap().clear();
        let end = self.h.run_program(text, 1_000_000).unwrap();
        assert_eq!(end, JobEnd::Finished, "{text}");
        self.record.lock().unwrap().clone()
    }

    /// Runs `text` and asks for a stop on the first tick past X = `PAUSE_AT_X_MM`.
    fn run_and_stop(&mut self, text: &str) -> Vec<[f64; hal::MAX_AXES]> {
        self.record.lock().unwrap().clear();
        self.h.start_program(text).unwrap();
        self.h
            .run_until(1_000_000, |s| s.axes.commanded[0] > PAUSE_AT_X_MM)
            .expect("never passed X");
        self.h.send(RtCommand::Stop).unwrap();
        self.h.wait_state(MachineState::Idle, 1_000_000).unwrap();
        self.record.lock().unwrap().clone()
    }
}

fn check(what: &str, m: &Measured, reached: f64, parabolic: bool) {
    let want = expected_accel(&m.dir);
    assert!(
        reached <= want * (1.0 + 1e-6) + 1e-6 && reached >= want * 0.995,
        "{what}: path acceleration {reached:.1} mm/s², expected {want:.1} ({m:?})"
    );
    for (i, a_lim) in A_MM_S2.iter().enumerate() {
        assert!(
            m.axis_accel[i] <= a_lim * (1.0 + 1e-6) + 1e-6,
            "{what}: axis {i} at {} mm/s² ({m:?})",
            m.axis_accel[i]
        );
        let j_lim = kernel::plan::AXIS_JERK_PER_ACCEL_PER_S * a_lim;
        assert!(
            !parabolic || m.axis_jerk[i] <= j_lim * (1.0 + 1e-6) + 1e-6,
            "{what}: axis {i} jerk {} mm/s³ ({m:?})",
            m.axis_jerk[i]
        );
    }
}

fn moves_reach_their_own_axes_limits(parabolic: bool) {
    let mut m = machine();
    if parabolic {
        // 2.R338 = 2: parabolic. R52 and R237 (path accelerations without continuity and of
        // rapids, 500 mm/s² by default) above every axis: the axes alone limit.
        m.h.set_constants(&[(338, 0.020), (52, 100_000.0), (237, 100_000.0)]);
    }
    // Single-axis moves: each reaches its own axis's limit (Z 500 never slows X or Y down).
    // Diagonals: XY reaches min(a_x/|u_x|, a_y/|u_y|) = 894 mm/s² here; XZ shows that Z's
    // 500 mm/s² only counts as a_z/|u_z|.
    let moves = [
        ("feed X", "G90 G1 X100 F12000"),
        ("feed Y", "G90 G1 Y100 F12000"),
        ("feed Z", "G90 G1 Z-100 F12000"),
        ("feed XY", "G90 G1 X200 Y150 F12000"),
        ("feed XZ", "G90 G1 X300 Z-80 F12000"),
        ("rapid X", "G90 G0 X200"),
        ("rapid Y", "G90 G0 Y50"),
        ("rapid Z", "G90 G0 Z0"),
        ("rapid XY", "G90 G0 X0 Y0"),
    ];
    for (what, text) in moves {
        let points = m.run(text);
        let r = measure(&points);
        check(what, &r, r.path_accel, parabolic);
        check(what, &r, r.path_decel, parabolic);
    }
    // Stops (stop set: the axis limits) brake at the same limits.
    for (what, text) in [
        ("stop X", "G90 G1 X200 F12000"),
        ("stop XY", "G90 G1 X200 Y100 F12000"),
    ] {
        m.run("G90 G0 X0 Y0 Z0");
        let points = m.run_and_stop(text);
        let end = points[points.len() - 1];
        assert!(end[0] < 200.0 - 10.0, "{what}: did not stop early: {end:?}");
        // Only the motion after the pause: the stop is its only deceleration.
        let from = points
            .iter()
            .position(|p| p[0] > PAUSE_AT_X_MM)
            .expect("passed X");
        let r = measure(&points[from.saturating_sub(2)..]);
        check(what, &r, r.path_decel, parabolic);
    }
}

#[test]
fn linear_moves_reach_the_limits_of_the_axes_they_move() {
    moves_reach_their_own_axes_limits(false);
}

#[test]
fn parabolic_moves_reach_the_limits_of_the_axes_they_move() {
    moves_reach_their_own_axes_limits(true);
}

/// A program of G1 lines at `feed` through `points` (absolute), smooth continuity (G23).
fn polyline_program(points: &[[f64; 2]], feed_mm_min: f64) -> String {
    let mut text = format!("G90 G23 F{feed_mm_min}\n");
    for p in points {
        text += &format!("G1 X{:.6} Y{:.6}\n", p[0], p[1]);
    }
    text + "G98\n"
}

/// Issue #32: turns closer than a tick's step, and a straight junction just after them
/// (collinear chords, as CAM output splits a line), run through the daemon's pipeline: no
/// axis past its limit. The old planner took an axis above it on such paths (the lines
/// after them used more acceleration than the turns left; docs/planner.md).
#[test]
fn turns_closer_than_a_step_keep_every_axis_limit() {
    let mut m = machine();
    for feed in [3000.0, 6000.0, 12000.0] {
        for (t1, t2, straight) in [(2.0f64, 1.0f64, false), (1.0, 2.0, true), (3.0, 0.5, true)] {
            for l in [0.007, 0.02, 0.05, 0.12] {
                m.run("G90 G0 X0 Y0 Z0");
                let mut a = 70f64.to_radians();
                let mut p = [0.0, 0.0];
                let mut points = Vec::new();
                let third = straight.then_some((1.7 * l, 0.0));
                for (len, turn) in [(5.0, t1), (l, t2)]
                    .into_iter()
                    .chain(third)
                    .chain([(5.0, 0.0)])
                {
                    p = [p[0] + a.cos() * len, p[1] + a.sin() * len];
                    points.push(p);
                    a += turn.to_radians();
                }
                let text = polyline_program(&points, feed);
                let r = measure(&m.run(&text));
                for (i, a_lim) in A_MM_S2.iter().enumerate() {
                    assert!(
                        r.axis_accel[i] <= a_lim * (1.0 + 1e-6),
                        "axis {i} at {} mm/s² ({t1}°, {l} mm, {t2}°, straight {straight}, F{feed})",
                        r.axis_accel[i]
                    );
                }
            }
        }
    }
}
