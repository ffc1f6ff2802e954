mod plan_common;
use plan_common::*;

#[test]
fn tmp_circle_speed() {
    let cfg = reference_config_with("machine-parabolic.rek");
    for p in reference_paths() {
        if p.name != "circle" {
            continue;
        }
        let r = run(cfg.clone(), &p.blocks);
        let v: Vec<String> = r
            .ticks
            .iter()
            .step_by(10)
            .map(|t| format!("{:.1}", t.path_v_mm_s))
            .collect();
        println!("{}", v.join(" "));
        let s = &r.segments[1200];
        println!(
            "v_max {:.2} accel {:.1} jerk {:.0} cap {:?} n {}",
            s.v_max_mm_s, s.accel_mm_s2, s.jerk_mm_s3, s.junction_cap_mm_s, s.axis_filter_ticks
        );
    }
}
