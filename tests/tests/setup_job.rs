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
    d.jog_step("X", 12.3456);
    d.jog_step("Y", -7.5);
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
    d.jog_step("X", -30.0);
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
    d.jog_step("X", 5.0);
    let here = commanded(&d);
    ok(&d, &["touch-off", "1", "X", "0", "--work", "G54"]);
    d.jog_step("X", -30.0);
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

/// Waits for the next hold at a program stop; returns its status.
fn held(d: &Cncd) -> Value {
    let mut s = Value::Null;
    wait_for("a program stop", || {
        s = status(d);
        s["program_stop"] == true
    });
    s
}

fn at(s: &Value) -> [f64; 3] {
    let a = |i: usize| s["axes"][i]["commanded_mm"].as_f64().unwrap();
    [a(0), a(1), a(2)]
}

fn near(a: [f64; 3], b: [f64; 3]) -> bool {
    (0..3).all(|k| (a[k] - b[k]).abs() < 1e-3)
}

#[test]
fn two_tool_changes_hold_name_the_tool_and_go_on_with_its_entries() {
    let cwd = temp_dir("tool_change");
    let d = Cncd::start(
        &cwd,
        &format!("{MILL_TOML}\n[tool_change]\nmode = \"manual\"\n"),
    );
    ok(&d, &["offset-set", "1", "--radius", "3", "--l3", "10"]);
    ok(&d, &["offset-set", "2", "--radius", "5", "--l3", "25.5"]);
    // Each M0 stands at the end of a compensated cut: Y is the radius, Z the length.
    let program = "N10 G0 X0 Y0 Z50\nN20 T1 M6\nN30 G0 Z0\nN40 G41 G1 X20 Y0 F3000\n\
                   N50 G1 X30 M0\nN60 G40 G1 X40\nN70 T2 M6\nN80 G0 Z0\nN90 G41 G1 X60 Y0\n\
                   N100 G1 X70 M0\nN110 G40 G1 X80\nN120 M30\n";
    std::fs::write(cwd.join("tools.nc"), program).unwrap();
    ok(&d, &["load", "tools.nc"]);
    ok(&d, &["start"]);
    let s = held(&d);
    assert_eq!(s["tool_change"]["tool"], 1, "{s}");
    assert_eq!(s["tool_change"]["radius_mm"], 3.0, "{s}");
    assert_eq!(s["tool_change"]["length_mm"][2], 10.0, "{s}");
    assert!(near(at(&s), [0.0, 0.0, 50.0]), "{s}");
    let line = ok(&d, &["status"]);
    assert!(line.contains("tool change: put in tool T1"), "{line}");
    // Cycle Start confirms as Resume does.
    ok(&d, &["start"]);
    let s = held(&d);
    assert!(s["tool_change"].is_null(), "{s}");
    assert!(near(at(&s), [30.0, 3.0, 10.0]), "tool 1 cut: {s}");
    ok(&d, &["resume"]);
    let s = held(&d);
    assert_eq!(s["tool_change"]["tool"], 2, "{s}");
    assert_eq!(s["tool_change"]["radius_mm"], 5.0, "{s}");
    assert!(near(at(&s), [40.0, 0.0, 10.0]), "{s}");
    ok(&d, &["resume"]);
    let s = held(&d);
    assert!(near(at(&s), [70.0, 5.0, 25.5]), "tool 2 cut: {s}");
    ok(&d, &["resume"]);
    d.wait_idle();
    assert!(near(commanded(&d), [80.0, 0.0, 25.5]));
}

/// The lines of the ```sh blocks of a markdown text, in order.
fn sh_lines(md: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut in_sh = false;
    for line in md.lines() {
        let t = line.trim();
        if t.starts_with("```") {
            in_sh = !in_sh && t == "```sh";
            continue;
        }
        // A comment after `#` says where the machine stands.
        let t = t.split('#').next().unwrap_or_default().trim();
        if in_sh && !t.is_empty() {
            out.push(t.to_string());
        }
    }
    out
}

#[test]
fn docs_setup_md_runs_as_written() {
    const REPO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
    let md = std::fs::read_to_string(format!("{REPO}/docs/setup.md")).unwrap();
    let cwd = temp_dir("setup_docs");
    let programs = cwd.join("programs/setup");
    std::fs::create_dir_all(&programs).unwrap();
    for f in ["touched.nc", "tools.nc"] {
        std::fs::copy(format!("{REPO}/programs/setup/{f}"), programs.join(f)).unwrap();
    }
    let d = Cncd::start(&cwd, MILL_TOML);
    let (mut touched, mut prompts, mut probed) = (None, 0, 0);
    for line in sh_lines(&md) {
        let args: Vec<&str> = line.split_whitespace().collect();
        assert_eq!(args[0], "cncctl", "{line}");
        if line.starts_with("cncctl touch-off 1 X") {
            touched = Some(commanded(&d));
        }
        let out = ok(&d, &args[1..]);
        prompts += usize::from(out.contains("tool change: put in tool T"));
        if line.starts_with("cncctl probe") {
            probed += usize::from(out.contains("written") || out.contains("contact at"));
        }
        // At rest before the next command: idle, or held at a program stop.
        wait_for(&line, || {
            let s = status(&d);
            s["state"] == "idle" || s["program_stop"] == true
        });
        if line == "cncctl run programs/setup/touched.nc" {
            let (here, at) = (touched.unwrap(), commanded(&d));
            assert!(
                (0..2).all(|k| (here[k] - at[k]).abs() < 1e-3),
                "{here:?} {at:?}"
            );
        }
    }
    assert_eq!(prompts, 2, "each status names its tool");
    assert_eq!(probed, 4, "each probing command reports what it found");
    // The bore's centre reads X0 Y0 through entry 5 (the simulated bore is at X50 Y50).
    let e: Value = serde_json::from_str(ok(&d, &["--json", "offsets"]).trim()).unwrap();
    let five = e["entries"]
        .as_array()
        .unwrap()
        .iter()
        .find(|x| x["entry"] == 5)
        .unwrap_or_else(|| panic!("{e}"));
    for k in 0..2 {
        let l = five["length_mm"][k].as_f64().unwrap();
        assert!((l - 50.0).abs() < 0.005, "{five}");
    }
}

#[test]
fn before_homing_touch_off_and_probing_are_refused() {
    let cwd = temp_dir("not_homed");
    let axes = "[[axes]]\nname = \"X\"\nhoming = \"required\"\nhoming_direction = -1\n\
        reference_mm = 0\n[[axes]]\nname = \"Y\"\n[[axes]]\nname = \"Z\"\n";
    let io = "[[io.inputs]]\nname = \"estop\"\nfunction = \"estop\"\n\
        [[io.inputs]]\nname = \"x_home\"\nfunction = \"home\"\naxis = \"X\"\nsim_at_mm = -5\n\
        [[io.inputs]]\nname = \"probe\"\nfunction = \"probe\"\n";
    let d = Cncd::start(&cwd, &format!("{MILL_TOML}\n{axes}\n{io}"));
    let before = ok(&d, &["offsets-file"]);
    for (args, code) in [
        (&["touch-off", "1", "X", "0"][..], "touch_off_not_homed"),
        (&["probe", "move", "Z", "-5"][..], "probe_not_homed"),
        (&["probe", "tool-setter", "1"][..], "probe_not_homed"),
    ] {
        let (done, why) = d.cncctl(args);
        assert!(!done && why.contains(code), "{args:?}: {why}");
    }
    assert_eq!(ok(&d, &["offsets-file"]), before, "nothing written");
    ok(&d, &["home"]);
    d.wait_idle();
    ok(&d, &["touch-off", "1", "X", "0"]);
    let (done, why) = d.cncctl(&["probe", "move", "Z", "5"]);
    assert!(!done && why.contains("probe_no_contact"), "{why}");
}

#[test]
fn an_iso_tool_change_holds_and_goes_on_with_the_tools_length() {
    let cwd = temp_dir("iso_tool_change");
    let d = Cncd::start(&cwd, MILL_TOML);
    ok(&d, &["offset-set", "2", "--radius", "4", "--l3", "12.5"]);
    let program = "G21 G90 G0 X10 Y0 Z50\nT2 M6\nG43\nG0 Z0\nG1 X20 F3000\nM30\n";
    std::fs::write(cwd.join("iso.ngc"), program).unwrap();
    ok(&d, &["load", "iso.ngc"]);
    ok(&d, &["start"]);
    let s = held(&d);
    assert_eq!(s["tool_change"]["tool"], 2, "{s}");
    assert!(near(at(&s), [10.0, 0.0, 50.0]), "{s}");
    ok(&d, &["resume"]);
    d.wait_idle();
    // G43 takes the tool's length: Z0 is at machine 12.5.
    assert!(
        near(commanded(&d), [20.0, 0.0, 12.5]),
        "{:?}",
        commanded(&d)
    );
}
