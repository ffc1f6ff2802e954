//! Dwell, subprograms and repeats of the CNC836 dialect (docs/language.md, "Dwell" and
//! "Subprograms and repeats").

use kernel::block::{Block, BlockKind, Comp, Feed};
use kernel::offsets::OffsetEntry;
use kernel::program::dry_run::{self, MoveKind};
use kernel::program::{Interpreter, Lines, Setup, compile, stream, validate};
use kernel::{DiagCode, Diagnostic};

fn mill() -> Setup {
    Setup::new(&['X', 'Y', 'Z'])
}

fn ok(text: &str) -> Vec<Block> {
    let c = compile(text, &mill());
    assert!(!c.has_errors(), "unexpected errors: {:#?}", c.diagnostics);
    c.blocks
}

fn errors(text: &str) -> Vec<Diagnostic> {
    let c = compile(text, &mill());
    assert!(c.has_errors(), "expected an error in {text:?}");
    c.diagnostics.into_iter().filter(|d| d.is_error()).collect()
}

/// The first error of `text`: its code, line and column.
fn first_error(text: &str) -> (DiagCode, u32, u32) {
    let e = errors(text).remove(0);
    (e.code, e.line, e.column)
}

fn x_end(b: &Block) -> f64 {
    b.motion().expect("a motion block").1[0]
}

/// (N, line) of every block.
fn n_and_lines(b: &[Block]) -> Vec<(Option<u32>, u32)> {
    b.iter().map(|b| (b.n, b.line)).collect()
}

// ---- Dwell G4 F<seconds> ------------------------------------------------------------------

#[test]
fn g4_f_is_a_dwell_in_seconds_and_leaves_the_feed() {
    let b = ok("G1 X10 F100\nN20 G4 F2.5\nG4 F2\nR1=0.5\nG4 FR1\nG1 X20");
    assert_eq!(b[1].kind, BlockKind::Dwell { seconds: 2.5 });
    assert_eq!((b[1].n, b[1].line), (Some(20), 2));
    assert_eq!(b[2].kind, BlockKind::Dwell { seconds: 2.0 });
    assert_eq!(b[4].kind, BlockKind::Dwell { seconds: 0.5 });
    // F of G4 is a time: the feed of the next move is still F100.
    assert_eq!(b[5].feed, Feed::MmPerMin(100.0));
    let seqs: Vec<u32> = b.iter().map(|b| b.seq).collect();
    assert_eq!(seqs, [0, 1, 2, 3, 4, 5]);
    let (moves, d) = dry_run::moves("G1 X10 F100\nG4 F1.5\n", &mill());
    assert!(d.is_empty(), "{d:?}");
    assert_eq!(moves[1].kind, MoveKind::Dwell { seconds: 1.5 });
    assert_eq!(moves[1].end[0], 10.0);
}

#[test]
fn a_dwell_under_compensation_carries_it() {
    let mut s = mill();
    s.offsets
        .set_entry(
            1,
            OffsetEntry {
                radius_mm: 2.0,
                length_mm: [0.0; 4],
            },
        )
        .unwrap();
    let c = compile("D1 G41 G1 X10 F100\nG4 F1\nX20\nG40 X30", &s);
    assert!(!c.has_errors(), "{:?}", c.diagnostics);
    assert_eq!(
        c.blocks[1].comp,
        Comp::Left {
            d: 1,
            radius_mm: 2.0
        }
    );
}

#[test]
fn dwell_errors_have_codes() {
    assert_eq!(first_error("N5 G4"), (DiagCode::DwellWithoutTime, 1, 4));
    assert_eq!(first_error("G4 X1 F2"), (DiagCode::DwellNotAlone, 1, 4));
    assert_eq!(first_error("G4 F2 M8"), (DiagCode::DwellNotAlone, 1, 7));
    assert_eq!(first_error("G1 G4 F2"), (DiagCode::DwellNotAlone, 1, 1));
    assert_eq!(first_error("G4 F1 R1=2"), (DiagCode::DwellNotAlone, 1, 7));
    assert_eq!(first_error("G4 F100000"), (DiagCode::WordOutOfRange, 1, 4));
    assert_eq!(first_error("G4 F-1"), (DiagCode::WordOutOfRange, 1, 4));
    assert_eq!(first_error("G4 G4 F1"), (DiagCode::WordTwice, 1, 4));
    ok("G4 F99999.999\nG4 F0");
}

// ---- Subprograms and repeats -----------------------------------------------------------------

const REPEATED: &str = "\
N10 G0 X0 Y0
N20 L10 P3
N30 G0 X100
N40 M30
%L10 ; one step of 10 mm
N100 G91 G1 X10 F500
N110 G90
N120 M17
";

#[test]
fn a_subprogram_runs_count_times_with_its_own_line_numbers() {
    let c = compile(REPEATED, &mill());
    assert!(!c.has_errors(), "{:?}", c.diagnostics);
    // Definitions after the end are not lines left out: no note.
    assert!(c.diagnostics.is_empty(), "{:?}", c.diagnostics);
    let b = c.blocks;
    assert_eq!(
        n_and_lines(&b),
        [
            (Some(10), 1),
            (Some(100), 6),
            (Some(110), 7),
            (Some(100), 6),
            (Some(110), 7),
            (Some(100), 6),
            (Some(110), 7),
            (Some(30), 3),
            (Some(40), 4),
        ]
    );
    let seqs: Vec<u32> = b.iter().map(|b| b.seq).collect();
    assert_eq!(seqs, (0..9).collect::<Vec<_>>());
    let xs: Vec<f64> = [1, 3, 5, 7].iter().map(|&k| x_end(&b[k])).collect();
    assert_eq!(xs, [10.0, 20.0, 30.0, 100.0]);
    // validate, stream and compile read the program the same way.
    assert!(validate(REPEATED, &mill()).is_empty());
    let streamed: Vec<Block> = stream(REPEATED, &mill()).map(Result::unwrap).collect();
    assert_eq!(streamed, b);
}

#[test]
fn a_definition_in_the_way_is_passed_over() {
    let b = ok("%L1\nG1 X5 F100\nM17\nG0 X1\nL1\nG0 X2\nL1\n");
    assert_eq!(
        n_and_lines(&b),
        [(None, 4), (None, 2), (None, 6), (None, 2)]
    );
    assert_eq!(x_end(&b[1]), 5.0);
}

#[test]
fn calls_nest_and_carry_the_modal_state() {
    let text = "\
G1 F200
L1 P2
M30
%L1
G91 X1
L2 P2
G90
M17
%L2
G91 Y1 ; in L1's G91
M17
";
    let b = ok(text);
    let lines: Vec<u32> = b.iter().map(|b| b.line).collect();
    assert_eq!(lines, [1, 5, 10, 10, 7, 5, 10, 10, 7, 3]);
    let last_move = b[7].motion().unwrap().1;
    assert_eq!((last_move[0], last_move[1]), (2.0, 4.0));
}

#[test]
fn call_words_may_be_parameters() {
    let b = ok("R1=2 R2=3\nLR1 PR2\nM30\n%L2\nG91 G0 X1\nM17\n");
    assert_eq!(b.len(), 5);
    assert_eq!(x_end(&b[3]), 3.0);
}

#[test]
fn nesting_is_bounded() {
    // Each level calls itself: the ninth call is refused, the levels return.
    let (code, line, _) = first_error("L1\nM30\n%L1\nN7 L1\nM17\n");
    assert_eq!((code, line), (DiagCode::LoopLimit, 4));
    let e = errors("L1\nM30\n%L1\nN7 L1\nM17\n");
    assert_eq!(e.len(), 1, "{e:?}");
    assert_eq!(e[0].block, Some(7));
    // Eight levels are allowed.
    let mut text = String::from("L1\nM30\n");
    for k in 1..=8 {
        text.push_str(&format!("%L{k}\n"));
        if k < 8 {
            text.push_str(&format!("L{}\n", k + 1));
        } else {
            text.push_str("G0 X8\n");
        }
        text.push_str("M17\n");
    }
    assert_eq!(ok(&text).len(), 2);
}

#[test]
fn passes_are_bounded() {
    let text = "L1 P9999\nM30\n%L1\nL2 P9999\nM17\n%L2\nM17\n";
    let d = validate(text, &mill());
    assert_eq!(d.len(), 1, "{d:?}");
    assert_eq!(d[0].code, DiagCode::LoopLimit);
}

/// Passes times the lines of each are bounded too (`Setup::max_lines_again`): a few lines of
/// calls in calls (a fuzz finding: 253 bytes, 1,000,000 passes, 12 M lines checked) stop
/// with one `loop_limit` once the program has read that many lines again.
#[test]
fn lines_read_again_are_bounded() {
    let mut setup = mill();
    setup.max_lines_again = 10_000;
    let text = "L1 P9999\nM30\n%L1\nG91 G0 X1\nL2 P3\nM17\n%L2\nG0 X-1\nG0 Y1\nM17\n";
    let d = validate(text, &setup);
    assert_eq!(d.len(), 1, "{d:?}");
    assert_eq!(d[0].code, DiagCode::LoopLimit);
    assert!(
        d[0].message.contains("10000 lines again"),
        "{}",
        d[0].message
    );
    // Within the bound, the same program runs.
    let few = text.replace("P9999", "P100");
    assert!(validate(&few, &setup).is_empty());
    // Reading the whole source once more (the search for labels) is not counted.
    let mut long = String::from("L1\n");
    for k in 0..20_000 {
        long.push_str(&format!("G0 X{}\n", k % 10));
    }
    long.push_str("M30\n%L1\nG0 Y1\nM17\n");
    setup.max_lines_again = 10;
    assert!(validate(&long, &setup).is_empty());
}

#[test]
fn subprogram_errors_have_codes() {
    assert_eq!(
        first_error("G0 X1\nN20 L5"),
        (DiagCode::SubroutineUnknown, 2, 1)
    );
    assert_eq!(
        first_error("L1\nM30\n%L1\nM17\n%L1\nM17\n"),
        (DiagCode::SubprogramTwice, 5, 1)
    );
    // The end of the program inside a subprogram, in a definition passed over, or the next
    // definition: the error is on the line of the %L without an end.
    assert_eq!(
        first_error("L1\nM30\n%L1\nG0 X1\n"),
        (DiagCode::SubprogramWithoutReturn, 3, 1)
    );
    assert_eq!(
        first_error("%L1\nG0 X1\n"),
        (DiagCode::SubprogramWithoutReturn, 1, 1)
    );
    assert_eq!(
        first_error("L1\nM30\n%L1\nG0 X1\n%L2\nM17\n"),
        (DiagCode::SubprogramWithoutReturn, 3, 1)
    );
    assert_eq!(
        first_error("%L1\nG0 X1\n%L2\nM17\nL2"),
        (DiagCode::SubprogramWithoutReturn, 1, 1)
    );
    assert_eq!(
        first_error("G0 X1\nM17"),
        (DiagCode::ReturnWithoutCall, 2, 1)
    );
    for (text, col) in [
        ("%L0", 3),
        ("%L12a", 3),
        ("%L10000", 3),
        ("L1 X5", 4),
        ("N1 P3", 4),
        ("M17 X1", 5),
        ("R1=17\nMR1", 1),
    ] {
        let (code, _, c) = first_error(text);
        assert_eq!((code, c), (DiagCode::SubprogramSyntax, col), "{text}");
    }
    assert_eq!(first_error("L0").0, DiagCode::WordOutOfRange);
    assert_eq!(first_error("L1 P0").0, DiagCode::WordOutOfRange);
    assert_eq!(first_error("L1.5").0, DiagCode::WordNotWhole);
    assert_eq!(first_error("L1 L2").0, DiagCode::WordTwice);
}

#[test]
fn a_wrong_block_ending_a_subprogram_still_ends_it() {
    // M17 with another word is refused, and the subprogram ends there all the same: the
    // caller goes on (one error, not one per line after it).
    let e = errors("L1\nG0 X9\nM30\n%L1\nG0 X1\nM17 X2\n");
    assert_eq!(e.len(), 1, "{e:?}");
    assert_eq!((e[0].code, e[0].line), (DiagCode::SubprogramSyntax, 6));
}

#[test]
fn block_delete_skips_a_call_but_not_the_bounds_of_a_subprogram() {
    let mut s = mill();
    s.block_delete = true;
    let text = "G0 X1\n/L1\nM30\n%L1\nG0 X5\nM17\n";
    assert_eq!(compile(text, &s).blocks.len(), 2);
    s.block_delete = false;
    assert_eq!(compile(text, &s).blocks.len(), 3);
    let c = compile("L1\nM30\n%L1\nG0 X5\n/M17\nM17\n", &s);
    let e = c.diagnostics.iter().find(|d| d.is_error()).unwrap();
    assert_eq!((e.code, e.line), (DiagCode::SubprogramSyntax, 5));
}

#[test]
fn code_after_the_end_is_still_noted_beside_definitions() {
    let c = compile("G0 X1\nM30\n%L1\nG0 X5\nM17\nG0 X7\n", &mill());
    assert!(!c.has_errors());
    assert_eq!(c.diagnostics.len(), 1);
    assert_eq!(c.diagnostics[0].code, DiagCode::LinesAfterEnd);
}

#[test]
fn a_line_alone_cannot_call() {
    let mut i = Interpreter::new(&mill());
    let e = i.line(1, "L1").unwrap_err();
    assert_eq!(e.code, DiagCode::SourceCannotSeek);
    assert!(i.line(2, "G0 X1").unwrap().is_some());
}

/// Lines that cannot go back (a pipe): a call is refused, everything else runs.
struct Forward<'a>(std::str::Lines<'a>);

impl Lines for Forward<'_> {
    fn next_line(&mut self, _: u32) -> Option<Result<&str, Diagnostic>> {
        self.0.next().map(Ok)
    }
}

#[test]
fn a_source_that_cannot_seek_refuses_calls_only() {
    let text = "G0 X1\nL1\nG0 X2\nM30\n%L1\nM17\n";
    let items: Vec<_> = kernel::program::stream_lines(Forward(text.lines()), &mill()).collect();
    assert_eq!(items.len(), 4);
    assert_eq!(
        items[1].as_ref().unwrap_err().code,
        DiagCode::SourceCannotSeek
    );
    assert!(items[2].is_ok() && items[3].is_ok());
}
