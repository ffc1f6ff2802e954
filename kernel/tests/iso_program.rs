//! The ISO / RS274-NGC dialect through the kernel's doors (`compile`, the dry run): LinuxCNC
//! 2.9's semantics for offsets, tools, arcs, cycles and O-words, and the codes of what is
//! refused (docs/language.md, "ISO programs"). The comparison with LinuxCNC's own interpreter
//! is kernel/tests/iso_rs274.rs.

use kernel::DiagCode;
use kernel::block::{BlockKind, Feed, Path, ProgramStop, SpindleDir};
use kernel::offsets::{OffsetEntry, WorkOffsets};
use kernel::program::dry_run::{Move, MoveKind, moves};
use kernel::program::{Dialect, Setup, compile};
use kernel::units::AxesMm;

fn setup() -> Setup {
    let mut s = Setup::new(&['X', 'Y', 'Z']);
    s.dialect = Dialect::Iso;
    s.offsets
        .set_entry(
            1,
            OffsetEntry {
                radius_mm: 3.0,
                length_mm: [0.0, 0.0, 10.0, 0.0],
            },
        )
        .unwrap();
    s.offsets
        .set_entry(
            2,
            OffsetEntry {
                radius_mm: 5.0,
                length_mm: [0.0, 0.0, 25.5, 0.0],
            },
        )
        .unwrap();
    let mut w = WorkOffsets::default();
    w.systems[0] = AxesMm([10.0, 20.0, -5.0, 0.0, 0.0, 0.0]);
    w.systems[1] = AxesMm([-100.0, 50.0, 0.0, 0.0, 0.0, 0.0]);
    s.work_offsets = w;
    s
}

fn run(text: &str) -> Vec<Move> {
    let (m, d) = moves(text, &setup());
    let errors: Vec<_> = d.iter().filter(|d| d.is_error()).collect();
    assert!(errors.is_empty(), "{text}\n{errors:#?}");
    m
}

fn ends(m: &[Move]) -> Vec<[f64; 3]> {
    m.iter()
        .filter(|m| !matches!(m.kind, MoveKind::Dwell { .. }))
        .map(|m| [m.end[0], m.end[1], m.end[2]])
        .collect()
}

fn near(a: [f64; 3], b: [f64; 3]) -> bool {
    (0..3).all(|k| (a[k] - b[k]).abs() < 1e-9)
}

fn assert_ends(text: &str, want: &[[f64; 3]]) {
    let got = ends(&run(text));
    assert_eq!(got.len(), want.len(), "{text}\n{got:?}");
    for (g, w) in got.iter().zip(want) {
        assert!(near(*g, *w), "{text}\ngot {got:?}\nwant {want:?}");
    }
}

fn refused(text: &str, code: DiagCode, line: u32) -> String {
    let (_, d) = moves(text, &setup());
    let e = d
        .iter()
        .find(|d| d.is_error())
        .unwrap_or_else(|| panic!("no error: {text}"));
    assert_eq!((e.code, e.line), (code, line), "{text}: {}", e.message);
    e.message.clone()
}

#[test]
fn work_offset_and_tool_length_make_machine_positions() {
    assert_ends(
        "G21 G90 G54\nT1 M6\nG43 H1\nG0 X0 Y0 Z5\nG1 Z-1 F100\nG55 G0 X1\nG49 G53 G0 Z0\nM30\n",
        &[
            [10.0, 20.0, 10.0],
            [10.0, 20.0, 4.0],
            [-99.0, 20.0, 4.0],
            [-99.0, 20.0, 0.0],
        ],
    );
}

#[test]
fn m6_is_a_program_stop_before_the_motion_of_its_line() {
    let c = compile("T2 M6 G0 X1\n", &setup());
    assert!(!c.has_errors(), "{:?}", c.diagnostics);
    // The stop names the tool (issue #47) and the spindle stops for the change.
    assert_eq!(c.blocks[0].kind, BlockKind::ToolChange { tool: 2 });
    assert_eq!(c.blocks[0].m, [Some(6), None, None, None]);
    assert_eq!(
        ProgramStop::of_block(&c.blocks[0]),
        ProgramStop::ToolChange { tool: 2 }
    );
    assert_eq!(c.blocks[0].spindle.dir, SpindleDir::Stopped);
    assert!(matches!(c.blocks[1].kind, BlockKind::Motion { .. }));
}

#[test]
fn inches_incremental_and_g92() {
    assert_ends(
        "G20 G91 G0 X1 Y1\nG21 G90 G92 X0 Y0\nG0 X5\nG92.1\nG0 X5\n",
        &[[25.4, 25.4, 0.0], [30.4, 25.4, 0.0], [15.0, 25.4, 0.0]],
    );
}

#[test]
fn radius_form_arc_and_ijk_give_the_same_centre() {
    let a = run("G0 X0 Y0\nG2 X10 Y0 R5 F100\n");
    let b = run("G0 X0 Y0\nG2 X10 Y0 I5 J0 F100\n");
    let centre = |m: &Move| match m.kind {
        MoveKind::Arc { centre, .. } => [centre[0], centre[1]],
        _ => panic!("not an arc"),
    };
    assert_eq!(centre(&a[1]), [15.0, 20.0]);
    assert_eq!(centre(&b[1]), [15.0, 20.0]);
    // Negative R: the larger arc, centre on the other side of the chord.
    let c = run("G0 X0 Y0\nG2 X10 Y0 R-5.000001 F100\n");
    assert!((centre(&c[1])[1] - 20.0).abs() < 1e-2);
    refused("G0 X0 Y0\nG2 X30 Y0 R5 F100\n", DiagCode::ArcRadiusForm, 2);
    refused(
        "G0 X0 Y0\nG2 X10 Y0 I5 J0 P2 F100\n",
        DiagCode::ArcRadiusForm,
        2,
    );
}

#[test]
fn helical_arc_feed_and_inverse_time() {
    let m = run("G0 X0 Y0 Z0\nG93 G3 X0 Y0 Z-1 I5 J0 F2\n");
    let len = (std::f64::consts::TAU * 5.0).hypot(1.0);
    assert!((m[1].feed_mm_min.unwrap() - 2.0 * len).abs() < 1e-9);
    refused("G93 G1 X1\n", DiagCode::NoFeed, 1);
}

#[test]
fn g81_with_g98_returns_to_the_initial_level() {
    // Program coordinates: start Z10, R2, bottom -3, two holes (G54: +10, +20, -5).
    let text = "G0 X0 Y0 Z10\nG98 G81 X1 Y1 R2 Z-3 F100\nX2\nG80\n";
    assert_ends(
        text,
        &[
            [10.0, 20.0, 5.0],
            [11.0, 21.0, 5.0],
            [11.0, 21.0, -3.0],
            [11.0, 21.0, -8.0],
            [11.0, 21.0, 5.0],
            [12.0, 21.0, 5.0],
            [12.0, 21.0, -3.0],
            [12.0, 21.0, -8.0],
            [12.0, 21.0, 5.0],
        ],
    );
}

#[test]
fn g83_pecks_and_g91_repeats() {
    let m = run("G0 X0 Y0 Z5\nG99 G83 X0 Y0 R1 Z-2 Q1.5 F100\n");
    // R1: feed to -0.5, up to R, down to -0.5+0.254, feed to -2, up to R.
    let z: Vec<f64> = m.iter().map(|m| m.end[2] + 5.0).collect();
    let want = [5.0, 5.0, 1.0, -0.5, 1.0, -0.5 + 0.254, -2.0, 1.0];
    assert_eq!(z.len(), want.len(), "{z:?}");
    for (a, b) in z.iter().zip(want) {
        assert!((a - b).abs() < 1e-9, "{z:?}");
    }
    // G91: X steps per hole, L holes.
    let m = run("G0 X0 Y0 Z5\nG91 G99 G81 X10 R-4 Z-3 L3 F100\n");
    let xs: Vec<f64> = m
        .iter()
        .filter(|m| matches!(m.kind, MoveKind::Feed))
        .map(|m| m.end[0] - 10.0)
        .collect();
    assert_eq!(xs, [10.0, 20.0, 30.0]);
}

#[test]
fn cycles_refuse_missing_words() {
    refused("G0 Z5\nG81 X1 Z-1 F100\n", DiagCode::CycleWord, 2);
    refused("G0 Z5\nG83 X1 R1 Z-1 F100\n", DiagCode::CycleWord, 2);
    refused("G0 Z5\nG82 X1 R1 Z-1 F100\n", DiagCode::CycleWord, 2);
}

#[test]
fn dwell_is_a_block() {
    let m = run("G0 X1\nG4 P0.5\n");
    assert_eq!(m[1].kind, MoveKind::Dwell { seconds: 0.5 });
}

#[test]
fn parameters_are_read_before_the_line_sets_them() {
    assert_ends(
        "#1=5\n#1=7 G0 X#1\nG0 X#1\n",
        &[[15.0, 0.0, 0.0], [17.0, 0.0, 0.0]],
    );
    assert_ends("#<a>=2\nG0 X[#<a>*3+SIN[90]]\n", &[[17.0, 0.0, 0.0]]);
}

#[test]
fn subroutines_loops_and_conditions() {
    let text = "\
o100 sub
  G0 X#1 Y#2
  o100 return [#1+#2]
o100 endsub
#<i>=0
o1 while [#<i> LT 3]
  o100 call [#<i>] [1]
  #<i>=[#<i>+1]
o1 endwhile
o2 if [#<_value> EQ 3]
  G0 Z1
o2 else
  G0 Z2
o2 endif
o3 repeat [2]
  G0 X9
o3 endrepeat
#<k>=0
o4 do
  #<k>=[#<k>+1]
  o5 if [#<k> EQ 2]
    o4 continue
  o5 endif
  o6 if [#<k> EQ 4]
    o4 break
  o6 endif
  G0 Y#<k>
o4 while [#<k> LT 10]
M2
";
    let z: Vec<[f64; 3]> = ends(&run(text));
    let want = [
        [10.0, 21.0, 0.0],
        [11.0, 21.0, 0.0],
        [12.0, 21.0, 0.0],
        [12.0, 21.0, -4.0],
        [19.0, 21.0, -4.0],
        [19.0, 21.0, -4.0],
        [19.0, 21.0, -4.0],
        [19.0, 23.0, -4.0],
    ];
    assert_eq!(z.len(), want.len(), "{z:?}");
    for (a, b) in z.iter().zip(want) {
        assert!(near(*a, b), "{z:?}");
    }
}

#[test]
fn a_subroutine_may_follow_its_call() {
    assert_ends(
        "o<later> call [4]\nM2\no<later> sub\nG0 X#1\no<later> endsub\n",
        &[[14.0, 0.0, 0.0]],
    );
}

/// Loops in loops are bounded by the lines they read again (`Setup::max_lines_again`), not
/// only each by its iterations: three nested repeats of 1000 would read 10^9 lines.
#[test]
fn nested_loops_are_bounded_in_lines() {
    let mut s = setup();
    s.max_lines_again = 20_000;
    let text = "o1 repeat [1000]\no2 repeat [1000]\no3 repeat [1000]\nG0 X1\n\
                o3 endrepeat\no2 endrepeat\no1 endrepeat\nM2\n";
    let (_, d) = moves(text, &s);
    let e: Vec<_> = d.iter().filter(|d| d.is_error()).collect();
    assert_eq!(e.len(), 1, "{e:?}");
    assert_eq!(e[0].code, DiagCode::LoopLimit);
    let (_, d) = moves(&text.replace("[1000]", "[10]"), &s);
    assert!(!d.iter().any(|d| d.is_error()), "{d:?}");
}

/// A cycle block's pecks are bounded (`MAX_PECKS`): a micrometre's peck down a metre is
/// refused naming Q, and a peck below the depth's rounding ends (it never would in the
/// loop's own subtraction).
#[test]
fn pecks_are_bounded() {
    let text = "G0 X0 Y0 Z10\nG83 X1 Y1 Z-1000 R1 Q0.0001 F100\nM2\n";
    assert!(refused(text, DiagCode::CycleWord, 2).contains("pecks"));
    let text = "G91 G0 X0 Y0 Z10\nG83 X1 Y1 Z-10 R1 Q0.001 L11 F100\nM2\n";
    assert!(refused(text, DiagCode::CycleWord, 2).contains("at most 100000"));
    let text =
        "G0 X0 Y0 Z1000000000010\nG83 X1 Y1 Z999999999999 R1000000000000 Q0.00002 F100\nM2\n";
    let (m, d) = moves(text, &setup());
    assert!(!d.iter().any(|d| d.is_error()), "{d:?}");
    assert!(m.len() <= 3 * 100_000 + 10, "{}", m.len());
}

#[test]
fn flow_errors_have_codes() {
    refused(
        "o1 while [1]\n#1=[#1+1]\no1 endwhile\n",
        DiagCode::LoopLimit,
        1,
    );
    refused("o9 call\n", DiagCode::SubroutineUnknown, 1);
    refused("G0 X1\no1 endwhile\n", DiagCode::OWordMismatch, 2);
    let (_, d) = moves("o1 if [1]\nG0 X1\n", &setup());
    assert!(d.iter().any(|d| d.code == DiagCode::OWordMismatch), "{d:?}");
}

#[test]
fn what_is_not_run_is_refused_naming_the_word() {
    assert!(refused("G0 X1\nG28\n", DiagCode::IsoUnsupported, 2).contains("G28"));
    assert!(refused("G38.1 Z-10 F100\n", DiagCode::IsoUnsupported, 1).contains("G38.1"));
    assert!(refused("M66 P0 L3\n", DiagCode::IsoUnsupported, 1).contains("M66"));
    assert!(refused("G0 A10\n", DiagCode::IsoUnsupported, 1).contains('A'));
    refused("G0 X1 G1 Y1\n", DiagCode::IsoModalConflict, 1);
    refused("T100 M6\n", DiagCode::ToolNotInTable, 1);
}

#[test]
fn compensation_uses_the_entry_radius() {
    let c = compile(
        "T1 M6\nG0 X0 Y0\nG41 D2 G1 X10 F100\nG1 Y10\nG40 G1 X0\n",
        &setup(),
    );
    assert!(!c.has_errors(), "{:?}", c.diagnostics);
    let comp = c.blocks.iter().find_map(|b| match b.comp {
        kernel::block::Comp::Left { d, radius_mm } => Some((d, radius_mm)),
        _ => None,
    });
    assert_eq!(comp, Some((2, 5.0)));
    let feeds: Vec<_> = c
        .blocks
        .iter()
        .filter_map(|b| match (b.kind, b.feed) {
            (
                BlockKind::Motion {
                    path: Path::Line, ..
                },
                Feed::MmPerMin(f),
            ) => Some(f),
            _ => None,
        })
        .collect();
    assert_eq!(feeds, [100.0, 100.0, 100.0]);
}

#[test]
fn a_word_not_run_refuses_the_program_even_where_it_is_not_reached() {
    let m = refused(
        "o1 sub\nM66 P0 L3\no1 endsub\nG0 X1\nM2\n",
        DiagCode::IsoUnsupported,
        2,
    );
    assert!(m.contains("M66"), "{m}");
}

#[test]
fn percent_brackets_the_program() {
    assert_ends("%\nG0 X1\n%\nG0 X2\n", &[[11.0, 0.0, 0.0]]);
}

#[test]
fn mdi_inherits_motion_feed_and_distance_mode() {
    let s = setup();
    let mut st = kernel::program::stream("G91 G1 X1 F250\n", &s);
    while st.next().is_some() {}
    let next = Setup {
        modal: Some(st.modal()),
        ..setup()
    };
    let c = compile("X2\n", &next);
    assert!(!c.has_errors(), "{:?}", c.diagnostics);
    assert_eq!(c.blocks[0].feed, Feed::MmPerMin(250.0));
    match c.blocks[0].kind {
        BlockKind::Motion {
            start,
            end,
            path: Path::Line,
        } => assert_eq!(end[0] - start[0], 2.0),
        k => panic!("{k:?}"),
    }
}
