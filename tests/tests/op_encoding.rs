//! Issue #31 (Seen 8), legacy code pages through `cncd` and `cncctl`: with `[program]
//! encoding` set, a program saved by an original controller (Czech comments in windows-1250
//! or cp852) validates, uploads, lists and runs unchanged at every door; a non-ASCII byte
//! outside a comment is still refused with its code; the default (UTF-8) refuses such a file
//! with `text_not_utf8`.

mod operator_support;

use operator_support::*;

/// `N10 G1 X5 F3000 ; Hrubování čepu` / `N20 X10 ; Řez` / `N30 X0` with the letters given.
fn program(a_acute: u8, i_acute: u8, c_caron: u8, r_caron: u8) -> Vec<u8> {
    let mut p = b"N10 G1 X5 F3000 ; Hrubov".to_vec();
    p.extend([a_acute, b'n', i_acute, b' ', c_caron]);
    p.extend(b"epu\nN20 X10 ; ");
    p.push(r_caron);
    p.extend(b"ez\nN30 X0\n");
    p
}

fn runs_unchanged(encoding: &str, text: &[u8]) {
    let cwd = temp_dir(&format!("enc_{encoding}"));
    let toml = format!("{MILL_TOML}\n[program]\nencoding = \"{encoding}\"\n");
    let d = Cncd::start(&cwd, &toml);
    std::fs::write(cwd.join("OLD.NC"), text).unwrap();
    let (ok, out) = d.cncctl(&["validate", "OLD.NC"]);
    assert!(ok, "{encoding} validate: {out}");
    let (ok, out) = d.cncctl(&["upload", "OLD.NC"]);
    assert!(ok, "{encoding} upload: {out}");
    let (ok, out) = d.cncctl(&["--json", "programs"]);
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    assert!(
        ok && v["programs"][0]["blocks"] == 3,
        "{encoding} listing: {out}"
    );
    let (ok, out) = d.cncctl(&["run", "OLD.NC"]);
    assert!(ok, "{encoding} run: {out}\n{}", d.log());
    let (ok, out) = d.cncctl(&["--json", "status"]);
    let s: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    assert!(ok && s["finished_job"] == s["job"], "{s}");
    // Words stay ASCII: the same byte outside the comment is an error with its code.
    let mut bad = text.to_vec();
    let at = bad.iter().position(|&b| b == b'X').unwrap();
    bad.insert(at, text.iter().copied().find(|b| !b.is_ascii()).unwrap());
    std::fs::write(cwd.join("BAD.NC"), bad).unwrap();
    let (ok, out) = d.cncctl(&["validate", "BAD.NC"]);
    assert!(
        !ok && out.contains("unexpected_character"),
        "{encoding}: {out}"
    );
}

#[test]
fn a_windows_1250_program_runs_unchanged() {
    runs_unchanged("windows-1250", &program(0xE1, 0xED, 0xE8, 0xD8));
}

#[test]
fn a_cp852_program_runs_unchanged() {
    runs_unchanged("cp852", &program(0xA0, 0xA1, 0x9F, 0xFC));
}

#[test]
fn utf8_by_default_refuses_a_legacy_file_with_its_code() {
    let cwd = temp_dir("enc_default");
    let d = Cncd::start(&cwd, MILL_TOML);
    std::fs::write(cwd.join("OLD.NC"), program(0xE1, 0xED, 0xE8, 0xD8)).unwrap();
    let (ok, out) = d.cncctl(&["validate", "OLD.NC"]);
    assert!(!ok && out.contains("text_not_utf8"), "{out}");
}
