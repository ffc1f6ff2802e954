//! The planner against the independent reference of issue #32 (`scripts/planner-reference/`:
//! dense paths, the exact junction bound on the polyline and TOPP-RA on the smooth curve,
//! computed without the planner's code). Deterministic, in virtual time, on the configuration
//! `cncd` builds for the machine: every axis within its acceleration and speed,
//! setpoints on the polyline (1 nm), and the machining time within 1.03 of
//! max(exact, smooth) — except on the paths listed in `NOT_YET_MET`, where the bound is the
//! ratio measured when this test was written (a regression guard; see docs/planner.md).

mod plan_common;

use plan_common::*;

/// Paths where the planner is still more than 3 % above the limit (issue #32 is not met
/// there), with the ratio they must not exceed.
const NOT_YET_MET: &[(&str, f64)] = &[("splines", 1.12), ("arcs", 1.09), ("helix", 1.045)];

#[test]
fn dense_paths_run_near_the_independent_limit_within_the_axis_limits() {
    let cfg = reference_config();
    let mut failures = vec![];
    for p in reference_paths() {
        let r = run(cfg.clone(), &p.blocks);
        let w = measure(&cfg, &r, 8.0);
        let ratio = r.time_s() / p.limit_s;
        let bound = NOT_YET_MET
            .iter()
            .find(|(n, _)| *n == p.name)
            .map_or(1.03, |(_, b)| *b);
        println!(
            "{:10} {:6} blocks: {:.3} s, limit {:.3} s (exact {:.3}, smooth {:.3}), ratio {ratio:.3} (bound {bound}), axis a {:.6}, off path {:.1e} mm",
            p.name,
            p.blocks.len(),
            r.time_s(),
            p.limit_s,
            p.exact_s,
            p.smooth_s,
            w.axis_a,
            w.off_path_mm
        );
        let within = w.axis_a <= 1.0 + 1e-6 && w.axis_v <= 1.0 + 1e-9 && w.path_v <= 1.0 + 1e-9;
        if ratio > bound || !within || w.off_path_mm > 1e-6 || w.missed_stops > 0 {
            failures.push(format!("{} ({}): ratio {ratio:.4}, {w:?}", p.name, p.title));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
