//! Issue #47 (part 1), as a machinist sets up a job, through `cncd` and `cncctl` on the
//! simulated mill: touch-off (the entry's lengths so that here reads a value) and the
//! manual tool change (M6 holds, names the tool, Resume goes on with its entries).

mod operator_support;

use operator_support::*;
use serde_json::Value;

fn status(d: &Cncd) -> Value {
    let (ok, out) = d.cncctl(&["--json", "status"]);
    assert!(ok, "{out}");
    serde_json::from_str(out.trim()).expect("one JSON object")
}

fn commanded(d: &Cncd) -> [f64; 3] {
    let s = status(d);
    let a = |i: usize| s["axes"][i]["commanded_mm"].as_f64().unwrap();
    [a(0), a(1), a(2)]
}

fn ok(d: &Cncd, args: &[&str]) -> String {
    let (ok, out) = d.cncctl(args);
    assert!(ok, "cncctl {args:?}: {out}\n{}", d.log());
    out
}

#[test]
fn touch_off_then_the_program_goes_to_the_touched_point() {
    let cwd = temp_dir("touch_off");
    let d = Cncd::start(&cwd, MILL_TOML);
    ok(&d, &["jog", "X", "--step", "12.3456"]);
    d.wait_idle();
    ok(&d, &["jog", "Y", "--step", "-7.5"]);
    d.wait_idle();
    let here = commanded(&d);
    let out = ok(&d, &["touch-off", "1", "X", "0", "--radius", "2"]);
    assert!(out.contains("D01"), "{out}");
    ok(&d, &["touch-off", "1", "Y", "0"]);
    // Written to the file as every operator edit is.
    let file = ok(&d, &["offsets-file"]);
    assert!(file.contains("01:"), "{file}");
    // Bad input is refused with its code and changes nothing.
    let (refused, why) = d.cncctl(&["touch-off", "1", "C", "0"]);
    assert!(!refused && why.contains("touch_off_invalid"), "{why}");
    let (refused, why) = d.cncctl(&["touch-off", "100", "X", "0"]);
    assert!(!refused && why.contains("touch_off_invalid"), "{why}");
    // Away, then the CNC836 program selects entry 1 and goes to X0 Y0.
    ok(&d, &["jog", "X", "--step", "-30"]);
    d.wait_idle();
    std::fs::write(cwd.join("part.nc"), "N10 &1 G1 X0 Y0 F3000\nN20 M30\n").unwrap();
    ok(&d, &["run", "part.nc"]);
    let at = commanded(&d);
    for k in 0..2 {
        assert!(
            (at[k] - here[k]).abs() < 1e-3,
            "axis {k}: {at:?} vs {here:?}"
        );
    }
    // ISO: G54 X10 in the file; a touch-off relative to G54 and `G43 H1` reach it too.
    ok(&d, &["work-offset-set", "G54", "X10"]);
    ok(&d, &["jog", "X", "--step", "5"]);
    d.wait_idle();
    let here = commanded(&d);
    ok(&d, &["touch-off", "1", "X", "0", "--work", "G54"]);
    ok(&d, &["jog", "X", "--step", "-30"]);
    d.wait_idle();
    std::fs::write(cwd.join("part.ngc"), "G43 H1\nG1 X0 Y0 F3000\nM30\n").unwrap();
    ok(&d, &["run", "part.ngc"]);
    let at = commanded(&d);
    for k in 0..2 {
        assert!(
            (at[k] - here[k]).abs() < 1e-3,
            "ISO axis {k}: {at:?} vs {here:?}"
        );
    }
    // Refused while a program holds (a typed code), the table unchanged.
    std::fs::write(cwd.join("hold.nc"), "N10 G1 X1 F3000 M0\nN20 M30\n").unwrap();
    ok(&d, &["load", "hold.nc"]);
    ok(&d, &["start"]);
    wait_for("the program stop", || status(&d)["program_stop"] == true);
    let before = ok(&d, &["offsets-file"]);
    let (refused, why) = d.cncctl(&["touch-off", "1", "X", "5"]);
    assert!(!refused && why.contains("touch_off_busy"), "{why}");
    assert_eq!(ok(&d, &["offsets-file"]), before);
    ok(&d, &["stop"]);
    d.wait_idle();
}
