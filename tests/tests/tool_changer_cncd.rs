//! The automatic tool changer (docs/setup.md "Automatic tool changer") through `cncd` and
//! `cncctl` on the simulated mill: an ISO program with two tool changes runs to its end with
//! no operator action; a confirmation that does not come holds it with the wait timed out
//! until the input is set and `cncctl resume`.

mod operator_support;

use operator_support::*;
use serde_json::Value;

const REK: &str = "; mill\nR052=500\nR055=0.010\nR237=500\n";

const CHANGER: &str = "[[io.inputs]]\nname = \"estop\"\nfunction = \"estop\"\n\
    [[io.inputs]]\nname = \"unclamped\"\nconfirms = [\"M62\"]\ntimeout_ms = 200\n\
    [[io.inputs]]\nname = \"clamped\"\nconfirms = [\"M64\"]\ntimeout_ms = 200\n\
    [[io.outputs]]\nname = \"unclamp\"\non = [\"M61\"]\noff = [\"M63\"]\n\
    [[io.outputs]]\nname = \"tool_bit0\"\n\
    [[io.outputs]]\nname = \"tool_bit1\"\n\
    [tool_change]\nmode = \"automatic\"\nsequence = [61, 62, 63, 64]\n\
    tool_number_outputs = [\"tool_bit0\", \"tool_bit1\"]\n";

const PROGRAM: &str = "G21 G90\nT2 M6\nG1 X5 F3000\nT3 M6\nG1 X10\nM2\n";

fn json(d: &Cncd, args: &[&str]) -> Value {
    d.json(args)
}

fn ok(d: &Cncd, args: &[&str]) -> String {
    let (ok, out) = d.cncctl(args);
    assert!(ok, "cncctl {args:?}: {out}\n{}", d.log());
    out
}

fn point<'a>(io: &'a Value, kind: &str, name: &str) -> &'a Value {
    io[kind]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["name"] == name)
        .unwrap_or_else(|| panic!("{name} in {io}"))
}

#[test]
fn m6_runs_the_changer_without_resume_and_a_missing_confirmation_holds_until_resume() {
    let cwd = temp_dir("atc");
    std::fs::create_dir_all(cwd.join("data")).unwrap();
    std::fs::write(cwd.join("data/TAB0.REK"), REK).unwrap();
    let d = Cncd::start(&cwd, &format!("{MILL_TOML}\n{CHANGER}"));
    for input in ["unclamped", "clamped"] {
        ok(&d, &["io", "sim-set", input, "1"]);
    }
    std::fs::write(cwd.join("atc.ngc"), PROGRAM).unwrap();
    // Both confirmations read 1: the program runs through both changes by itself.
    ok(&d, &["run", "atc.ngc", "--quiet"]);
    let s = json(&d, &["status"]);
    assert!(s["tool_change"].is_null() && s["state"] == "idle", "{s}");
    let io = json(&d, &["io"]);
    assert_eq!(point(&io, "outputs", "tool_bit0")["value"], 1, "T3: {io}");
    assert_eq!(point(&io, "outputs", "tool_bit1")["value"], 1, "T3: {io}");
    assert_eq!(point(&io, "outputs", "unclamp")["value"], 0, "{io}");
    // The clamp sensor does not report: the first change holds at its last wait.
    ok(&d, &["io", "sim-set", "clamped", "0"]);
    ok(&d, &["load", "atc.ngc"]);
    ok(&d, &["start"]);
    wait_for("the wait timed out", || {
        point(&json(&d, &["io"]), "inputs", "clamped")["wait_timed_out"] == true
    });
    let s = json(&d, &["status"]);
    assert_eq!(s["state"], "hold", "{s}");
    assert!(s["tool_change"].is_null(), "no manual prompt: {s}");
    ok(&d, &["io", "sim-set", "clamped", "1"]);
    ok(&d, &["resume"]);
    d.wait_idle();
    let s = json(&d, &["status"]);
    assert_eq!(s["finished_job"], s["job"], "{s}");
}
