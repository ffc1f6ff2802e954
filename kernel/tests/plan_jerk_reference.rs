//! Issue #49: the parabolic profile against Ruckig (`scripts/jerk-reference/`: the
//! time-optimal jerk-limited move under the same limits, computed without the planner's
//! code). On the configuration `cncd` builds from each constants file there, every move of the
//! suite (short moves that never reach F or A included) takes at most 1.03 × Ruckig's time,
//! and the setpoints keep the path's jerk, acceleration and speed and every axis's jerk and
//! acceleration within their limits (third, second and first differences of 4 ms setpoints).

mod plan_common;

use kernel::constants::Constants;
use kernel::plan::{AxisLimits, PlannerConfig};
use plan_common::*;

const TS: f64 = 0.004;
const A_AXIS: f64 = 1000.0;
const J_AXIS: f64 = 50.0 * A_AXIS;

fn reference_dir() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/jerk-reference")
}

/// The reference machine (20000 mm/min, 1000 mm/s² per axis) with constants file `rek`,
/// as cncd builds it.
fn config(rek: &str) -> PlannerConfig {
    let text = std::fs::read_to_string(reference_dir().join(format!("{rek}.rek"))).unwrap();
    let c = Constants::parse(&text).unwrap();
    assert!(c.validate().is_empty(), "{rek}: {:?}", c.validate());
    let axis = AxisLimits {
        v_max_mm_s: 20000.0 / 60.0,
        a_max_mm_s2: A_AXIS,
    };
    PlannerConfig::for_machine(&[axis; 3], 0.0, Some(&c))
}

/// One row of `ruckig-<rek>.tsv` with its move of `moves.tsv`.
struct Move {
    name: String,
    program: String,
    a_mm_s2: f64,
    j_mm_s3: f64,
    ruckig_s: f64,
}

fn moves(rek: &str) -> Vec<Move> {
    let read = |f: &str| std::fs::read_to_string(reference_dir().join(f)).unwrap();
    let rows = |t: String| -> Vec<Vec<String>> {
        t.lines()
            .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
            .map(|l| l.split('\t').map(str::to_owned).collect())
            .collect()
    };
    let programs = rows(read("moves.tsv"));
    rows(read(&format!("ruckig-{rek}.tsv")))
        .into_iter()
        .map(|r| {
            let m = programs.iter().find(|m| m[0] == r[0]).unwrap();
            Move {
                name: r[0].clone(),
                program: format!("G1 X{} Y{} Z{} F{}\n", m[1], m[2], m[3], m[4]),
                a_mm_s2: r[3].parse().unwrap(),
                j_mm_s3: r[4].parse().unwrap(),
                ruckig_s: r[5].parse().unwrap(),
            }
        })
        .collect()
}

/// Largest |k-th difference| / Ts^k of the arc length along the move and of each axis.
fn worst(r: &Run, k: usize) -> (f64, f64) {
    let pts: Vec<[f64; 3]> = r
        .ticks
        .iter()
        .map(|t| [t.position[0], t.position[1], t.position[2]])
        .collect();
    let s: Vec<f64> = pts
        .iter()
        .map(|p| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt())
        .collect();
    let diff = |xs: &[f64]| -> f64 {
        let mut d = xs.to_vec();
        for _ in 0..k {
            d = d.windows(2).map(|w| (w[1] - w[0]) / TS).collect();
        }
        d.iter().fold(0.0f64, |m, x| m.max(x.abs()))
    };
    let axis = (0..3)
        .map(|i| diff(&pts.iter().map(|p| p[i]).collect::<Vec<_>>()))
        .fold(0.0f64, f64::max);
    (diff(&s), axis)
}

#[test]
fn parabolic_moves_take_ruckigs_time_within_their_jerk() {
    let mut failures = vec![];
    for rek in ["parabolic-set", "parabolic-default"] {
        let cfg = config(rek);
        for m in moves(rek) {
            let r = run(cfg.clone(), &program_of_g1(&m.program));
            let ratio = r.time_s() / m.ruckig_s;
            let (path_j, axis_j) = worst(&r, 3);
            let (path_a, axis_a) = worst(&r, 2);
            println!(
                "{rek:18} {:9} {:.3} s, Ruckig {:.4} s, ratio {ratio:.3}, path j/J {:.4}, axis j {:.4}, path a/A {:.4}, axis a {:.4}",
                m.name,
                r.time_s(),
                m.ruckig_s,
                path_j / m.j_mm_s3,
                axis_j / J_AXIS,
                path_a / m.a_mm_s2,
                axis_a / A_AXIS
            );
            let within = path_j <= m.j_mm_s3 * (1.0 + 1e-6)
                && axis_j <= J_AXIS * (1.0 + 1e-6)
                && path_a <= m.a_mm_s2 * (1.0 + 1e-6)
                && axis_a <= A_AXIS * (1.0 + 1e-6);
            if ratio > 1.03 || !within {
                failures.push(format!("{rek} {}: ratio {ratio:.4}", m.name));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
