//! `cncd --check-config`: the real binary on a good file (the documented example in `deploy/`)
//! and on one file per class of mistake. A mistake exits with status 2 (the unit's
//! `RestartPreventExitStatus=2`) and a message that names the key.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

mod systemd_support;
use systemd_support::{cncd_binary, repo};

/// The binary, built once per test process.
fn cncd() -> &'static Path {
    static BIN: OnceLock<PathBuf> = OnceLock::new();
    BIN.get_or_init(cncd_binary)
}

fn check(path: &Path) -> Output {
    Command::new(cncd())
        .args(["--check-config", "--config"])
        .arg(path)
        .output()
        .unwrap()
}

/// Writes `text` to a fresh file named after the case and checks it.
fn check_text(case: &str, text: &str) -> Output {
    let dir = std::env::temp_dir().join(format!("cncd-check-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{case}.toml"));
    std::fs::write(&path, text).unwrap();
    let out = check(&path);
    let _ = std::fs::remove_file(&path);
    out
}

/// The file is refused with status 2 and the error `code` (printed as `error [code]:`, the
/// form cncctl gives diagnostics), and the message holds every one of `needles` (the key).
fn assert_refused(case: &str, text: &str, code: &str, needles: &[&str]) {
    let out = check_text(case, text);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        out.status.code(),
        Some(2),
        "{case}: expected exit status 2, got {:?}\nstdout: {}\nstderr: {err}",
        out.status,
        String::from_utf8_lossy(&out.stdout)
    );
    assert!(
        err.contains(&format!("error [{code}]: ")),
        "{case}: expected code {code}:\n{err}"
    );
    for n in needles {
        assert!(err.contains(n), "{case}: message lacks {n:?}:\n{err}");
    }
    assert!(
        err.contains(&format!("{case}.toml")),
        "{case}: message does not name the file:\n{err}"
    );
    assert!(out.stdout.is_empty(), "{case}: printed on stdout");
}

const AXIS: &str = "[[axes]]\nname = \"X\"\n";

#[test]
fn the_documented_example_is_valid() {
    let out = check(&repo().join("deploy/cncd.toml"));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        text.contains("configuration is valid: axes XYZ, bus can on can0, API on 127.0.0.1:50051"),
        "{text}"
    );
}

#[test]
fn an_empty_file_is_the_simulated_mill() {
    let out = check_text("empty", "");
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("axes XYZ, bus sim"), "{text}");
}

#[test]
fn a_missing_file_or_no_file_is_refused() {
    let out = check(Path::new("/nonexistent/cncd.toml"));
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("error [config_read]: "), "{err}");
    assert!(err.contains("cannot read /nonexistent/cncd.toml"), "{err}");

    let out = Command::new(cncd()).arg("--check-config").output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--check-config --config FILE"), "{err}");
}

#[test]
fn syntax_error_gives_line_and_column() {
    assert_refused(
        "syntax",
        "[[axes]]\nname = \"X\"\nmax_accel_mm_s2 = 800 800\n",
        "config_parse",
        &["line 3", "column"],
    );
    assert_refused(
        "unclosed",
        "[rt\npriority = 80\n",
        "config_parse",
        &["line 1"],
    );
}

#[test]
fn unknown_key_is_named() {
    assert_refused(
        "unknown-rt",
        "[rt]\nprio = 80\n",
        "config_parse",
        &["prio", "priority"],
    );
    assert_refused(
        "unknown-axis",
        &format!("{AXIS}max_accel = 800\n"),
        "config_parse",
        &["max_accel", "max_accel_mm_s2"],
    );
    assert_refused(
        "unknown-section",
        "[rtt]\npriority = 80\n",
        "config_parse",
        &["rtt"],
    );
}

#[test]
fn wrong_type_is_named() {
    assert_refused(
        "type-accel",
        &format!("{AXIS}max_accel_mm_s2 = \"fast\"\n"),
        "config_parse",
        &["max_accel_mm_s2", "invalid type"],
    );
    assert_refused(
        "type-listen",
        "[api]\nlisten = 5\n",
        "config_parse",
        &["listen"],
    );
    assert_refused(
        "type-lock",
        "[rt]\nlock_memory = \"yes\"\n",
        "config_parse",
        &["lock_memory", "invalid type"],
    );
    assert_refused(
        "type-name",
        "[[axes]]\nname = \"XY\"\n",
        "config_parse",
        &["name", "invalid"],
    );
}

#[test]
fn out_of_range_value_is_named() {
    assert_refused(
        "range-accel",
        &format!("{AXIS}[[axes]]\nname = \"Y\"\nmax_accel_mm_s2 = -5\n"),
        "config_bad_value",
        &["axes[1].max_accel_mm_s2: -5 must be a positive number"],
    );
    assert_refused(
        "range-velocity",
        &format!("{AXIS}max_velocity_mm_min = nan\n"),
        "config_bad_value",
        &["axes[0].max_velocity_mm_min"],
    );
    assert_refused(
        "range-priority",
        "[rt]\npriority = 120\n",
        "config_bad_value",
        &["rt.priority: 120 is outside 1..99"],
    );
    assert_refused(
        "range-axes",
        &"[[axes]]\nname = \"A\"\n".repeat(7),
        "config_bad_value",
        &["axes:"],
    );
    assert_refused(
        "range-letter",
        "[[axes]]\nname = \"x\"\n",
        "config_bad_value",
        &["axes[0].name"],
    );
    assert_refused(
        "program-dialect",
        "[program]\ndialect = \"fanuc\"\n",
        "config_bad_value",
        &["program.dialect: \"fanuc\" is not a program language cncd reads: \"cnc836\" or \"iso\""],
    );
}

#[test]
fn duplicate_axis_is_named() {
    assert_refused(
        "duplicate-axis",
        "[[axes]]\nname = \"X\"\n[[axes]]\nname = \"Y\"\n[[axes]]\nname = \"X\"\n",
        "config_duplicate",
        &["axes[2].name: axis X appears twice"],
    );
}

#[test]
fn bad_bus_settings_are_named() {
    let can = "[bus]\nkind = \"can\"\ninterface = \"can0\"\n";
    assert_refused(
        "bus-kind",
        "[bus]\nkind = \"usb\"\n",
        "config_parse",
        &["usb"],
    );
    assert_refused(
        "bus-no-interface",
        "[bus]\nkind = \"can\"\n",
        "config_parse",
        &["interface"],
    );
    assert_refused(
        "bus-no-node",
        &format!("{AXIS}{can}"),
        "config_missing",
        &["axes[0].node_id"],
    );
    assert_refused(
        "bus-node-twice",
        &format!("{AXIS}node_id = 4\n[[axes]]\nname = \"Y\"\nnode_id = 4\n{can}"),
        "config_duplicate",
        &["axes[1].node_id: node 4 is used twice"],
    );
    assert_refused(
        "bus-node-range",
        &format!("{AXIS}node_id = 127\n{can}"),
        "config_duplicate",
        &["axes[0].node_id"],
    );
    assert_refused(
        "bus-window",
        &format!("{can}following_window_mm = -1\n"),
        "config_bad_value",
        &["bus.following_window_mm"],
    );
    assert_refused(
        "bus-unknown-key",
        &format!("{can}bitrate = 1000000\n"),
        "config_parse",
        &["bitrate"],
    );
    assert_refused(
        "bus-serial-port",
        "[bus]\nkind = \"serial\"\nport = \"\"\n",
        "config_missing",
        &["bus.port"],
    );
}

#[test]
fn bad_paths_are_named() {
    assert_refused(
        "path-dir",
        "[storage]\ndir = \"\"\n",
        "config_missing",
        &["storage.dir"],
    );
    assert_refused(
        "path-offsets",
        "[storage]\noffsets_file = \"\"\n",
        "config_missing",
        &["storage.offsets_file", "must name a file"],
    );
    assert_refused(
        "path-dotdot",
        "[storage]\nconstants_file = \"data/..\"\n",
        "config_missing",
        &["storage.constants_file", "must name a file"],
    );
    assert_refused(
        "path-same",
        "[storage]\noffsets_file = \"TAB0.KOR\"\nconstants_file = \"TAB0.KOR\"\n",
        "config_duplicate",
        &["storage.constants_file: the same file as storage.offsets_file"],
    );
    assert_refused(
        "path-type",
        "[storage]\ndir = 5\n",
        "config_parse",
        &["dir", "invalid type"],
    );
}

#[test]
fn bad_simulation_and_api_settings_are_named() {
    assert_refused(
        "sim-kv",
        "[sim]\nkv_per_s = 0\n",
        "config_bad_value",
        &["sim.kv_per_s: 0 must be a positive number"],
    );
    assert_refused(
        "home-nan",
        &format!("{AXIS}home_mm = nan\n"),
        "config_bad_value",
        &["axes[0].home_mm"],
    );
    assert_refused(
        "api-remote-no-tls",
        "[api]\nlisten = \"0.0.0.0:50051\"\n",
        "config_missing",
        &["api.tls_cert", "requires TLS"],
    );
    assert_refused(
        "api-token-hash",
        "[[api.tokens]]\nname = \"hmi\"\nrole = \"operator\"\nsha256 = \"abc\"\n",
        "config_bad_value",
        &["api.tokens[0].sha256"],
    );
    assert_refused(
        "api-role",
        "[api]\nlocal_role = \"root\"\n",
        "config_parse",
        &["root", "local_role"],
    );
}

#[test]
fn tls_files_are_loaded_by_the_check() {
    // Files that do not exist, and a file that is not PEM, fail the check (not the next start).
    assert_refused(
        "tls-missing",
        "[api]\ntls_cert = \"/nonexistent/cert.pem\"\ntls_key = \"/nonexistent/key.pem\"\n",
        "api_tls_file",
        &["api.tls_cert", "/nonexistent/cert.pem"],
    );
    let junk = std::env::temp_dir().join(format!("cncd-check-junk-{}.pem", std::process::id()));
    std::fs::write(&junk, "not a certificate\n").unwrap();
    assert_refused(
        "tls-junk",
        &format!("[api]\ntls_cert = {junk:?}\ntls_key = {junk:?}\n"),
        "api_tls",
        &["api.tls_cert"],
    );
    let _ = std::fs::remove_file(&junk);
}

#[test]
fn the_daemon_refuses_a_bad_file_with_status_2_too() {
    // Not only --check-config: starting on a bad file exits 2, which the unit does not restart
    // (RestartPreventExitStatus=2).
    let dir = std::env::temp_dir().join(format!("cncd-check-run-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("bad.toml");
    std::fs::write(&path, "[rt]\npriority = 0\n").unwrap();
    let out = Command::new(cncd())
        .arg("--config")
        .arg(&path)
        .args(["--log", "stderr"])
        .current_dir(&dir)
        .output()
        .unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("error [config_bad_value]: "), "{err}");
    assert!(err.contains("rt.priority: 0 is outside 1..99"), "{err}");
    assert_eq!(err.matches("rt.priority").count(), 1, "said twice:\n{err}");
}

/// `[bus] cycle_ms` (issue #23): whole milliseconds from 1 to 10, on every bus kind; the
/// serial protocol's 4 ms only.
#[test]
fn bus_cycle_outside_1_to_10_ms_or_fractional_is_refused() {
    for (case, v) in [("cycle-0", "0"), ("cycle-11", "11"), ("cycle-3.5", "3.5")] {
        assert_refused(
            case,
            &format!("[bus]\nkind = \"sim\"\ncycle_ms = {v}\n"),
            "config_bad_value",
            &[
                "bus.cycle_ms",
                v,
                "whole number of milliseconds from 1 to 10",
            ],
        );
        assert_refused(
            &format!("{case}-can"),
            &format!(
                "{AXIS}node_id = 1\n[bus]\nkind = \"can\"\ninterface = \"can0\"\ncycle_ms = {v}\n"
            ),
            "config_bad_value",
            &["bus.cycle_ms", v],
        );
    }
    assert_refused(
        "cycle-serial",
        "[bus]\nkind = \"serial\"\nport = \"/dev/ttyUSB0\"\ncycle_ms = 2\n",
        "config_bad_value",
        &["bus.cycle_ms", "serial protocol's cycle is 4 ms"],
    );
    for ms in [1, 2, 5, 10] {
        let out = check_text(
            &format!("cycle-ok-{ms}"),
            &format!("[bus]\nkind = \"sim\"\ncycle_ms = {ms}\n"),
        );
        assert!(
            out.status.success(),
            "{ms} ms: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

/// `[io]` (issue #46, docs/io.md): each mistake refused with its key.
#[test]
fn io_mistakes_are_refused_with_the_key() {
    let can = "[bus]\nkind = \"can\"\ninterface = \"vcan0\"\n";
    let estop = |node: u8, bit: u8| {
        format!(
            "[[io.inputs]]\nname = \"e{node}_{bit}\"\nnode_id = {node}\nbit = {bit}\nfunction = \"estop\"\n"
        )
    };
    // The configuration is accepted as written.
    let ok = format!(
        "{can}{}[[io.outputs]]\nname = \"coolant\"\nnode_id = 10\nbit = 0\non = [\"M8\"]\noff = [\"M9\"]\n",
        estop(10, 0)
    );
    let out = check_text("io_ok", &ok);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // One input, one function: the same point twice.
    let twice = format!(
        "{can}{}[[io.inputs]]\nname = \"door\"\nnode_id = 10\nbit = 0\nfunction = \"door\"\n",
        estop(10, 0)
    );
    assert_refused(
        "io_input_twice",
        &twice,
        "config_duplicate",
        &["io.inputs[1]"],
    );
    // One output bound twice.
    let out_twice = format!(
        "{can}[[io.outputs]]\nname = \"a\"\nnode_id = 10\nbit = 1\n\
         [[io.outputs]]\nname = \"b\"\nnode_id = 10\nbit = 1\n"
    );
    assert_refused(
        "io_output_twice",
        &out_twice,
        "config_duplicate",
        &["io.outputs[1]"],
    );
    // A node that is a drive's (unknown as a module), a module on a sim bus.
    assert_refused(
        "io_drive_node",
        &format!("{can}{}", estop(1, 0)),
        "config_duplicate",
        &["io.inputs[0].node_id", "axis X"],
    );
    assert_refused(
        "io_sim_node",
        &estop(10, 0),
        "config_bad_value",
        &["io.inputs[0].node_id"],
    );
    // A bit outside the module, or outside any module.
    let small = format!(
        "{can}{}[[io.modules]]\nnode_id = 10\ninput_bits = 8\n",
        estop(10, 8)
    );
    assert_refused(
        "io_bit_module",
        &small,
        "config_bad_value",
        &["io.inputs[0].bit", "module 10"],
    );
    assert_refused(
        "io_bit_64",
        &format!("{can}{}", estop(10, 64)),
        "config_bad_value",
        &["io.inputs[0].bit"],
    );
    // An M function the controller uses itself.
    let m5 = format!("{can}[[io.outputs]]\nname = \"x\"\nnode_id = 10\nbit = 0\non = [\"M5\"]\n");
    assert_refused(
        "io_m5",
        &m5,
        "config_bad_value",
        &["io.outputs[0].on[0]", "M5"],
    );
    // An unknown key is named by serde.
    let typo = "[[io.inputs]]\nname = \"e\"\nfuntion = \"estop\"\n";
    assert_refused("io_typo", typo, "config_parse", &["funtion"]);
}
