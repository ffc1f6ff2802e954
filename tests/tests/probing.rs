//! Issue #47 (probing), through `cncd` and `cncctl` on the simulated mill: its probe touches
//! the simulated workpiece (X 0..100, Y 0..100, top Z -10, a 20 mm bore at X50 Y50) and tool
//! setter (X-40 Y50, top Z -20) with a 42.5 mm tool. Every position taken is checked
//! against that geometry, the sim's, not against what the controller computes; the bound
//! is the documented accuracy: the probe input is sampled once per bus period (4 ms), so
//! the position taken lies within feed × period past the surface.

mod operator_support;

use operator_support::*;
use serde_json::Value;

const TOOL_MM: f64 = 42.5;
/// One bus period (4 ms) at the latch feed (60 mm/min here: 1 mm/s) and at the search feed
/// (600 mm/min: 10 mm/s).
const LATCH_STEP_MM: f64 = 1.0 * 0.004;
const SEARCH_STEP_MM: f64 = 10.0 * 0.004;
/// The table keeps 6 decimals.
const TABLE_MM: f64 = 1e-6;

fn config() -> String {
    format!(
        "{MILL_TOML}\n[sim]\ntool_length_mm = {TOOL_MM}\n\n[probe]\nsearch_feed_mm_min = 600\n\
         latch_feed_mm_min = 60\nbackoff_mm = 0.5\n\n[probe.setter]\nx_mm = -40\ny_mm = 50\n\
         z_mm = -20\nclearance_z_mm = 40\n"
    )
}

fn json(d: &Cncd, args: &[&str]) -> Value {
    d.json(args)
}

fn commanded(d: &Cncd, axis: usize) -> f64 {
    json(d, &["status"])["axes"][axis]["commanded_mm"]
        .as_f64()
        .unwrap()
}

/// Moves one axis to `target` (machine coordinates) by a jog step, and waits.
fn go(d: &Cncd, axis: usize, target: f64) {
    let step = target - commanded(d, axis);
    if step.abs() > 1e-9 {
        let letter = ["X", "Y", "Z"][axis];
        d.jog_step(letter, step);
    }
}

fn refused(d: &Cncd, args: &[&str], code: &str) {
    let (ok, out) = d.cncctl(args);
    assert!(!ok && out.contains(code), "cncctl {args:?}: {out}");
}

/// `value` lies in `[truth - step, truth]` (taken at most one period past the surface),
/// give or take the table's rounding.
fn within(what: &str, value: f64, truth: f64, step: f64) {
    let past = truth - value;
    assert!(
        (-TABLE_MM..=step + TABLE_MM).contains(&past),
        "{what}: {value} against {truth} (one period {step} mm)"
    );
}

fn written(reply: &Value, axis: &str) -> f64 {
    reply["written"]
        .as_array()
        .unwrap()
        .iter()
        .find(|w| w["axis"] == axis)
        .unwrap_or_else(|| panic!("{reply}"))["length_mm"]
        .as_f64()
        .unwrap()
}

#[test]
fn probing_finds_the_simulated_workpiece_and_writes_the_entries() {
    let cwd = temp_dir("probing");
    let d = Cncd::start(&cwd, &config());
    // The tool setter writes the tool's length: its tip touches the top at -20.
    let r = json(&d, &["probe", "tool-setter", "3"]);
    within("tool length", written(&r, "Z"), TOOL_MM, LATCH_STEP_MM);
    let z = commanded(&d, 2);
    assert!((z - 40.0).abs() < 1e-6, "back at the clearance: {z}");
    // A probing move onto the top (-10 at the tip) reports the contact.
    go(&d, 0, 20.0);
    go(&d, 1, 20.0);
    let r = json(&d, &["probe", "move", "Z", "-20"]);
    let z = r["machine_mm"][2].as_f64().unwrap();
    within("top face", z, -10.0 + TOOL_MM, SEARCH_STEP_MM);
    // It stands in contact now: the next move toward the part is refused, nothing moves.
    let here = commanded(&d, 2);
    refused(&d, &["probe", "move", "Z", "-1"], "probe_already_triggered");
    assert_eq!(commanded(&d, 2), here);
    // Away until it releases, then a move that misses.
    json(&d, &["probe", "move", "Z", "5", "--away"]);
    d.wait_idle();
    go(&d, 2, 60.0);
    refused(&d, &["probe", "move", "Z", "-5"], "probe_no_contact");
    assert!((commanded(&d, 2) - 55.0).abs() < 1e-6, "the whole distance");
    // The left edge (X 0), from outside below the top: the ball's radius is taken.
    go(&d, 0, -10.0);
    go(&d, 1, 50.0);
    go(&d, 2, -20.0 + TOOL_MM);
    let r = json(&d, &["probe", "edge", "4", "X", "+"]);
    within("edge", -written(&r, "X"), 0.0, LATCH_STEP_MM);
    // The bore's centre from off-centre inside it: the lengths make it read X0 Y0.
    go(&d, 2, 20.0 + TOOL_MM);
    go(&d, 0, 47.0);
    go(&d, 1, 52.5);
    go(&d, 2, -20.0 + TOOL_MM);
    let r = json(&d, &["probe", "bore", "5"]);
    for axis in ["X", "Y"] {
        let c = written(&r, axis);
        assert!((c - 50.0).abs() <= LATCH_STEP_MM + TABLE_MM, "{axis}: {r}");
    }
    let across = r["diameter_mm"].as_f64().unwrap();
    assert!((across - 20.0).abs() <= 2.0 * LATCH_STEP_MM, "{r}");
    // The entries are in the table on file, as every edit.
    let file = json(&d, &["offsets-file"]);
    let text = file["text"].as_str().unwrap();
    for n in ["03:", "04:", "05:"] {
        assert!(text.contains(n), "{n} in {text}");
    }
    // Not while a program runs.
    std::fs::write(cwd.join("hold.nc"), "N10 G1 X50 F3000 M0\nN20 M30\n").unwrap();
    json(&d, &["load", "hold.nc"]);
    json(&d, &["start"]);
    wait_for("the program stop", || {
        json(&d, &["status"])["program_stop"] == true
    });
    refused(&d, &["probe", "move", "Z", "-1"], "probe_busy");
    refused(&d, &["probe", "bore", "5"], "probe_busy");
    json(&d, &["stop"]);
    d.wait_idle();
}

/// Runs program `name` (written with `text`) to its end: the status of the idle machine.
fn run(d: &Cncd, name: &str, text: &str) -> Value {
    std::fs::write(d.cwd.join(name), text).unwrap();
    json(d, &["load", name]);
    let before = json(d, &["status"])["job"].as_u64().unwrap_or(0);
    json(d, &["start"]);
    wait_for("the program's end", || {
        let s = json(d, &["status"]);
        s["state"] == "idle" && s["job"].as_u64().unwrap_or(0) > before
    });
    json(d, &["status"])
}

fn commanded_of(s: &Value, axis: usize) -> f64 {
    s["axes"][axis]["commanded_mm"].as_f64().unwrap()
}

#[test]
fn programs_probe_with_g38_and_g31() {
    let cwd = temp_dir("probing_programs");
    std::fs::create_dir_all(cwd.join("data")).unwrap();
    std::fs::write(
        cwd.join("data/TAB0.REK"),
        "; mill\nR052=500\nR055=0.010\nR237=500\n",
    )
    .unwrap();
    let d = Cncd::start(&cwd, &config());
    // docs/setup.md's program. The top face reads -10 + 42.5 at the spindle: a fast touch,
    // back 5, a slow one, then 2 mm above what the slow one found.
    let md = include_str!("../../docs/setup.md");
    let text = md
        .split("```ngc\n")
        .nth(1)
        .and_then(|b| b.split("```").next())
        .expect("the program in docs/setup.md");
    let s = run(&d, "touch.ngc", text);
    assert_eq!(s["alarm"], "", "{s}");
    within(
        "G38.2 top face",
        commanded_of(&s, 2) - 2.0,
        -10.0 + TOOL_MM,
        LATCH_STEP_MM,
    );
    assert!((commanded_of(&s, 0) - 30.0).abs() < 1e-6, "{s}");
    // G38.3 may miss: the program goes on (#5070 = 0 moves X to 40).
    let text = "G21 G90\nG0 Z50\nG38.3 Z45 F600\nG0 X[40 + #5070]\nM2\n";
    let s = run(&d, "maybe.ngc", text);
    assert!((commanded_of(&s, 0) - 40.0).abs() < 1e-6, "{s}");
    // G38.2 must touch: a miss ends the run at that block with its code.
    let text = "G21 G90\nG38.2 Z40 F600\nG0 X50\nM2\n";
    let s = run(&d, "miss.ngc", text);
    assert!(
        s["alarm"].as_str().unwrap().contains("probe_no_contact"),
        "{s}"
    );
    assert!(
        (commanded_of(&s, 0) - 40.0).abs() < 1e-6,
        "nothing after it ran: {s}"
    );
    assert!(
        (commanded_of(&s, 2) - 40.0).abs() < 1e-6,
        "the whole move: {s}"
    );
    // Away from a contact that is not there: refused before anything moves.
    let text = "G21 G90\nG0 X20 Y20 Z35\nG38.4 Z50 F600\nM2\n";
    let s = run(&d, "clear.ngc", text);
    assert!(
        s["alarm"]
            .as_str()
            .unwrap()
            .contains("probe_already_triggered"),
        "{s}"
    );
    assert_eq!(commanded_of(&s, 2), 35.0, "nothing moved: {s}");
    // CNC836: G31, the contact in R92.
    let text = "N10 G0 X20 Y20 Z50\nN20 G31 Z0 F600\nN30 G0 ZR92\nN40 M30\n";
    let s = run(&d, "touch.nc", text);
    within(
        "G31 top face",
        commanded_of(&s, 2),
        -10.0 + TOOL_MM,
        SEARCH_STEP_MM,
    );
}

#[test]
fn a_machine_without_a_probe_input_refuses_probing() {
    let cwd = temp_dir("probing_none");
    let io = "[[io.inputs]]\nname = \"estop\"\nfunction = \"estop\"\n";
    let d = Cncd::start(&cwd, &format!("{MILL_TOML}\n{io}"));
    refused(&d, &["probe", "move", "Z", "-1"], "probe_unavailable");
    refused(&d, &["probe", "edge", "1", "X", "up"], "give the direction");
    // A program's probing move too, before anything moves.
    let s = run(&d, "probe.ngc", "G21 G90\nG0 Z5\nG38.2 Z-20 F300\nM2\n");
    assert!(
        s["alarm"].as_str().unwrap().contains("probe_unavailable"),
        "{s}"
    );
    assert_eq!(commanded_of(&s, 2), 5.0, "nothing moved: {s}");
}

#[test]
fn the_settings_in_docs_setup_md_are_a_valid_configuration() {
    let md =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/setup.md")).unwrap();
    let blocks: Vec<&str> = md
        .split("```toml\n")
        .skip(1)
        .filter_map(|b| b.split("```").next())
        .collect();
    let path = std::path::Path::new("docs/setup.md");
    let parse = |key: &str| {
        let block = blocks.iter().find(|b| b.contains(key)).expect(key);
        daemon::runtime::config::Config::parse(block, path).unwrap()
    };
    let c = parse("[probe]");
    assert_eq!(c.probe().latch_feed_mm_min, 50.0);
    assert_eq!(c.probe().setter.map(|s| s.x_mm), Some(-40.0));
    assert_eq!(c.sim.bores.len(), 1);
    // The automatic tool changer's example too.
    let c = parse("[tool_change]");
    assert_eq!(c.tool_change.sequence, [61, 62, 63]);
}
