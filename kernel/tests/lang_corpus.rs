//! Corpus of malformed programs and TAB0.KOR files with the messages they must produce, and of
//! good programs that must pass (kernel/tests/corpus, format in its README).

use std::fs;
use std::path::{Path, PathBuf};

use kernel::Diagnostic;
use kernel::offsets;
use kernel::program::{IjMode, Setup, compile};

fn corpus(dir: &str, ext: &str) -> Vec<PathBuf> {
    let d = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/corpus")
        .join(dir);
    let mut files: Vec<PathBuf> = fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == ext))
        .collect();
    files.sort();
    files
}

/// `EXPECT line:col message` → (line, col, message part).
fn expectation(rest: &str) -> (u32, u32, String) {
    let (pos, msg) = rest.split_once(' ').expect("EXPECT line:col message");
    let (l, c) = pos.split_once(':').expect("line:col");
    (
        l.parse().unwrap(),
        c.parse().unwrap(),
        msg.trim().to_string(),
    )
}

/// Directives in `; ` comment lines of a program: SETUP lathe, CONST Rn=v, IJ absolute,
/// OFFSET <TAB0.KOR entry line>, EXPECT line:col message.
fn program_setup(text: &str) -> (Setup, Vec<(u32, u32, String)>) {
    let mut setup = Setup::new(&['X', 'Y', 'Z', 'U']);
    let mut expect = Vec::new();
    let mut consts = Vec::new();
    let mut offs = Vec::new();
    for line in text.lines() {
        let Some(d) = line.strip_prefix("; ") else {
            continue;
        };
        if let Some(rest) = d.strip_prefix("EXPECT ") {
            expect.push(expectation(rest));
        } else if d == "SETUP lathe" {
            setup.axis_names = vec!['X', 'Z'];
        } else if let Some(c) = d.strip_prefix("CONST ") {
            consts.push(c.to_string());
        } else if d == "IJ absolute" {
            setup.ij = IjMode::Absolute;
        } else if let Some(o) = d.strip_prefix("OFFSET ") {
            offs.push(o.to_string());
        }
    }
    setup.constants = kernel::constants::Constants::parse(&consts.join("\n")).unwrap();
    // Entry 01 has a tool of radius 5 unless the file says otherwise.
    let mut table = format!("$KOR\n01: R=5.0\n{}", offs.join("\n"));
    if offs.iter().any(|o| o.starts_with("01:")) {
        table = format!("$KOR\n{}", offs.join("\n"));
    }
    setup.offsets = offsets::parse(&table, &setup.axis_names).unwrap().table;
    (setup, expect)
}

fn check(file: &Path, errors: &[Diagnostic], expect: &[(u32, u32, String)]) {
    if let Err(e) = std::panic::catch_unwind(|| check_inner(file, errors, expect)) {
        FAILS.with(|f| {
            f.borrow_mut()
                .push(e.downcast_ref::<String>().cloned().unwrap_or_default())
        });
    }
}

thread_local!(static FAILS: std::cell::RefCell<Vec<String>> = const { std::cell::RefCell::new(Vec::new()) });

fn fails() {
    let f = FAILS.with(|f| f.take());
    assert!(
        f.is_empty(),
        "{} corpus files failed:\n{}",
        f.len(),
        f.join("\n")
    );
}

fn check_inner(file: &Path, errors: &[Diagnostic], expect: &[(u32, u32, String)]) {
    let got: Vec<(u32, u32, &str)> = errors
        .iter()
        .map(|d| (d.line, d.column, d.message.as_str()))
        .collect();
    assert_eq!(
        got.len(),
        expect.len(),
        "{}: expected {expect:?}, got {got:#?}",
        file.display()
    );
    for (g, e) in got.iter().zip(expect) {
        assert!(
            g.0 == e.0 && g.1 == e.1 && g.2.contains(&e.2),
            "{}: expected {e:?}, got {g:?}",
            file.display()
        );
    }
}

#[test]
fn malformed_programs_give_the_expected_messages() {
    let files = corpus("programs", "nc");
    assert!(files.len() >= 40, "corpus has {} programs", files.len());
    for f in &files {
        let text = fs::read_to_string(f).unwrap();
        let (setup, expect) = program_setup(&text);
        assert!(!expect.is_empty(), "{}: no EXPECT", f.display());
        let c = compile(&text, &setup);
        let errors: Vec<Diagnostic> = c.diagnostics.into_iter().filter(|d| d.is_error()).collect();
        check(f, &errors, &expect);
        for e in &errors {
            assert!(e.line > 0 && e.column > 0, "{}: unlocated {e}", f.display());
        }
    }
    fails();
}

#[test]
fn good_programs_pass() {
    let files = corpus("good", "nc");
    assert!(files.len() >= 4);
    for f in &files {
        let text = fs::read_to_string(f).unwrap();
        let (setup, _) = program_setup(&text);
        let c = compile(&text, &setup);
        assert!(!c.has_errors(), "{}: {:#?}", f.display(), c.diagnostics);
        assert!(!c.blocks.is_empty());
    }
}

#[test]
fn malformed_offset_tables_give_the_expected_messages() {
    let files = corpus("kor", "kor");
    assert!(files.len() >= 15, "corpus has {} tables", files.len());
    for f in &files {
        let text = fs::read_to_string(f).unwrap();
        let mut axes = vec!['X', 'Y', 'Z'];
        let mut expect = Vec::new();
        for line in text.lines() {
            if let Some(rest) = line.strip_prefix("EXPECT ") {
                expect.push(expectation(rest));
            } else if line == "AXES XZ" {
                axes = vec!['X', 'Z'];
            }
        }
        let errors = offsets::parse(&text, &axes).expect_err(&f.display().to_string());
        check(f, &errors, &expect);
    }
    fails();
}
