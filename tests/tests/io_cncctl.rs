//! The machine's inputs and outputs (issue #46) through `cncd` and `cncctl` as a machine
//! builder commissioning the simulated machine uses them: `cncctl io`, `sim-set`, `force`,
//! MDI M8/M9, the e-stop refusing Reset.

mod operator_support;

use operator_support::*;

fn io_json(d: &Cncd) -> serde_json::Value {
    let (ok, out) = d.cncctl(&["--json", "io"]);
    assert!(ok, "{out}");
    serde_json::from_str(out.trim()).unwrap()
}

fn value(io: &serde_json::Value, kind: &str, name: &str) -> u64 {
    io[kind]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["name"] == name)
        .unwrap_or_else(|| panic!("{name} in {io}"))["value"]
        .as_u64()
        .unwrap()
}

#[test]
fn estop_force_and_m8_through_cncd_and_cncctl() {
    let cwd = temp_dir("io");
    let d = Cncd::start(&cwd, MILL_TOML);
    d.wait_idle();
    let io = io_json(&d);
    assert_eq!(value(&io, "inputs", "estop"), 1, "{io}");
    assert_eq!(value(&io, "inputs", "door"), 1);
    assert_eq!(value(&io, "outputs", "coolant"), 0);
    assert_eq!(io["simulated"], true);
    // The human list names every point.
    let (ok, text) = d.cncctl(&["io"]);
    assert!(
        ok && text.contains("x_limit_pos") && text.contains("spindle_enable"),
        "{text}"
    );
    // MDI M8 switches the coolant on, M9 off.
    let (ok, out) = d.cncctl(&["mdi", "M8"]);
    assert!(ok, "{out}");
    wait_for("coolant on", || {
        value(&io_json(&d), "outputs", "coolant") == 1
    });
    // (The M8 job ends once its block has run: idle before the next MDI.)
    d.wait_idle();
    let (ok, out) = d.cncctl(&["mdi", "M9"]);
    assert!(ok, "{out}");
    wait_for("coolant off", || {
        value(&io_json(&d), "outputs", "coolant") == 0
    });
    // The e-stop chain opens: fault; Reset is refused until it closes.
    let (ok, out) = d.cncctl(&["io", "sim-set", "estop", "0"]);
    assert!(ok, "{out}");
    wait_for("fault", || {
        let (_, s) = d.cncctl(&["--json", "status"]);
        s.contains("\"state\":\"fault\"") && s.contains("emergency stop")
    });
    let (ok, out) = d.cncctl(&["reset"]);
    assert!(!ok && out.contains("emergency-stop chain is open"), "{out}");
    let (ok, out) = d.cncctl(&["io", "sim-set", "estop", "1"]);
    assert!(ok, "{out}");
    let (ok, out) = d.cncctl(&["reset"]);
    assert!(ok, "{out}");
    d.wait_idle();
    // Forcing an output: marked FORCED, released by Reset.
    let (ok, out) = d.cncctl(&["io", "force", "coolant", "1"]);
    assert!(ok && out.contains("FORCED"), "{out}");
    assert_eq!(value(&io_json(&d), "outputs", "coolant"), 1);
    let (ok, out) = d.cncctl(&["reset"]);
    assert!(ok, "{out}");
    wait_for("forcing released", || {
        let io = io_json(&d);
        value(&io, "outputs", "coolant") == 0 && !io.to_string().contains("\"forced\":true")
    });
    // A limit switch: fault naming the axis and side; after Reset only a jog away moves.
    let (ok, out) = d.cncctl(&["io", "sim-set", "x_limit_pos", "1"]);
    assert!(ok, "{out}");
    wait_for("limit fault", || {
        let (_, s) = d.cncctl(&["--json", "status"]);
        s.contains("\"state\":\"fault\"") && s.contains("axis X") && s.contains("positive side")
    });
    let (ok, out) = d.cncctl(&["reset"]);
    assert!(ok, "{out}");
    d.wait_idle();
    let (ok, out) = d.cncctl(&["jog", "X", "--step", "1"]);
    assert!(!ok && out.contains("limit switch"), "{out}");
    let (ok, out) = d.cncctl(&["jog", "X", "--step", "-1"]);
    assert!(ok, "{out}");
    let (ok, out) = d.cncctl(&["io", "sim-set", "x_limit_pos", "release"]);
    assert!(ok, "{out}");
    // A wrong value is refused by cncctl itself.
    let (ok, out) = d.cncctl(&["io", "force", "coolant", "2"]);
    assert!(!ok && out.contains("give 0, 1 or release"), "{out}");
}

/// The simulated machine with buttons wired: the cycle start button starts the loaded
/// program, feed hold holds it, cycle start resumes it.
const BUTTONS: &str = "[[io.inputs]]\nname = \"estop\"\nfunction = \"estop\"\n\n\
    [[io.inputs]]\nname = \"start\"\nfunction = \"cycle_start\"\n\n\
    [[io.inputs]]\nname = \"hold\"\nfunction = \"feed_hold\"\n";

fn state(d: &Cncd) -> String {
    let (_, s) = d.cncctl(&["--json", "status"]);
    s
}

fn press(d: &Cncd, button: &str) {
    for v in ["1", "0"] {
        let (ok, out) = d.cncctl(&["io", "sim-set", button, v]);
        assert!(ok, "{out}");
    }
}

#[test]
fn the_cycle_start_and_feed_hold_buttons_start_hold_and_resume_the_program() {
    let cwd = temp_dir("io-buttons");
    let d = Cncd::start(&cwd, &format!("{MILL_TOML}\n{BUTTONS}"));
    d.wait_idle();
    let part = cwd.join("part.nc");
    std::fs::write(&part, "G1 X300 F600\nM30\n").unwrap();
    let (ok, out) = d.cncctl(&["load", part.to_str().unwrap()]);
    assert!(ok, "{out}");
    press(&d, "start");
    wait_for("running", || state(&d).contains("\"state\":\"running\""));
    press(&d, "hold");
    wait_for("hold", || state(&d).contains("\"state\":\"hold\""));
    press(&d, "start");
    wait_for("running again", || {
        state(&d).contains("\"state\":\"running\"")
    });
    let (ok, out) = d.cncctl(&["stop"]);
    assert!(ok, "{out}");
    d.wait_idle();
}
