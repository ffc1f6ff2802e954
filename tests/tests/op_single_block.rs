//! Issue #31 (Seen 6), single block through `cncd` and `cncctl` on the simulated machine: the
//! path stops at rest exactly at the end of every block (within 1 µm, actual position), the
//! status names the block just finished, and start (or resume) runs the next block. Also when
//! single block is switched on while a program runs through smooth junctions.

mod operator_support;

use operator_support::*;
use serde_json::Value;

/// Blocks joined smoothly (G23) in X and Y, so that without single block the path would run
/// through the junctions; end points by block number.
const PROGRAM: &str = "N10 G1 X5 Y0 F3000\nN20 G23 X10 Y3\nN30 G23 X12 Y8\nN40 G23 X20 Y8\n";
const ENDS: [(u32, [f64; 2]); 4] = [
    (10, [5.0, 0.0]),
    (20, [10.0, 3.0]),
    (30, [12.0, 8.0]),
    (40, [20.0, 8.0]),
];

fn status(d: &Cncd) -> Value {
    let (ok, out) = d.cncctl(&["--json", "status"]);
    assert!(ok, "{out}");
    serde_json::from_str(out.trim()).unwrap()
}

fn actual(s: &Value) -> [f64; 2] {
    let a = |i: usize| s["axes"][i]["actual_mm"].as_f64().unwrap();
    [a(0), a(1)]
}

/// Waits until `f` holds with the axes settled (at rest, actual = commanded); that status.
fn wait_settled(d: &Cncd, what: &str, f: impl Fn(&Value) -> bool) -> Value {
    let mut last = Value::Null;
    wait_for(what, || {
        last = status(d);
        let settled = (0..2).all(|i| {
            let ax = &last["axes"][i];
            (ax["actual_mm"].as_f64().unwrap() - ax["commanded_mm"].as_f64().unwrap()).abs() < 1e-6
        });
        last["path_velocity_mm_s"].as_f64() == Some(0.0) && settled && f(&last)
    });
    last
}

/// Waits for a single-block stop with the axes settled; its status.
fn wait_block_stop(d: &Cncd) -> Value {
    wait_settled(d, "a single-block stop", |s| !s["block_finished"].is_null())
}

/// Waits for the program's end with the axes settled; its status.
fn wait_end(d: &Cncd) -> Value {
    wait_settled(d, "the program's end", |s| {
        s["state"] == "idle" && s["finished_job"] == s["job"]
    })
}

fn assert_at_end_of(s: &Value, n: u32) {
    let end = ENDS.iter().find(|(b, _)| *b == n).unwrap().1;
    let a = actual(s);
    let err = ((a[0] - end[0]).powi(2) + (a[1] - end[1]).powi(2)).sqrt();
    assert!(
        err <= 1e-3,
        "N{n}: stands at {a:?}, its end is {end:?} ({err} mm)"
    );
}

#[test]
fn single_block_stops_exactly_at_each_block_end_and_names_it() {
    let cwd = temp_dir("single_block");
    let d = Cncd::start(&cwd, MILL_TOML);
    std::fs::write(cwd.join("sb.nc"), PROGRAM).unwrap();
    for args in [&["single-block", "on"][..], &["load", "sb.nc"], &["start"]] {
        let (ok, out) = d.cncctl(args);
        assert!(ok, "{args:?}: {out}");
    }
    for n in [10, 20, 30] {
        let s = wait_block_stop(&d);
        assert_eq!(s["block_finished"]["block"], n, "{s}");
        assert_eq!(s["state"], "hold", "{s}");
        assert_at_end_of(&s, n);
        let (ok, out) = d.cncctl(&["status"]);
        assert!(
            ok && out.contains(&format!("single block: N{n} (line {}) done", n / 10)),
            "{out}"
        );
        // Cycle start runs the next block.
        let (ok, out) = d.cncctl(&["start"]);
        assert!(ok, "{out}");
    }
    assert_at_end_of(&wait_end(&d), 40);
}

#[test]
fn single_block_switched_on_while_running_stops_at_a_block_end() {
    let cwd = temp_dir("single_block_on");
    let d = Cncd::start(&cwd, MILL_TOML);
    // Slow enough that the switch comes while the path moves.
    std::fs::write(cwd.join("sb.nc"), PROGRAM.replace("F3000", "F300")).unwrap();
    let (ok, out) = d.cncctl(&["load", "sb.nc"]);
    assert!(ok, "{out}");
    let (ok, out) = d.cncctl(&["start"]);
    assert!(ok, "{out}");
    let (ok, out) = d.cncctl(&["single-block", "on"]);
    assert!(ok, "{out}");
    let s = wait_block_stop(&d);
    let n = s["block_finished"]["block"].as_u64().unwrap() as u32;
    assert_at_end_of(&s, n);
    let (ok, out) = d.cncctl(&["single-block", "off"]);
    assert!(ok, "{out}");
    let (ok, out) = d.cncctl(&["resume"]);
    assert!(ok, "{out}");
    assert_at_end_of(&wait_end(&d), 40);
}

#[test]
fn a_restart_in_single_block_holds_after_the_approach_and_after_each_block() {
    let cwd = temp_dir("single_block_restart");
    let d = Cncd::start(&cwd, MILL_TOML);
    std::fs::write(cwd.join("sb.nc"), PROGRAM).unwrap();
    for args in [
        &["single-block", "on"][..],
        &["load", "sb.nc"],
        &["start", "--from-block", "30", "--yes"],
    ] {
        let (ok, out) = d.cncctl(args);
        assert!(ok, "{args:?}: {out}");
    }
    // The approach (to where N30 starts: the end of N20) is a block of its own: it holds at
    // its end, without a block number.
    let s = wait_block_stop(&d);
    assert!(s["block_finished"]["block"].is_null(), "{s}");
    assert_eq!(s["state"], "hold", "{s}");
    assert_at_end_of(&s, 20);
    let (ok, out) = d.cncctl(&["status"]);
    assert!(ok && out.contains("single block: approach done"), "{out}");
    // Then one block per cycle start, each ending exactly at its end point.
    let (ok, out) = d.cncctl(&["start"]);
    assert!(ok, "{out}");
    let s = wait_block_stop(&d);
    assert_eq!(s["block_finished"]["block"], 30, "{s}");
    assert_at_end_of(&s, 30);
    let (ok, out) = d.cncctl(&["start"]);
    assert!(ok, "{out}");
    assert_at_end_of(&wait_end(&d), 40);
}
