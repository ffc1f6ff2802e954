//! Issue #31, "files on disk are the truth" (SPEC §3: the memory copy is loaded from the file at
//! power-on and after every saved edit), through `cncd` and `cncctl` as an operator uses them:
//! TAB0.KOR and TAB0.REK edited by hand while cncd runs.

mod operator_support;

use operator_support::*;

/// The memory table as `cncctl --json offsets` shows it: (entry, radius).
fn memory_radii(d: &Cncd) -> Vec<(u64, f64)> {
    let (ok, out) = d.cncctl(&["--json", "offsets"]);
    assert!(ok, "{out}");
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    v["entries"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| {
            (
                e["entry"].as_u64().unwrap(),
                e["radius_mm"].as_f64().unwrap(),
            )
        })
        .collect()
}

/// The file as `cncctl --json offsets-file` shows it, byte for byte.
fn file_text(d: &Cncd) -> String {
    let (ok, out) = d.cncctl(&["--json", "offsets-file"]);
    assert!(ok, "{out}");
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    v["text"].as_str().unwrap().to_string()
}

/// Active alarms of `source` in `cncctl --json status`.
fn alarms_of(d: &Cncd, source: &str) -> Vec<String> {
    let (ok, out) = d.cncctl(&["--json", "status"]);
    assert!(ok, "{out}");
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    v["active_alarms"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|a| a["source"] == source)
        .map(|a| a["message"].as_str().unwrap().to_string())
        .collect()
}

/// Seen 1: a hand edit of TAB0.KOR was neither loaded nor kept; `offset-set` rewrote the file
/// from memory and lost entry 09, R=7 and the comment.
#[test]
fn hand_edits_of_the_offset_table_are_loaded_and_kept() {
    let cwd = temp_dir("kor");
    let d = Cncd::start(&cwd, MILL_TOML);
    let kor = d.data.join("TAB0.KOR");
    let (ok, out) = d.cncctl(&["offset-set", "1", "--radius", "5"]);
    assert!(ok, "{out}");

    // Saved by an editor that writes a new file and renames it (vim, most GUI editors).
    let hand = "my comment\n$KOR\n01: R=7 Z=-2\n09: R=9\n";
    save_by_rename(&kor, hand);
    wait_for("the hand edit loaded into memory", || {
        memory_radii(&d) == [(1, 7.0), (9, 9.0)]
    });
    assert_eq!(file_text(&d), hand, "offsets-file shows the file");

    // An API edit of one entry keeps every other byte.
    let (ok, out) = d.cncctl(&["offset-set", "3", "--radius", "2"]);
    assert!(ok, "{out}");
    let want = "my comment\n$KOR\n01: R=7 Z=-2\n03: R=2.0\n09: R=9\n";
    assert_eq!(std::fs::read_to_string(&kor).unwrap(), want);
    assert_eq!(memory_radii(&d), [(1, 7.0), (3, 2.0), (9, 9.0)]);

    // Saved in place and edited over the API at once (before any watch could see it): the
    // edit is made on top of the newer file, never over it.
    let hand = format!("{want}11: R=1   ; new tool\n");
    std::fs::write(&kor, &hand).unwrap();
    let (ok, out) = d.cncctl(&["offset-set", "9", "--radius", "4"]);
    assert!(ok, "{out}");
    assert_eq!(
        std::fs::read_to_string(&kor).unwrap(),
        "my comment\n$KOR\n01: R=7 Z=-2\n03: R=2.0\n09: R=4.0\n11: R=1   ; new tool\n"
    );
    assert_eq!(memory_radii(&d), [(1, 7.0), (3, 2.0), (9, 4.0), (11, 1.0)]);

    // A bad edit: refused with file, line and code; memory kept; an alarm says so; the API
    // does not write over it.
    let bad = "my comment\n$KOR\n01: R=abc\n";
    save_by_rename(&kor, bad);
    wait_for("the offsets_file alarm", || {
        !alarms_of(&d, "offsets_file").is_empty()
    });
    let alarm = alarms_of(&d, "offsets_file").remove(0);
    assert!(
        alarm.contains("TAB0.KOR")
            && alarm.contains("line 3")
            && alarm.contains("offset_value_syntax"),
        "{alarm}"
    );
    assert_eq!(memory_radii(&d), [(1, 7.0), (3, 2.0), (9, 4.0), (11, 1.0)]);
    let (ok, out) = d.cncctl(&["offset-set", "5", "--radius", "1"]);
    assert!(!ok && out.contains("storage_file_invalid"), "{out}");
    assert_eq!(
        std::fs::read_to_string(&kor).unwrap(),
        bad,
        "never overwritten"
    );
    assert_eq!(file_text(&d), bad, "offsets-file shows the file as it is");
    let (ok, out) = d.cncctl(&["alarms"]);
    assert!(ok && out.contains("offsets_file"), "{out}");

    // Fixed by hand: loaded, the alarm cleared.
    save_by_rename(&kor, "$KOR\n01: R=3\n");
    wait_for("the fixed file loaded", || memory_radii(&d) == [(1, 3.0)]);
    wait_for("the alarm cleared", || {
        alarms_of(&d, "offsets_file").is_empty()
    });
}

/// The value of constant `r` as `cncctl --json constants get` shows it.
fn constant_text(d: &Cncd, r: &str) -> String {
    let (ok, out) = d.cncctl(&["--json", "constants", "get", r]);
    assert!(ok, "{out}");
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    v[0]["text"].as_str().unwrap().to_string()
}

/// Seen 1 for TAB0.REK: `R039=00045.000` written by hand, then `constants set R52=600`
/// dropped it.
#[test]
fn hand_edits_of_the_constants_file_are_loaded_and_kept() {
    let cwd = temp_dir("rek");
    let d = Cncd::start(&cwd, MILL_TOML);
    let rek = d.data.join("TAB0.REK");
    let (ok, out) = d.cncctl(&["constants", "set", "R52=500"]);
    assert!(ok, "{out}");
    let mut text = std::fs::read_to_string(&rek).unwrap();
    text.push_str("; set by hand\nR039=00045.000\n");
    std::fs::write(&rek, &text).unwrap();
    wait_for("R39 loaded", || constant_text(&d, "39") == "00045.000");

    let (ok, out) = d.cncctl(&["constants", "set", "R52=600"]);
    assert!(ok, "{out}");
    let after = std::fs::read_to_string(&rek).unwrap();
    assert_eq!(after, text.replace("R052=00500.000", "R052=00600.000"));
    assert_eq!(constant_text(&d, "R39"), "00045.000");
    assert_eq!(constant_text(&d, "52"), "00600.000");

    // A bad edit keeps the constants in force, raises an alarm and refuses API edits.
    let bad = format!("{after}R052=12x\n");
    save_by_rename(&rek, &bad);
    wait_for("the constants_file alarm", || {
        !alarms_of(&d, "constants_file").is_empty()
    });
    let alarm = alarms_of(&d, "constants_file").remove(0);
    assert!(
        alarm.contains("TAB0.REK") && alarm.contains("constant_"),
        "{alarm}"
    );
    assert_eq!(constant_text(&d, "52"), "00600.000");
    let (ok, out) = d.cncctl(&["constants", "set", "R52=700"]);
    assert!(!ok && out.contains("storage_file_invalid"), "{out}");
    assert_eq!(std::fs::read_to_string(&rek).unwrap(), bad);
    save_by_rename(&rek, &after);
    wait_for("the alarm cleared", || {
        alarms_of(&d, "constants_file").is_empty()
    });
}

/// `cncctl offsets-replace` sends the revision it is based on: the one given with
/// `--revision` (as `--json offsets-file` showed it) or the one on disk when it starts. A hand
/// edit saved since the revision was read is refused with `storage_file_changed` and kept.
#[test]
fn offsets_replace_never_overwrites_an_edit_it_has_not_seen() {
    let cwd = temp_dir("replace_rev");
    let d = Cncd::start(&cwd, MILL_TOML);
    std::fs::write(cwd.join("first.kor"), "$KOR\n01: R=3\n").unwrap();
    let (ok, out) = d.cncctl(&["offsets-replace", "first.kor"]);
    assert!(ok, "{out}");
    let (ok, out) = d.cncctl(&["--json", "offsets-file"]);
    assert!(ok, "{out}");
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    let seen = v["revision"].as_str().unwrap().to_string();
    assert_eq!(seen.len(), 16, "{v}");
    // Someone saves a hand edit after the HMI (or the operator) read the file.
    let hand = "by hand\n$KOR\n01: R=7\n";
    std::fs::write(d.data.join("TAB0.KOR"), hand).unwrap();
    std::fs::write(cwd.join("new.kor"), "$KOR\n02: R=1\n").unwrap();
    let (ok, out) = d.cncctl(&["offsets-replace", "new.kor", "--revision", &seen]);
    assert!(!ok && out.contains("storage_file_changed"), "{out}");
    assert_eq!(
        std::fs::read_to_string(d.data.join("TAB0.KOR")).unwrap(),
        hand
    );
    // Without --revision: based on the file as it is now, so it replaces it.
    let (ok, out) = d.cncctl(&["offsets-replace", "new.kor"]);
    assert!(ok, "{out}");
    assert_eq!(
        std::fs::read_to_string(d.data.join("TAB0.KOR")).unwrap(),
        "$KOR\n02: R=1\n"
    );
}
