//! Golden corpus of the CNC836 dialect (kernel/tests/data/cnc836, format in its README): every
//! program's dry-run moves, messages and streamed blocks must stay what the expected files say.
//! `REGENERATE=1` rewrites the expected files instead (scripts/cnc836-corpus/regenerate).

use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

use kernel::block::{Block, BlockKind, Path as MovePath};
use kernel::constants::Constants;
use kernel::kr::Gear;
use kernel::offsets;
use kernel::program::{IjMode, Setup, dry_run, stream};
use kernel::{Diagnostic, Severity};

fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/cnc836")
}

/// `setups.txt`: program name → (base, options).
fn manifest() -> Vec<(String, String, Vec<String>)> {
    let text = fs::read_to_string(data_dir().join("setups.txt")).unwrap();
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let mut f = l.split_whitespace().map(str::to_string);
            let name = f.next().unwrap();
            let base = f.next().expect("a base after the program name");
            (name, base, f.collect())
        })
        .collect()
}

/// The base `corpus`: the machine of kernel/tests/lang_corpus.rs with the program's own
/// `; SETUP lathe`, `; CONST`, `; IJ absolute` and `; OFFSET` lines.
fn corpus_setup(text: &str) -> Setup {
    let mut setup = Setup::new(&['X', 'Y', 'Z', 'U']);
    let mut consts = Vec::new();
    let mut offs = Vec::new();
    for line in text.lines() {
        let Some(d) = line.strip_prefix("; ") else {
            continue;
        };
        if d == "SETUP lathe" {
            setup.axis_names = vec!['X', 'Z'];
        } else if let Some(c) = d.strip_prefix("CONST ") {
            consts.push(c.to_string());
        } else if d == "IJ absolute" {
            setup.ij = IjMode::Absolute;
        } else if let Some(o) = d.strip_prefix("OFFSET ") {
            offs.push(o.to_string());
        }
    }
    setup.constants = Constants::parse(&consts.join("\n")).unwrap();
    let mut table = format!("$KOR\n01: R=5.0\n{}", offs.join("\n"));
    if offs.iter().any(|o| o.starts_with("01:")) {
        table = format!("$KOR\n{}", offs.join("\n"));
    }
    setup.offsets = offsets::parse(&table, &setup.axis_names).unwrap().table;
    setup
}

/// The simulated lathe of programs/lathe (cncd-lathe.toml and TAB0.REK).
fn lathe_diameter() -> Setup {
    let mut s = Setup::new(&['X', 'Z']);
    s.constants =
        Constants::parse("R000=00001.000\nR001=00003.000\nR067=00001.000\nR329=00000.300").unwrap();
    s.diameter_axis = Some(0);
    s.gears = [(250.0, 41), (500.0, 42), (1000.0, 43), (2000.0, 44)]
        .iter()
        .map(|&(max_rpm, m)| Gear {
            max_rpm,
            output_range: 0x7FFF,
            m_code: Some(m),
        })
        .collect();
    s.max_feed_mm_min = 10_000.0;
    s
}

fn setup_of(text: &str, base: &str, options: &[String]) -> Setup {
    let mut s = match base {
        "corpus" => corpus_setup(text),
        "mill3" => Setup::new(&['X', 'Y', 'Z']),
        "lathe-diameter" => lathe_diameter(),
        other => panic!("unknown base {other}"),
    };
    for o in options {
        let (key, value) = o.split_once('=').unwrap_or((o.as_str(), ""));
        match key {
            "start" => {
                for (k, v) in value.split(',').enumerate() {
                    s.start[k] = v.parse().unwrap();
                }
            }
            "axes" => s.axis_names = value.chars().collect(),
            "rotary" => {
                let (letter, kppr) = value.split_once(':').unwrap();
                let k = s
                    .axis_names
                    .iter()
                    .position(|a| a.to_string() == letter)
                    .unwrap();
                s.rotary_kpulses_per_rev[k] = kppr.parse().unwrap();
            }
            "block-delete" => s.block_delete = true,
            other => panic!("unknown option {other}"),
        }
    }
    s
}

fn diag_line(d: &Diagnostic) -> String {
    let sev = match d.severity {
        Severity::Info => "info",
        Severity::Warning => "warning",
        Severity::Error => "error",
    };
    let n = d.block.map_or("-".to_string(), |n| format!("N{n}"));
    format!("{sev} {} {}:{} {n}", d.code.as_str(), d.line, d.column)
}

fn axes(p: &kernel::AxesMm, n: usize) -> String {
    let v: Vec<String> = p.0[..n].iter().map(|x| format!("{x}")).collect();
    v.join(",")
}

/// One block on one line: everything later stages read, in a fixed order.
fn block_line(b: &Block, n_axes: usize) -> String {
    let kind = match b.kind {
        BlockKind::Motion { start, end, path } => {
            let path = match path {
                MovePath::Rapid => "rapid".to_string(),
                MovePath::Line => "line".to_string(),
                MovePath::Probe(mv) => format!("probe {mv:?}"),
                MovePath::Arc { dir, center, plane } => {
                    format!("arc {dir:?} {plane:?} c=({})", axes(&center, n_axes))
                }
            };
            format!(
                "{path} ({})->({})",
                axes(&start, n_axes),
                axes(&end, n_axes)
            )
        }
        BlockKind::Dwell { seconds } => format!("dwell {seconds}"),
        BlockKind::Technology => "technology".to_string(),
        BlockKind::TableWrite { entry, values } => format!("table D{entry} {values:?}"),
        BlockKind::ToolChange { tool } => format!("tool change T{tool}"),
    };
    let sp = &b.spindle;
    let n = b.n.map_or("-".to_string(), |n| format!("N{n}"));
    format!(
        "#{} L{} {n} {kind} | {:?} {:?} {:?} {:?} set{} | {:?} S{} css={} lim{} gear{} P{} len{} | m={:?}",
        b.seq,
        b.line,
        b.feed,
        b.plane,
        b.comp,
        b.continuity,
        b.dyn_set,
        sp.dir,
        sp.s,
        sp.css,
        sp.limit_rpm,
        sp.gear,
        sp.gear_max_rpm,
        sp.length_offset_mm,
        b.m
    )
}

/// What the expected file of `text` read on `setup` says.
fn render(text: &str, setup: &Setup) -> String {
    let mut out = String::from("== moves\n");
    let (moves, diags) = dry_run::moves(text, setup);
    for m in &moves {
        writeln!(out, "{}", m.json(&setup.axis_names)).unwrap();
    }
    out.push_str("== dry run diagnostics\n");
    for d in &diags {
        writeln!(out, "{}", diag_line(d)).unwrap();
    }
    out.push_str("== stream\n");
    let n_axes = setup.axis_names.len().min(kernel::MAX_AXES);
    let mut s = stream(text, setup);
    while let Some(item) = s.next() {
        for d in s.take_notes() {
            writeln!(out, "  {}", diag_line(&d)).unwrap();
        }
        match item {
            Ok(b) => writeln!(out, "{}", block_line(&b, n_axes)).unwrap(),
            Err(d) => writeln!(out, "! {}", diag_line(&d)).unwrap(),
        }
    }
    for d in s.take_notes() {
        writeln!(out, "  {}", diag_line(&d)).unwrap();
    }
    out
}

#[test]
fn cnc836_programs_behave_as_recorded() {
    let dir = data_dir();
    let regenerate = std::env::var("REGENERATE").is_ok_and(|v| v == "1");
    let listed = manifest();
    let mut programs: Vec<PathBuf> = fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "nc"))
        .collect();
    programs.sort();
    assert!(programs.len() >= 30, "{} programs", programs.len());
    for (name, _, _) in &listed {
        assert!(
            dir.join(name).exists(),
            "setups.txt lists {name}, not in the corpus"
        );
    }
    let mut failed = Vec::new();
    for p in &programs {
        let name = p.file_name().unwrap().to_string_lossy().to_string();
        let text = fs::read_to_string(p).unwrap();
        let (base, options) = listed
            .iter()
            .find(|(n, _, _)| *n == name)
            .map_or(("corpus", &[][..]), |(_, b, o)| (b.as_str(), o.as_slice()));
        let got = render(&text, &setup_of(&text, base, options));
        let expected_path = p.with_extension("expected");
        if regenerate {
            fs::write(&expected_path, &got).unwrap();
            continue;
        }
        let expected = fs::read_to_string(&expected_path)
            .unwrap_or_else(|_| panic!("{}: no expected file", expected_path.display()));
        if got != expected {
            let first = got
                .lines()
                .zip(expected.lines())
                .position(|(a, b)| a != b)
                .unwrap_or(got.lines().count().min(expected.lines().count()));
            failed.push(format!(
                "{name}: line {} of the expected file differs:\n  expected: {}\n  got:      {}",
                first + 1,
                expected.lines().nth(first).unwrap_or("<end>"),
                got.lines().nth(first).unwrap_or("<end>")
            ));
        }
    }
    assert!(
        failed.is_empty(),
        "{} of {} programs differ from their expected files \
         (an intended change: scripts/cnc836-corpus/regenerate):\n{}",
        failed.len(),
        programs.len(),
        failed.join("\n")
    );
}
