//! The planner against the independent references of issue #32 (`scripts/planner-reference/`:
//! dense paths, the exact junction bound on the polyline and TOPP-RA on the smooth curve,
//! computed without the planner's code; and `scripts/linuxcnc-compare/linuxcnc.tsv`, LinuxCNC
//! 2.9 on the same paths). Deterministic, in virtual time, on the configuration `cncd` builds
//! for the machine: every axis within its acceleration and speed, setpoints on the
//! polyline (1 nm), the machining time within 1.03 of max(exact, smooth), and faster than
//! LinuxCNC on every path.

mod plan_common;

use plan_common::*;

/// LinuxCNC 2.9's time on each reference path, s (`linuxcnc.tsv`).
fn linuxcnc_s(name: &str) -> f64 {
    let file = reference_dir().join("../linuxcnc-compare/linuxcnc.tsv");
    let table = std::fs::read_to_string(file).unwrap();
    let row = table
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| l.split('\t').collect::<Vec<_>>())
        .find(|f| f[0] == name)
        .unwrap_or_else(|| panic!("no LinuxCNC time for {name}"));
    row[1].parse().unwrap()
}

#[test]
fn dense_paths_run_near_the_independent_limit_within_the_axis_limits() {
    let cfg = reference_config();
    let mut failures = vec![];
    for p in reference_paths() {
        let r = run(cfg.clone(), &p.blocks);
        let w = measure(&cfg, &r, 8.0);
        let ratio = r.time_s() / p.limit_s;
        let linuxcnc = linuxcnc_s(&p.name);
        println!(
            "{:10} {:6} blocks: {:.3} s, limit {:.3} s (exact {:.3}, smooth {:.3}), ratio {ratio:.3}, LinuxCNC {linuxcnc:.3} s, axis a {:.6}, off path {:.1e} mm",
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
        let fast = ratio <= 1.03 && r.time_s() < linuxcnc;
        if !fast || !within || w.off_path_mm > 1e-6 || w.missed_stops > 0 {
            failures.push(format!("{} ({}): ratio {ratio:.4}, {w:?}", p.name, p.title));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
