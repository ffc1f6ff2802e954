//! The ISO dialect against LinuxCNC 2.9's own interpreter (kernel/tests/data/rs274, its
//! README; made by scripts/rs274-reference/make.sh from Debian's `rs274`, committed so this
//! test needs no LinuxCNC).
//!
//! Every `.ngc` there runs through the dry run with the reference's machine: axes X Y Z,
//! TAB0.KOR, the work offsets of work_offsets.txt (G54 in force), start at machine zero.
//! A program with a `<name>.jsonl` must give the same moves: kind by kind, end points and arc
//! centres within 1e-6 mm, plane and direction of arcs, feeds within 1e-6 relative, dwell
//! times. A program in refusals.txt must stop with its first error on the recorded line,
//! naming the recorded word, with code `iso_unsupported` unless the file gives another.
//!
//! One normalisation on both sides: a rapid or a feed move that ends where it starts is no
//! motion and is dropped (LinuxCNC's canned cycles, for one, position to where they already
//! are). Every program is reported, then the test fails if any differs.

use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

use kernel::block::{ArcDir, Plane};
use kernel::offsets::{self, WorkOffsets};
use kernel::program::dry_run::{Move, MoveKind, moves};
use kernel::program::{Dialect, Setup};
use kernel::{AxesMm, Diagnostic};

const AXES: [char; 3] = ['X', 'Y', 'Z'];
const POS_TOL_MM: f64 = 1e-6;
const FEED_TOL_REL: f64 = 1e-6;
const DWELL_TOL_S: f64 = 1e-9;
/// Below this a rapid or feed move has no length.
const ZERO_MOVE_MM: f64 = 1e-9;

fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/rs274")
}

/// A tiny JSON reader for the reference lines: objects, strings, numbers, true/false/null.
#[derive(Clone, Debug, PartialEq)]
enum Json {
    Null,
    Bool(bool),
    Num(f64),
    Str(String),
    Obj(Vec<(String, Json)>),
}

impl Json {
    fn get(&self, key: &str) -> Option<&Json> {
        match self {
            Json::Obj(kv) => kv.iter().find(|(k, _)| k == key).map(|(_, v)| v),
            _ => None,
        }
    }

    fn num(&self, key: &str) -> Option<f64> {
        match self.get(key) {
            Some(Json::Num(v)) => Some(*v),
            _ => None,
        }
    }

    fn str(&self, key: &str) -> Option<&str> {
        match self.get(key) {
            Some(Json::Str(s)) => Some(s),
            _ => None,
        }
    }
}

struct Reader<'a> {
    s: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn parse(text: &str) -> Result<Json, String> {
        let mut r = Reader {
            s: text.as_bytes(),
            at: 0,
        };
        let v = r.value()?;
        r.ws();
        if r.at != r.s.len() {
            return Err(format!("trailing text at byte {}", r.at));
        }
        Ok(v)
    }

    fn ws(&mut self) {
        while self.at < self.s.len() && self.s[self.at].is_ascii_whitespace() {
            self.at += 1;
        }
    }

    fn eat(&mut self, c: u8) -> Result<(), String> {
        self.ws();
        if self.s.get(self.at) == Some(&c) {
            self.at += 1;
            Ok(())
        } else {
            Err(format!("expected '{}' at byte {}", c as char, self.at))
        }
    }

    fn value(&mut self) -> Result<Json, String> {
        self.ws();
        match self.s.get(self.at) {
            Some(b'{') => self.object(),
            Some(b'"') => self.string().map(Json::Str),
            Some(b't') => self.word("true", Json::Bool(true)),
            Some(b'f') => self.word("false", Json::Bool(false)),
            Some(b'n') => self.word("null", Json::Null),
            Some(_) => self.number(),
            None => Err("unexpected end".into()),
        }
    }

    fn word(&mut self, w: &str, v: Json) -> Result<Json, String> {
        if self.s[self.at..].starts_with(w.as_bytes()) {
            self.at += w.len();
            Ok(v)
        } else {
            Err(format!("unexpected text at byte {}", self.at))
        }
    }

    fn number(&mut self) -> Result<Json, String> {
        let start = self.at;
        while self.at < self.s.len() && b"+-.eE0123456789".contains(&self.s[self.at]) {
            self.at += 1;
        }
        let t = std::str::from_utf8(&self.s[start..self.at]).unwrap();
        t.parse()
            .map(Json::Num)
            .map_err(|_| format!("bad number '{t}' at byte {start}"))
    }

    fn string(&mut self) -> Result<String, String> {
        self.eat(b'"')?;
        let mut out = String::new();
        loop {
            let Some(&c) = self.s.get(self.at) else {
                return Err("unterminated string".into());
            };
            self.at += 1;
            match c {
                b'"' => return Ok(out),
                b'\\' => {
                    let e = *self.s.get(self.at).ok_or("unterminated escape")?;
                    self.at += 1;
                    out.push(match e {
                        b'n' => '\n',
                        b't' => '\t',
                        other => other as char,
                    });
                }
                _ => {
                    // Multi-byte UTF-8 passes through byte by byte.
                    let len = match c {
                        0xf0.. => 4,
                        0xe0.. => 3,
                        0xc0.. => 2,
                        _ => 1,
                    };
                    let end = (self.at - 1 + len).min(self.s.len());
                    out.push_str(&String::from_utf8_lossy(&self.s[self.at - 1..end]));
                    self.at = end;
                }
            }
        }
    }

    fn object(&mut self) -> Result<Json, String> {
        self.eat(b'{')?;
        let mut kv = Vec::new();
        self.ws();
        if self.s.get(self.at) == Some(&b'}') {
            self.at += 1;
            return Ok(Json::Obj(kv));
        }
        loop {
            self.ws();
            let k = self.string()?;
            self.eat(b':')?;
            kv.push((k, self.value()?));
            self.ws();
            match self.s.get(self.at) {
                Some(b',') => self.at += 1,
                Some(b'}') => {
                    self.at += 1;
                    return Ok(Json::Obj(kv));
                }
                _ => return Err(format!("expected ',' or '}}' at byte {}", self.at)),
            }
        }
    }
}

/// One move of either side, in the reference's terms.
#[derive(Clone, Debug, PartialEq)]
struct M {
    kind: &'static str,
    end: [f64; 3],
    /// Arc: centre (the two plane axes meaningful), plane, direction.
    arc: Option<([f64; 3], &'static str, &'static str)>,
    feed_mm_min: Option<f64>,
    feed_mm_rev: Option<f64>,
    seconds: Option<f64>,
    /// Where it comes from: the N of rs274's listing, the source line of ours.
    at: String,
}

fn xyz(o: Option<&Json>) -> [f64; 3] {
    let mut p = [f64::NAN; 3];
    for (k, a) in AXES.iter().enumerate() {
        if let Some(v) = o.and_then(|o| o.num(&a.to_string())) {
            p[k] = v;
        }
    }
    p
}

fn plane_name(p: &str) -> &'static str {
    match p {
        "G17" => "G17",
        "G18" => "G18",
        "G19" => "G19",
        _ => "?",
    }
}

fn plane_axes(plane: &str) -> (usize, usize) {
    match plane {
        "G18" => Plane::G18.axes(),
        "G19" => Plane::G19.axes(),
        _ => Plane::G17.axes(),
    }
}

fn theirs(line: &str) -> Result<M, String> {
    let j = Reader::parse(line)?;
    let kind = match j.str("kind") {
        Some("rapid") => "rapid",
        Some("feed") => "feed",
        Some("arc") => "arc",
        Some("dwell") => "dwell",
        k => return Err(format!("unknown kind {k:?}")),
    };
    let arc = (kind == "arc").then(|| {
        let dir = if j.str("dir") == Some("ccw") {
            "ccw"
        } else {
            "cw"
        };
        (
            xyz(j.get("centre")),
            plane_name(j.str("plane").unwrap_or("")),
            dir,
        )
    });
    Ok(M {
        kind,
        end: xyz(j.get("end")),
        arc,
        feed_mm_min: j.num("feed_mm_min"),
        feed_mm_rev: j.num("feed_mm_rev"),
        seconds: j.num("seconds"),
        at: j
            .num("n")
            .map_or_else(|| "N-".to_string(), |n| format!("N{n}")),
    })
}

fn ours(m: &Move) -> M {
    let p = |a: &AxesMm| [a[0], a[1], a[2]];
    let (kind, arc, seconds) = match m.kind {
        MoveKind::Rapid => ("rapid", None, None),
        MoveKind::Feed => ("feed", None, None),
        MoveKind::Arc { centre, plane, dir } => {
            let plane = match plane {
                Plane::G17 => "G17",
                Plane::G18 => "G18",
                Plane::G19 => "G19",
            };
            let dir = if dir == ArcDir::Ccw { "ccw" } else { "cw" };
            ("arc", Some((p(&centre), plane, dir)), None)
        }
        MoveKind::Dwell { seconds } => ("dwell", None, Some(seconds)),
    };
    M {
        kind,
        end: p(&m.end),
        arc,
        feed_mm_min: m.feed_mm_min,
        feed_mm_rev: m.feed_mm_rev,
        seconds,
        at: format!("line {}", m.line),
    }
}

/// The moves without the rapids and feeds that end where they start (from machine zero).
fn without_null_moves(ms: Vec<M>) -> Vec<M> {
    let mut pos = [0.0; 3];
    let mut out = Vec::with_capacity(ms.len());
    for m in ms {
        if m.kind == "dwell" {
            out.push(m);
            continue;
        }
        let still = (0..3).all(|k| (m.end[k] - pos[k]).abs() < ZERO_MOVE_MM);
        pos = m.end;
        if still && matches!(m.kind, "rapid" | "feed") {
            continue;
        }
        out.push(m);
    }
    out
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

fn feeds_agree(a: Option<f64>, b: Option<f64>) -> bool {
    match (a, b) {
        (None, None) => true,
        (Some(a), Some(b)) => close(a, b, FEED_TOL_REL * a.abs().max(b.abs())),
        _ => false,
    }
}

/// Why move `o` (ours) is not move `t` (theirs), or `None`.
fn differs(o: &M, t: &M) -> Option<String> {
    if o.kind != t.kind {
        return Some(format!("kind {} / {}", o.kind, t.kind));
    }
    if o.kind == "dwell" {
        let (a, b) = (o.seconds.unwrap_or(f64::NAN), t.seconds.unwrap_or(f64::NAN));
        return (!close(a, b, DWELL_TOL_S)).then(|| format!("dwell {a} s / {b} s"));
    }
    if (0..3).any(|k| !close(o.end[k], t.end[k], POS_TOL_MM)) {
        return Some(format!("end {:?} / {:?}", o.end, t.end));
    }
    if let (Some((oc, op, od)), Some((tc, tp, td))) = (&o.arc, &t.arc) {
        if op != tp || od != td {
            return Some(format!("arc {op} {od} / {tp} {td}"));
        }
        let (i, j) = plane_axes(tp);
        if !close(oc[i], tc[i], POS_TOL_MM) || !close(oc[j], tc[j], POS_TOL_MM) {
            return Some(format!(
                "centre {}{} {}{} / {}{} {}{}",
                AXES[i], oc[i], AXES[j], oc[j], AXES[i], tc[i], AXES[j], tc[j]
            ));
        }
    }
    if o.kind != "rapid"
        && (!feeds_agree(o.feed_mm_min, t.feed_mm_min)
            || !feeds_agree(o.feed_mm_rev, t.feed_mm_rev))
    {
        return Some(format!(
            "feed {:?} mm/min {:?} mm/rev / {:?} mm/min {:?} mm/rev",
            o.feed_mm_min, o.feed_mm_rev, t.feed_mm_min, t.feed_mm_rev
        ));
    }
    None
}

fn show(m: &M) -> String {
    let mut s = format!(
        "{} X{:.6} Y{:.6} Z{:.6}",
        m.kind, m.end[0], m.end[1], m.end[2]
    );
    if let Some((c, p, d)) = &m.arc {
        let (i, j) = plane_axes(p);
        let _ = write!(
            s,
            " {p} {d} centre {}{:.6} {}{:.6}",
            AXES[i], c[i], AXES[j], c[j]
        );
    }
    if let Some(f) = m.feed_mm_min {
        let _ = write!(s, " F{f}");
    }
    if let Some(f) = m.feed_mm_rev {
        let _ = write!(s, " F{f}/rev");
    }
    if let Some(t) = m.seconds {
        s = format!("dwell {t} s");
    }
    format!("{s} ({})", m.at)
}

/// The machine of the reference runs.
fn setup() -> Setup {
    let dir = data_dir();
    let mut setup = Setup::new(&AXES);
    setup.dialect = Dialect::Iso;
    let kor = fs::read_to_string(dir.join("TAB0.KOR")).expect("TAB0.KOR");
    setup.offsets = offsets::parse(&kor, &AXES)
        .unwrap_or_else(|e| panic!("TAB0.KOR: {e:?}"))
        .table;
    let mut work = WorkOffsets::default();
    let text = fs::read_to_string(dir.join("work_offsets.txt")).expect("work_offsets.txt");
    for line in text.lines() {
        let line = line.split('#').next().unwrap_or("").trim();
        let mut words = line.split_whitespace();
        let Some(name) = words.next() else { continue };
        let k = WorkOffsets::index_of(name).unwrap_or_else(|| panic!("no system {name}"));
        for w in words {
            let axis = AXES
                .iter()
                .position(|a| w.starts_with(*a))
                .unwrap_or_else(|| panic!("{w}: not X, Y or Z"));
            work.systems[k][axis] = w[1..].parse().unwrap_or_else(|_| panic!("{w}"));
        }
    }
    setup.work_offsets = work;
    setup.start = AxesMm::ZERO;
    setup
}

/// Documented differences: `<name> <N> <why>` (deviations.txt).
fn deviations() -> Vec<(String, String, String)> {
    let text = fs::read_to_string(data_dir().join("deviations.txt")).unwrap_or_default();
    text.lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
        .filter_map(|l| {
            let mut f = l.splitn(3, ' ');
            Some((f.next()?.into(), f.next()?.into(), f.next()?.into()))
        })
        .collect()
}

/// A refusal: `<name> <line> <word> [code]` (code `error`: any error code).
struct Refusal {
    line: u32,
    word: String,
    code: String,
}

fn refusals() -> Vec<(String, Refusal)> {
    let text = fs::read_to_string(data_dir().join("refusals.txt")).expect("refusals.txt");
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            assert!(f.len() >= 3, "refusals.txt: {l}");
            let r = Refusal {
                line: f[1].parse().unwrap_or_else(|_| panic!("refusals.txt: {l}")),
                word: f[2].to_string(),
                code: f.get(3).unwrap_or(&"iso_unsupported").to_string(),
            };
            (f[0].to_string(), r)
        })
        .collect()
}

/// The message names the word: a G or M code as a whole (`G28`, not within `G28.1`), an
/// O-word by its label, any other word as written or by its letter standing alone in upper
/// case (`axis A`, `'^'`): the message may not repeat the value.
fn names_word(message: &str, word: &str) -> bool {
    let m = message.to_ascii_uppercase();
    let w = word.to_ascii_uppercase();
    if let Some(label) = w.strip_prefix("O<").and_then(|l| l.strip_suffix('>')) {
        return m.contains(label);
    }
    let whole = m.match_indices(&w).any(|(i, _)| {
        let before = m[..i].chars().next_back();
        let mut after = m[i + w.len()..].chars();
        let (a1, a2) = (after.next(), after.next());
        let joined_before = before.is_some_and(|c| c.is_ascii_alphanumeric());
        let more_digits = a1.is_some_and(|c| c.is_ascii_digit())
            || (a1 == Some('.') && a2.is_some_and(|c| c.is_ascii_digit()));
        !joined_before && !more_digits
    });
    if whole {
        return true;
    }
    let Some(letter) = w.chars().next() else {
        return false;
    };
    if matches!(letter, 'G' | 'M') {
        return false;
    }
    let b: Vec<char> = message.chars().collect();
    b.iter().enumerate().any(|(i, &c)| {
        c == letter
            && (i == 0 || !b[i - 1].is_alphanumeric())
            && b.get(i + 1).is_none_or(|n| !n.is_alphabetic())
    })
}

fn first_error(diags: &[Diagnostic]) -> Option<&Diagnostic> {
    diags.iter().find(|d| d.is_error())
}

fn check_moves(name: &str, text: &str, expected: &str, setup: &Setup) -> Result<usize, String> {
    let theirs: Vec<M> = expected
        .lines()
        .filter(|l| !l.trim().is_empty())
        .enumerate()
        .map(|(i, l)| theirs(l).map_err(|e| format!("{name}.jsonl line {}: {e}", i + 1)))
        .collect::<Result<_, _>>()?;
    let (ms, diags) = moves(text, setup);
    let mut report = String::new();
    if let Some(d) = first_error(&diags) {
        let _ = writeln!(
            report,
            "  error at line {} [{}]: {} (after {} moves)",
            d.line,
            d.code.as_str(),
            d.message,
            ms.len()
        );
    }
    let theirs = without_null_moves(theirs);
    let ours = without_null_moves(ms.iter().map(ours).collect());
    let mut shown = 0;
    for (i, (o, t)) in ours.iter().zip(&theirs).enumerate() {
        if let Some(why) = differs(o, t) {
            if shown < 5 {
                let _ = writeln!(
                    report,
                    "  move {i}: {why}\n    ours   {}\n    theirs {}",
                    show(o),
                    show(t)
                );
            }
            shown += 1;
        }
    }
    if shown > 5 {
        let _ = writeln!(report, "  … {} more moves differ", shown - 5);
    }
    if ours.len() != theirs.len() {
        let _ = writeln!(
            report,
            "  {} moves / {} moves (after dropping null moves)",
            ours.len(),
            theirs.len()
        );
        let k = ours.len().min(theirs.len());
        if let Some(t) = theirs.get(k) {
            let _ = writeln!(report, "    theirs next {}", show(t));
        }
        if let Some(o) = ours.get(k) {
            let _ = writeln!(report, "    ours next   {}", show(o));
        }
    }
    if report.is_empty() {
        Ok(theirs.len())
    } else {
        Err(report)
    }
}

fn check_refusal(text: &str, r: &Refusal, setup: &Setup) -> Result<(), String> {
    let (_, diags) = moves(text, setup);
    let Some(d) = first_error(&diags) else {
        return Err(format!(
            "  accepted; expected a refusal at line {} naming {}",
            r.line, r.word
        ));
    };
    let code_ok = r.code == "error" || d.code.as_str() == r.code;
    if d.line == r.line && code_ok && names_word(&d.message, &r.word) {
        return Ok(());
    }
    Err(format!(
        "  first error: line {} [{}] {}\n  expected:    line {} [{}] naming {}",
        d.line,
        d.code.as_str(),
        d.message,
        r.line,
        r.code,
        r.word
    ))
}

#[test]
fn iso_dry_run_matches_linuxcnc_rs274() {
    let dir = data_dir();
    let setup = setup();
    let refusals = refusals();
    let deviations = deviations();
    let mut programs: Vec<PathBuf> = fs::read_dir(&dir)
        .expect("kernel/tests/data/rs274")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "ngc"))
        .collect();
    programs.sort();
    assert!(!programs.is_empty(), "no programs in {}", dir.display());
    let mut report = String::new();
    let mut failing = Vec::new();
    for p in &programs {
        let name = p.file_stem().unwrap().to_string_lossy().to_string();
        // LinuxCNC's examples are not all UTF-8: read bytes, keep what decodes.
        let text = String::from_utf8_lossy(&fs::read(p).unwrap()).into_owned();
        let jsonl = dir.join(format!("{name}.jsonl"));
        let refusal = refusals.iter().find(|(n, _)| *n == name).map(|(_, r)| r);
        let result = match (refusal, fs::read_to_string(&jsonl)) {
            (Some(r), Err(_)) => check_refusal(&text, r, &setup)
                .map(|()| format!("refused at line {} ({})", r.line, r.word)),
            (None, Ok(expected)) => {
                check_moves(&name, &text, &expected, &setup).map(|n| format!("{n} moves"))
            }
            (Some(_), Ok(_)) => Err("  both a .jsonl and a refusal".to_string()),
            (None, Err(_)) => Err("  neither a .jsonl nor a refusal".to_string()),
        };
        let deviation = deviations.iter().find(|(n, _, _)| *n == name);
        let result = match (result, deviation) {
            (Err(why), Some((_, at, reason))) if why.contains(&format!("({at})")) => {
                Ok(format!("deviates from {at} on, as documented: {reason}"))
            }
            (r, _) => r,
        };
        match result {
            Ok(what) => {
                let _ = writeln!(report, "ok   {name}: {what}");
            }
            Err(why) => {
                let _ = writeln!(report, "FAIL {name}\n{why}");
                failing.push(name);
            }
        }
    }
    let total = programs.len();
    let _ = writeln!(
        report,
        "rs274 reference: {} of {total} programs agree, {} differ: {}",
        total - failing.len(),
        failing.len(),
        failing.join(" ")
    );
    println!("{report}");
    assert!(
        failing.is_empty(),
        "{} of {total} programs differ from LinuxCNC (report above)",
        failing.len()
    );
}

#[test]
fn json_reader_reads_reference_lines() {
    let m = theirs(
        r#"{"kind":"arc","end":{"X":1.5,"Y":-2,"Z":3e-1},"centre":{"Z":1,"X":0.25},"plane":"G18","dir":"ccw","feed_mm_min":100.0,"n":12}"#,
    )
    .unwrap();
    assert_eq!(m.kind, "arc");
    assert_eq!(m.end, [1.5, -2.0, 0.3]);
    let (c, p, d) = m.arc.unwrap();
    assert_eq!((c[0], c[2], p, d), (0.25, 1.0, "G18", "ccw"));
    assert_eq!(m.feed_mm_min, Some(100.0));
    assert_eq!(m.at, "N12");
    assert!(theirs(r#"{"kind":"feed","end":{"X":1}"#).is_err());
    assert_eq!(
        Reader::parse(r#"{"s":"a\"b","t":true,"u":null}"#).unwrap(),
        Json::Obj(vec![
            ("s".into(), Json::Str("a\"b".into())),
            ("t".into(), Json::Bool(true)),
            ("u".into(), Json::Null),
        ])
    );
}

#[test]
fn refusal_words_are_named() {
    assert!(names_word("G28 is not supported", "G28"));
    assert!(names_word("g28: not supported", "G28"));
    assert!(!names_word("G28.1 is not supported", "G28"));
    assert!(!names_word("G281 is not supported", "G28"));
    assert!(names_word(
        "G33.1 (rigid tapping) is not supported",
        "G33.1"
    ));
    assert!(!names_word("M6 is supported", "M66"));
    assert!(names_word("axis word A is not supported", "A0"));
    assert!(names_word("the word A12 is not supported", "A12"));
    assert!(!names_word("a word is not supported", "A12"));
    assert!(names_word("polar coordinates (^) are not supported", "^60"));
    assert!(names_word(
        "subroutine touchoff is not defined",
        "O<TOUCHOFF>"
    ));
}
