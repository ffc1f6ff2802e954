mod plan_common;
use kernel::plan::{AxisLimits, PlannerConfig};
use plan_common::*;

#[test]
fn scratch2() {
    let c = kernel::constants::Constants::parse(
        &std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/benches/plan/parabolic.rek"
        ))
        .unwrap(),
    )
    .unwrap();
    let axis = AxisLimits {
        v_max_mm_s: 200.0,
        a_max_mm_s2: 800.0,
    };
    let cfg = PlannerConfig::for_machine(&[axis; 3], 0.0, Some(&c));
    println!(
        "axis filter {} sets j {:?}",
        cfg.axis_filter_ticks, cfg.envelope.sets[0].jerk_mm_s3
    );
    for (name, blocks) in daemon_suite() {
        if !name.contains("circle") && !name.contains("zig") {
            continue;
        }
        let r = run(cfg.clone(), &blocks);
        let w = measure(&cfg, &r, 8.0);
        let s = &r.segments[5];
        println!(
            "{name}: {:.3} s  axis a {:.3} j {:.3}  seg jerkset {} A {:.1} J {:.1} off {:.4} vmax {:.1} crit {:.1} n {}",
            r.time_s(),
            w.axis_a,
            w.axis_j,
            s.axis_box.jerk.is_set(),
            s.axis_box.jerk.accel(),
            s.axis_box.jerk.path(),
            s.axis_box.jerk.off_mm(),
            s.axis_box.v_max_mm_s,
            s.axis_box.criteria_end_mm_s,
            s.axis_filter_ticks
        );
        let mut last = -1.0;
        for (i, t) in r.ticks.iter().enumerate() {
            if i % 25 == 0 && i < 600 {
                print!("{:.1} ", t.path_v_mm_s);
            }
            last = t.path_v_mm_s;
        }
        println!("{last}");
    }
}
