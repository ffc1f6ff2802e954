//! Issue #31 (Seen 5 and 7) through `cncd` and `cncctl` as a person or a script uses them:
//! `status --watch` into pipes and files, `constants get R384`, local ISO times, the alarm
//! history across a restart, a job interrupted by SIGKILL, library revisions.

mod operator_support;

use std::process::{Command, Stdio};

use operator_support::*;

/// Runs `line` with `sh -c` in the daemon's directory, `cncctl` on the PATH: status, stdout,
/// stderr.
fn sh(d: &Cncd, line: &str) -> (bool, String, String) {
    let bin_dir = bin("cncctl").parent().unwrap().to_owned();
    let path = format!(
        "{}:{}",
        bin_dir.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let out = Command::new("sh")
        .args(["-c", line])
        .current_dir(&d.cwd)
        .env("PATH", path)
        .env("CNCD_RUNTIME_DIR", &d.runtime)
        .env_remove("CNCCTL_ADDR")
        .stdin(Stdio::null())
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn is_local_iso_time(s: &str) -> bool {
    // 2026-11-27T14:05:09+01:00
    let b = s.as_bytes();
    s.len() >= 25
        && b[4] == b'-'
        && b[7] == b'-'
        && b[10] == b'T'
        && b[13] == b':'
        && b[16] == b':'
        && matches!(b[19], b'+' | b'-')
}

#[test]
fn status_watch_feeds_pipes_and_files_and_ends_quietly() {
    let cwd = temp_dir("watch");
    let d = Cncd::start(&cwd, MILL_TOML);
    // A closed pipe ends cncctl quietly, with status 0 (pipefail sees cncctl's own status).
    let (ok, out, err) = sh(
        &d,
        "{ cncctl --json status --watch; echo \"cncctl exit $?\" >&2; } | head -1",
    );
    assert!(ok, "{out} {err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.contains("cncctl exit 0"), "{err}");
    let v: serde_json::Value = serde_json::from_str(out.trim()).expect("one JSON object");
    assert_eq!(v["state"], "idle");
    // Into a file: a line per update.
    let (ok, _, err) = sh(
        &d,
        // The file exists before cncctl starts, so the loop never reads a missing file
        // (a killed-too-early cncctl used to leave none); bounded to 60 s.
        ": > watch.txt; cncctl status --watch --rate 50 >> watch.txt & pid=$!; n=0; \
         while [ \"$(wc -l < watch.txt)\" -lt 3 ] && [ $n -lt 600 ]; do sleep 0.1; n=$((n+1)); done; \
         kill $pid",
    );
    assert!(ok, "{err}");
    let text = std::fs::read_to_string(cwd.join("watch.txt")).unwrap();
    assert!(
        text.lines().count() >= 3 && text.starts_with("idle"),
        "{text}"
    );
    // R384 and 384 are the same constant.
    let (ok1, a) = d.cncctl(&["constants", "get", "R384"]);
    let (ok2, b) = d.cncctl(&["constants", "get", "384"]);
    assert!(ok1 && ok2 && a == b && a.contains("R384"), "{a}\n{b}");
}

#[test]
fn library_revision_is_what_runs() {
    let cwd = temp_dir("library");
    let d = Cncd::start(&cwd, MILL_TOML);
    std::fs::write(cwd.join("part.nc"), "N10 G1 X1 F1000\n").unwrap();
    std::fs::write(cwd.join("other.nc"), "N10 G1 X2 F1000\n").unwrap();
    let (ok, out) = d.cncctl(&["load", "part.nc"]);
    assert!(ok, "{out}");
    // A new text under the selected name without selecting it: refused with a code.
    let (ok, out) = d.cncctl(&["upload", "other.nc", "--name", "part.nc"]);
    assert!(!ok && out.contains("program_selected"), "{out}");
    let (ok, out) = d.cncctl(&["--json", "programs"]);
    assert!(ok, "{out}");
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    let rev = v["programs"][0]["revision"].as_str().unwrap().to_string();
    assert_eq!(rev.len(), 16, "{v}");
    assert_eq!(v["selected_revision"], rev.as_str());
    // Loading the new text selects it: the listing and the next start agree.
    let (ok, out) = d.cncctl(&["load", "other.nc"]);
    assert!(ok, "{out}");
    let (ok, out) = d.cncctl(&["upload", "other.nc", "--name", "part.nc"]);
    assert!(ok, "another name may be replaced: {out}");
    let (ok, out) = d.cncctl(&["--json", "programs"]);
    assert!(ok);
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    let revs: Vec<&str> = v["programs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["revision"].as_str().unwrap())
        .collect();
    assert_eq!(revs[0], revs[1], "same text, same revision: {v}");
    let (ok, out) = d.cncctl(&["programs"]);
    assert!(ok && out.contains(&format!("rev {}", revs[0])), "{out}");
    let stored = out.lines().nth(1).unwrap_or_default().to_string();
    let when = stored.split("stored ").nth(1).unwrap_or_default();
    assert!(is_local_iso_time(when), "{stored}");
    // Loading (selecting) another program while one runs: refused with the same code.
    std::fs::write(
        cwd.join("long.nc"),
        "N10 G1 X200 F300
N20 X0
",
    )
    .unwrap();
    let (ok, out) = d.cncctl(&["load", "long.nc"]);
    assert!(ok, "{out}");
    let (ok, out) = d.cncctl(&["start"]);
    assert!(ok, "{out}");
    let (ok, out) = d.cncctl(&["load", "part.nc"]);
    assert!(!ok && out.contains("program_selected"), "{out}");
    let (ok, out) = d.cncctl(&["stop"]);
    assert!(ok, "{out}");
}

#[test]
fn a_killed_job_is_recorded_and_the_alarm_history_survives_a_restart() {
    let cwd = temp_dir("killed");
    let mut d = Cncd::start(&cwd, MILL_TOML);
    // An alarm for the history: a bad hand edit of TAB0.KOR, then fixed.
    std::fs::write(d.data.join("TAB0.KOR"), "$KOR\n01: R=x\n").unwrap();
    wait_for("the offsets_file alarm", || {
        let (_, out) = d.cncctl(&["alarms"]);
        out.contains("RAISED") && out.contains("offsets_file")
    });
    std::fs::write(d.data.join("TAB0.KOR"), "$KOR\n").unwrap();
    wait_for("the alarm cleared", || {
        let (_, out) = d.cncctl(&["alarms"]);
        out.contains("cleared") && out.contains("offsets_file")
    });
    // A long program, killed mid-way.
    std::fs::write(
        cwd.join("long.nc"),
        "N10 G1 X1 F600\nN20 G1 X200 F300\nN30 G1 X0\n",
    )
    .unwrap();
    let (ok, out) = d.cncctl(&["load", "long.nc"]);
    assert!(ok, "{out}");
    let (ok, out) = d.cncctl(&["start"]);
    assert!(ok, "{out}");
    wait_for("block N20 recorded", || {
        std::fs::read_to_string(d.data.join("job.running"))
            .is_ok_and(|t| t.contains("\"block\":20"))
    });
    d.kill9();
    let d = Cncd::spawn(&cwd, &["--config", "cncd.toml"], &cwd.join("data"));
    let (ok, out) = d.cncctl(&["alarms"]);
    assert!(ok, "{out}");
    let line = out
        .lines()
        .find(|l| l.contains("interrupted_job"))
        .unwrap_or_else(|| panic!("no interrupted job in\n{out}\n{}", d.log()));
    assert!(line.contains("long.nc") && line.contains("N20"), "{line}");
    assert!(is_local_iso_time(line), "{line}");
    assert!(
        out.contains("offsets_file"),
        "history kept over the restart:\n{out}"
    );
    let (ok, out) = d.cncctl(&["--json", "status"]);
    assert!(
        ok && out.contains("interrupted_job"),
        "active until the next job: {out}"
    );
}
