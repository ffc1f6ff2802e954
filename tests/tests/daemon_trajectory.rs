//! Issue #16: `cncctl trajectory` gets the planned per-tick trajectory of a program from
//! `cncd` (simulated bus) without moving the machine: total time and a CSV of every tick.

mod vcan_support;

use std::time::Duration;

use vcan_support::Daemon;

const TS_S: f64 = 0.004;

#[test]
fn cncctl_trajectory_gives_the_planned_ticks_without_moving() {
    let d = Daemon::start("daemon-trajectory", "[bus]\nkind = 'sim'\n", [1, 2, 3]);
    // Default axes: 200 mm/s, 800 mm/s²; no constants file: the linear profile.
    let prog = d.program("line.nc", "N10 G1 X100 F6000\nN20 G1 X100 Y50\n");
    let csv = d.dir.join("traj.csv");
    let (ok, out) = d.cncctl(
        &["--json", "trajectory", &prog, "-o", csv.to_str().unwrap()],
        Duration::from_secs(120),
    );
    assert!(ok, "cncctl trajectory failed: {out}");
    let v: serde_like::Summary = serde_like::parse(&out);
    // Two stop-to-stop moves: 100 mm and 50 mm at 100 mm/s, ramps at 800 mm/s²:
    // (1 + 0.125) + (0.5 + 0.125) s, each within one tick of rounding, plus the tick at rest
    // at the stop between them.
    let ideal = 1.125 + 0.625;
    assert!(
        v.total_s >= ideal - 2.0 * TS_S && v.total_s <= ideal + 3.0 * TS_S,
        "{out}"
    );
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "t_s,X_mm,Y_mm,Z_mm,path_v_mm_s,seq,block"
    );
    let rows: Vec<Vec<f64>> = lines
        .map(|l| {
            l.split(',')
                .map(|x| x.parse::<f64>().unwrap_or(f64::NAN))
                .collect()
        })
        .collect();
    assert_eq!(rows.len() as u64, v.ticks);
    let last = rows.last().unwrap();
    assert!((last[0] - v.total_s).abs() < 1e-9, "{last:?}");
    assert_eq!(&last[1..4], &[100.0, 50.0, 0.0]);
    let peak = rows.iter().map(|r| r[4]).fold(0.0f64, f64::max);
    assert!((peak - 100.0).abs() < 1e-6, "peak path speed {peak}");
    // Per-axis acceleration of the setpoints within the axis limit.
    for axis in 1..4 {
        let vel: Vec<f64> = rows
            .windows(2)
            .map(|w| (w[1][axis] - w[0][axis]) / TS_S)
            .collect();
        for w in vel.windows(2) {
            let a = ((w[1] - w[0]) / TS_S).abs();
            assert!(a <= 800.0 * (1.0 + 1e-6) + 1e-3, "axis {axis}: {a} mm/s²");
        }
    }
    // The machine did not move.
    let s = d.status();
    assert!(
        s.starts_with("idle") && s.contains("X0.000 Y0.000 Z0.000"),
        "{s}"
    );
}

/// The two numbers of `cncctl --json trajectory` (no JSON crate in the tests package).
mod serde_like {
    pub struct Summary {
        pub total_s: f64,
        pub ticks: u64,
    }

    pub fn parse(out: &str) -> Summary {
        let line = out.lines().find(|l| l.contains("total_s")).expect(out);
        let field = |name: &str| {
            let at = line.find(&format!("\"{name}\":")).expect(line) + name.len() + 3;
            let rest = &line[at..];
            let end = rest.find([',', '}']).unwrap();
            rest[..end].trim().parse::<f64>().unwrap()
        };
        Summary {
            total_s: field("total_s"),
            ticks: field("ticks") as u64,
        }
    }
}
