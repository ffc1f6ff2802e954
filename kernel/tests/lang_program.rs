//! Interpreter behaviour against SPEC §2, §3, §4.6, §5 (issue #3).

use kernel::block::{ArcDir, Block, BlockKind, Comp, Continuity, Feed, Path, Plane, SpindleDir};
use kernel::offsets::{OffsetEntry, OffsetTable};
use kernel::program::{IjMode, Setup, compile, stream, validate};
use kernel::{DiagCode, Diagnostic, Severity};

fn mill() -> Setup {
    Setup::new(&['X', 'Y', 'Z', 'U'])
}

fn ok(text: &str, setup: &Setup) -> Vec<Block> {
    let c = compile(text, setup);
    assert!(!c.has_errors(), "unexpected errors: {:#?}", c.diagnostics);
    c.blocks
}

fn errors(text: &str, setup: &Setup) -> Vec<Diagnostic> {
    let c = compile(text, setup);
    assert!(c.has_errors(), "expected an error in {text:?}");
    assert!(c.blocks.is_empty(), "no blocks when there are errors");
    c.diagnostics.into_iter().filter(|d| d.is_error()).collect()
}

fn first_error(text: &str, setup: &Setup) -> Diagnostic {
    errors(text, setup).remove(0)
}

/// The first error of `text` on the mill has `code` (the message is shown when it does not).
fn assert_refused(text: &str, code: DiagCode) {
    let e = first_error(text, &mill());
    assert_eq!(e.code, code, "{text}: {}", e.message);
}

fn arc_center(b: &Block) -> (Plane, ArcDir, [f64; 3]) {
    match b.motion() {
        Some((_, _, Path::Arc { dir, center, plane })) => {
            (plane, dir, [center[0], center[1], center[2]])
        }
        other => panic!("not an arc: {other:?}"),
    }
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-9
}

// ---- SPEC §4.6 worked examples, through the whole interpreter ----------------------------

#[test]
fn e_address_refines_i_manual_example() {
    let mut s = mill();
    s.constants.set(55, 0.001); // R55 tight enough that the unrefined circle is refused
    // Start (0,0), Iz = 12.345 + 2.054 µm = 12.347054: half circle to X = 2·Iz.
    let prog = "G3 X24.694108 Y0 I12.345 J0 E2.054 F100";
    let b = ok(prog, &s);
    let (_, _, c) = arc_center(&b[0]);
    assert!(close(c[0], 12.347054) && close(c[1], 0.0), "{c:?}");
    // Without E the end point misses the circle by 4.1 µm > R55.
    let e = first_error("G3 X24.694108 Y0 I12.345 J0 F100", &s);
    assert_eq!(e.code, DiagCode::ArcEndOffCircle, "{}", e.message);
}

#[test]
fn e_address_refines_j_manual_example() {
    let mut s = mill();
    s.constants.set(55, 0.001);
    // Jz = 5.088 − 6.992 µm = 5.081008.
    let b = ok("G2 X0 Y10.162016 I0 J5.088 E-10006.992 F100", &s);
    let (_, dir, c) = arc_center(&b[0]);
    assert_eq!(dir, ArcDir::Cw);
    assert!(close(c[1], 5.081008) && close(c[0], 0.0), "{c:?}");
}

#[test]
fn e_with_a_bad_decade_8_is_an_error() {
    let e = first_error("G2 X0 Y10 I0 J5 E20001 F100", &mill());
    assert_eq!(e.code, DiagCode::ERefinementInvalid, "{}", e.message);
    assert_eq!(e.column, 17);
}

// ---- R325 refinement and the R55 end-point check ----------------------------------------

/// Quarter circle radius 10 about (0,10) from (0,0) to (10,10), centre written 3 µm off in I.
const OFF_CENTRE: &str = "G3 X10 Y10 I0.003 J10 F100";

#[test]
fn r55_refuses_an_arc_whose_end_misses_the_circle() {
    let mut s = mill();
    s.constants.set(55, 0.001);
    let e = first_error(OFF_CENTRE, &s);
    assert_eq!(e.code, DiagCode::ArcEndOffCircle, "{}", e.message);
    s.constants.set(55, 0.01);
    ok(OFF_CENTRE, &s);
}

#[test]
fn r325_refinement_makes_the_arc_consistent() {
    let mut s = mill();
    s.constants.set(55, 0.0);
    s.constants.set(325, 10000.010); // on, limit 10 µm
    let b = ok(OFF_CENTRE, &s);
    let (start, end, path) = b[0].motion().unwrap();
    let Path::Arc { center, .. } = path else {
        panic!()
    };
    let rs = (start[0] - center[0]).hypot(start[1] - center[1]);
    let re = (end[0] - center[0]).hypot(end[1] - center[1]);
    assert!((rs - re).abs() < 1e-6, "{rs} {re}");
    // Limit 1 µm: too small for a 3 µm error, the R55 check refuses the arc.
    s.constants.set(325, 10000.001);
    assert!(compile(OFF_CENTRE, &s).has_errors());
    // Decade 8 = 2: no limit test.
    s.constants.set(325, 20000.001);
    ok(OFF_CENTRE, &s);
    // Preprocessor off ($63 = 0): no refinement.
    s.preprocessor = false;
    assert!(compile(OFF_CENTRE, &s).has_errors());
}

#[test]
fn r397_d7_turns_a_bad_arc_into_a_line_with_a_warning() {
    let mut s = mill();
    s.constants.set(397, 1000.0); // 01000.000: decade 7 = 1
    assert!(s.constants.bad_arc_becomes_line());
    let c = compile("N7 G1 F100\nN8 G2 X10 Y1 I5 J1 ", &s);
    assert!(!c.has_errors(), "{:?}", c.diagnostics);
    assert_eq!(c.blocks[1].motion().unwrap().2, Path::Line);
    let w = &c.diagnostics[0];
    assert_eq!(
        (w.severity, w.block, w.line),
        (Severity::Warning, Some(8), 2)
    );
    assert_eq!(w.code, DiagCode::ArcReplacedByLine, "{}", w.message);
}

#[test]
fn arcs_need_both_centre_words_and_a_radius() {
    assert_refused("G2 X10 Y0 I5 F100", DiagCode::ArcNeedsCentre);
    assert_refused("G2 X10 Y0 I0 J0 F100", DiagCode::ArcRadiusZero);
    assert_refused("G1 X10 I5 J0 F100", DiagCode::ArcWordWithoutArc);
}

#[test]
fn full_circle_with_centre_only() {
    let b = ok("G2 I5 J0 F100", &mill());
    let (start, end, _) = b[0].motion().unwrap();
    assert_eq!(start, end);
    assert_eq!(arc_center(&b[0]).2, [5.0, 0.0, 0.0]);
}

#[test]
fn ij_absolute_setting() {
    let mut s = mill();
    s.ij = IjMode::Absolute;
    let b = ok("G0 X10 Y0\nG3 X20 Y10 I20 J0 F100", &s);
    assert_eq!(arc_center(&b[1]).2, [20.0, 0.0, 0.0]);
    // The same words read relative to the start are a different circle.
    assert!(compile("G0 X10 Y0\nG3 X20 Y10 I20 J0 F100", &mill()).has_errors());
    ok("G0 X10 Y0\nG3 X20 Y10 I10 J0 F100", &mill());
}

#[test]
fn arc_planes_map_i_j_to_the_plane_axes() {
    // G18 = axes (Z, X): I is along Z, J along X. Start (0,0,0) → end Z10 X10 about Z10 X0.
    let b = ok("G18 G2 X10 Z10 I10 J0 F100", &mill());
    let (plane, _, c) = arc_center(&b[0]);
    assert_eq!(plane, Plane::G18);
    assert_eq!(c, [0.0, 0.0, 10.0]);
    // G19 = (Y, Z).
    let b = ok("G19 G3 Y10 Z10 I0 J10 F100", &mill());
    assert_eq!(arc_center(&b[0]).2, [0.0, 0.0, 10.0]);
    // A two-axis lathe has no G18.
    let e = first_error("G18", &Setup::new(&['X', 'Z']));
    assert_eq!(e.code, DiagCode::PlaneNeedsAxis);
}

#[test]
fn helix_moves_the_third_axis_linearly() {
    let b = ok("G2 X10 Y0 Z-5 I5 J0 F100", &mill());
    let (_, end, _) = b[0].motion().unwrap();
    assert_eq!(end[2], -5.0);
}

// ---- G92 table writes (SPEC §3) ----------------------------------------------------------

fn with_entry_12() -> Setup {
    let mut s = mill();
    s.offsets
        .set_entry(
            12,
            OffsetEntry {
                radius_mm: 1.0,
                length_mm: [11.0, 12.0, 13.0, 14.0],
            },
        )
        .unwrap();
    s
}

#[test]
fn g92_writes_only_the_parameters_present_manual_example() {
    let s = with_entry_12();
    let text = "N10 G92 D12 R0=10.0 R2=25.5 R3=-5.0\nN20 D12 G41 G1 X10 F100\nN30 G40 X20";
    let mut st = stream(text, &s);
    let b0 = st.next().unwrap().unwrap();
    assert_eq!(
        b0.kind,
        BlockKind::TableWrite {
            entry: 12,
            values: [Some(10.0), None, Some(25.5), Some(-5.0), None]
        }
    );
    // The interpreter's own copy changed at once: X and 4th lengths untouched.
    assert_eq!(
        st.interpreter().unwrap().table().entry(12),
        Some(&OffsetEntry {
            radius_mm: 10.0,
            length_mm: [11.0, 25.5, -5.0, 14.0]
        })
    );
    let b1 = st.next().unwrap().unwrap();
    assert_eq!(
        b1.comp,
        Comp::Left {
            d: 12,
            radius_mm: 10.0
        }
    );
    assert_eq!(st.next().unwrap().unwrap().comp, Comp::Off);
    assert!(st.next().is_none());
    // The setup's table (what the daemon holds) is not touched by interpretation.
    assert_eq!(s.offsets.entry(12).unwrap().radius_mm, 1.0);
}

#[test]
fn g92_needs_an_entry_and_no_motion() {
    assert_refused("G92 R0=1", DiagCode::G92NeedsEntry);
    assert_refused("G92 D0 R0=1", DiagCode::G92NeedsEntry);
    assert_refused("G92 D100 R0=1", DiagCode::WordOutOfRange);
    assert_refused("G92 D1 X5 R0=1", DiagCode::G92WithMotion);
    let c = compile("G92 D3", &mill());
    assert!(!c.has_errors());
    assert_eq!(c.diagnostics[0].severity, Severity::Warning);
}

#[test]
fn g92_in_the_length_offset_entry_moves_later_blocks() {
    let s = with_entry_12();
    let b = ok("&12 G0 Z0\nG92 D12 R3=-5.0\nG0 Z0", &s);
    assert_eq!(b[0].motion().unwrap().1[2], 13.0);
    assert_eq!(b[2].motion().unwrap().1[2], -5.0);
}

// ---- Radius compensation words (SPEC §4.1, §4.2) -----------------------------------------

#[test]
fn g41_without_a_tool_is_an_error() {
    let e = first_error("N5 G41 G1 X10 F100", &mill());
    assert_eq!((e.block, e.line, e.column), (Some(5), 1, 4));
    assert_eq!(e.code, DiagCode::CompWithoutTool, "{}", e.message);
    assert!(compile("D0 G41 G1 X10 F100", &mill()).has_errors());
}

#[test]
fn compensation_carries_the_radius_of_the_selected_entry() {
    let s = with_entry_12();
    let b = ok("D12\nG42 G1 X10 F100\nX20\nG40 X30", &s);
    assert_eq!(b[0].comp, Comp::Off);
    assert_eq!(
        b[1].comp,
        Comp::Right {
            d: 12,
            radius_mm: 1.0
        }
    );
    assert_eq!(
        b[2].comp,
        Comp::Right {
            d: 12,
            radius_mm: 1.0
        }
    );
    assert_eq!(b[3].comp, Comp::Off);
}

#[test]
fn compensation_rules_checked_by_the_interpreter() {
    let s = with_entry_12();
    let e = first_error("D12 G41 G1 X10 F100\nG18", &s);
    assert_eq!(e.code, DiagCode::PlaneChangeUnderComp, "{}", e.message);
    let e = first_error("D12 G41 G1 X10 F100\nG42 X20", &s);
    assert_eq!(e.code, DiagCode::CompSideSwitch, "{}", e.message);
    let mut s6 = s.clone();
    s6.constants.set(397, 100.0); // 00100.000: decade 6 = 1
    ok("D12 G41 G1 X10 F100\nG42 X20", &s6);
    let e = first_error("D12 G41 G1 X10 F100\nG40 Z5", &s);
    assert_eq!(e.code, DiagCode::G40WithoutMotion, "{}", e.message);
    let mut s7 = s.clone();
    s7.constants.set(339, 1000.0); // 01000.000: decade 7 = 1
    ok("D12 G41 G1 X10 F100\nG40 Z5", &s7);
    let e = first_error("D12 G1 X10 F100\nG41 G2 X20 Y0 I5 J0", &s);
    assert_eq!(e.code, DiagCode::CompChangeOnArc, "{}", e.message);
}

// ---- Feed (SPEC §5) -----------------------------------------------------------------------

#[test]
fn feed_units_and_limits() {
    let b = ok(
        "G1 X1 F1000\nX2 F.5\nX3 F90000\nS1000 M3\nG95 X4 F1000\nX5 F0.2\nX6 F99999\nX7 F99.999",
        &mill(),
    );
    let f: Vec<Feed> = b.iter().map(|b| b.feed).collect();
    assert_eq!(f[0], Feed::MmPerMin(1000.0));
    assert_eq!(f[1], Feed::MmPerMin(500.0));
    assert_eq!(f[2], Feed::MmPerMin(90000.0));
    assert_eq!(f[4], Feed::MmPerRev(1.0));
    assert_eq!(f[5], Feed::MmPerRev(0.2));
    assert_eq!(f[6], Feed::MmPerRev(99.999));
    assert_eq!(f[7], Feed::MmPerRev(99.999));
    assert_refused("G1 X1 F90001", DiagCode::FeedOutOfRange);
    assert_refused("G1 X1 F90.1", DiagCode::FeedOutOfRange);
    let e = first_error("S100 M3 G95 G1 X1 F100000", &mill());
    assert_eq!(e.code, DiagCode::FeedOutOfRange, "{}", e.message);
}

#[test]
fn g95_needs_a_turning_spindle() {
    let e = first_error("G95 G1 X1 F100", &mill());
    assert_eq!(e.code, DiagCode::FeedPerRevWithoutSpindle, "{}", e.message);
    assert!(compile("S500 G95 G1 X1 F100", &mill()).has_errors());
    ok("S500 M4 G95 G1 X1 F100", &mill());
}

#[test]
fn feed_must_be_programmed_again_after_a_unit_change() {
    let e = first_error("M3 S100 G1 X1 F100\nG95 X2", &mill());
    assert_eq!(e.code, DiagCode::FeedModeChanged, "{}", e.message);
}

#[test]
fn m37_scales_the_feed_by_a_hundredth() {
    let b = ok("G1 X1 F1000 M37\nX2 M36", &mill());
    assert_eq!(b[0].feed, Feed::MmPerMin(10.0));
    assert_eq!(b[1].feed, Feed::MmPerMin(1000.0));
    assert_eq!(b[0].m, [Some(37), None, None, None]);
}

// ---- Spindle, constant cutting speed (SPEC §6 words) -------------------------------------

#[test]
fn lathe_example_with_r329_swap() {
    let mut s = Setup::new(&['X', 'Z']);
    s.constants.set(329, 0.3); // decade 3 = 3: swap G96/G97 and S in m/min
    let b = ok(
        "N10 G0 X300 Z100 M44 M3 S100 “rapid to diameter 300\nN15 Z-1\nN20 G96 G1 F200 S90 X50",
        &s,
    );
    let sp = b[0].spindle;
    assert_eq!(
        (sp.dir, sp.s, sp.gear, sp.css),
        (SpindleDir::Cw, 100.0, 4, false)
    );
    assert_eq!(b[2].feed, Feed::MmPerRev(0.2));
    assert!(b[2].spindle.css);
    assert_eq!(b[2].spindle.s, 90.0);
    // Without the swap the same block is written G97 ... S900.
    let b = ok(
        "N10 G0 X300 Z100 M44 M3 S100\nN15 Z-1\nN20 G97 G1 F200 S900 X50",
        &Setup::new(&['X', 'Z']),
    );
    assert_eq!(b[2].feed, Feed::MmPerRev(0.2));
    assert_eq!(b[2].spindle.s, 900.0);
}

#[test]
fn g76_sets_the_limit_not_the_speed() {
    let b = ok("S500 M3\nN100 G76 S2000", &mill());
    assert_eq!(b[1].spindle.limit_rpm, 2000.0);
    assert_eq!(b[1].spindle.s, 500.0);
    assert_refused("G76", DiagCode::G76NeedsS);
}

#[test]
fn leaving_css_without_s_keeps_the_reached_speed_for_g95() {
    // After G96 ends with G95 and no S, the runtime keeps the last reached speed (SPEC §6).
    let b = ok("M3 G96 S500\nG95 G1 X10 F100", &mill());
    assert!(!b[1].spindle.css);
    assert_eq!(b[1].spindle.s, 0.0);
}

#[test]
fn spindle_m_conflicts() {
    assert_refused("M3 M4", DiagCode::MGroupConflict);
    assert_refused("M36 M37", DiagCode::MGroupConflict);
    assert_refused("M1 M2 M3 M5 M8", DiagCode::TooManyMFunctions);
}

// ---- Continuity and dynamic sets (SPEC §7.1, §7.4) ---------------------------------------

#[test]
fn continuity_modes_and_dynamic_sets() {
    let b = ok(
        "G1 X1 F100\nG23 I2 X2\nX3\nG24 X4\nG98 I4\nG23 G2 X14 Y0 I5 J0",
        &mill(),
    );
    let c: Vec<(Continuity, u8)> = b.iter().map(|b| (b.continuity, b.dyn_set)).collect();
    assert_eq!(
        c,
        [
            (Continuity::G98, 1),
            (Continuity::G23, 2),
            (Continuity::G23, 2),
            (Continuity::G24, 2),
            (Continuity::G98, 4),
            (Continuity::G23, 4), // I is the arc centre here
        ]
    );
    assert_refused("G23 I5", DiagCode::WordOutOfRange);
    // After an arc (G2 still modal) G23 I3 alone selects the set; it is not a circle.
    let b = ok("G2 X10 Y0 I5 J0 F100\nG23 I3", &mill());
    assert_eq!((b[1].kind, b[1].dyn_set), (BlockKind::Technology, 3));
}

// ---- Parameters, length offsets, modal state ---------------------------------------------

#[test]
fn parameters_are_assigned_and_used_with_their_decimal_point() {
    let b = ok(
        "R1=1000 R2=1.5 R3=-2\nG1 XR3 FR1\nX-R3 FR2\nR4=R2 YR4",
        &mill(),
    );
    assert_eq!(b[1].motion().unwrap().1[0], -2.0);
    assert_eq!(b[1].feed, Feed::MmPerMin(1000.0));
    assert_eq!(b[2].motion().unwrap().1[0], 2.0);
    assert_eq!(b[2].feed, Feed::MmPerMin(1500.0));
    assert_eq!(b[3].motion().unwrap().1[1], 1.5);
    let e = first_error("N4 G0 XR9", &mill());
    assert_eq!(e.code, DiagCode::ParamUnassigned, "{}", e.message);
    assert_eq!(e.column, 7);
}

#[test]
fn length_offsets_shift_the_axes_of_the_entry() {
    let s = with_entry_12();
    let b = ok("G0 X0 Y0 Z0\n&12\nG0 X1\nG1 Z-1 F100\n&0 G0 Z5", &s);
    assert_eq!(&b[2].motion().unwrap().1.0[..4], &[12.0, 12.0, 13.0, 14.0]);
    assert_eq!(&b[3].motion().unwrap().1.0[..4], &[12.0, 12.0, 12.0, 14.0]);
    assert_eq!(&b[4].motion().unwrap().1.0[..4], &[1.0, 0.0, 5.0, 0.0]);
    let e = first_error("&12\nG2 X10 Y0 I5 J0 F100", &s);
    assert_eq!(e.code, DiagCode::ArcAfterOffsetChange, "{}", e.message);
}

#[test]
fn incremental_positions_and_start_point() {
    let mut s = mill();
    s.start[0] = 100.0;
    let b = ok("G91 G0 X10\nX10\nG90 X0", &s);
    let ends: Vec<f64> = b.iter().map(|b| b.motion().unwrap().1[0]).collect();
    assert_eq!(ends, [110.0, 120.0, 0.0]);
    assert_eq!(b[0].motion().unwrap().0[0], 100.0);
}

#[test]
fn a_bad_block_changes_no_state() {
    // N2 fails on its feed: its G91, X, S and R1 must not stick.
    let c = compile(
        "N1 G1 X10 F100\nN2 G91 X5 S77 R1=3 F100000\nN3 X1\nN4 G0 XR1",
        &mill(),
    );
    let errs: Vec<_> = c.diagnostics.iter().map(|d| d.block).collect();
    assert_eq!(errs, [Some(2), Some(4)], "{:?}", c.diagnostics);
    let mut st = stream("N1 G1 X10 F100\nN2 G91 X5 S77 F100000\nN3 X1", &mill());
    st.next();
    assert!(st.next().unwrap().is_err());
    let b = st.next().unwrap().unwrap();
    assert_eq!(b.motion().unwrap().1[0], 1.0);
    assert_eq!(b.spindle.s, 0.0);
}

#[test]
fn every_error_is_located_and_all_are_reported() {
    let text = "N1 G1 X1 F100\nN2 G1 X2 Q4\nN3 G7\n\nN5 X1.2.3\nN6 G1 G2 X1\n";
    let c = compile(text, &mill());
    let got: Vec<(Option<u32>, u32, u32)> = c
        .diagnostics
        .iter()
        .map(|d| (d.block, d.line, d.column))
        .collect();
    assert_eq!(
        got,
        [
            (Some(2), 2, 10),
            (Some(3), 3, 4),
            (Some(5), 5, 8),
            (Some(6), 6, 7),
        ]
    );
    assert_eq!(c.diagnostics[1].code, DiagCode::UnknownGFunction);
}

#[test]
fn columns_count_characters_not_bytes() {
    // “ and Ř are multi-byte; the column of Q is still 4.
    let e = first_error("X1 Q2 “Ř", &mill());
    assert_eq!(e.column, 4);
    let e = first_error("; Řez\nŘ1", &mill());
    assert_eq!((e.line, e.column), (2, 1));
}

#[test]
fn remarks_comments_and_crlf() {
    let b = ok(
        "; program header\r\nN10 G0 X10 ; rapid\r\nN20 G1 X20 F100 \"cut\r\n\r\n",
        &mill(),
    );
    assert_eq!(b.len(), 2);
    assert_eq!((b[1].n, b[1].line), (Some(20), 3));
}

#[test]
fn setup_with_a_reserved_axis_letter_is_refused() {
    let c = compile("G0 X1", &Setup::new(&['X', 'F']));
    assert!(c.has_errors());
    assert_eq!(c.diagnostics[0].code, DiagCode::AxisNamesInvalid);
}

// ---- Streaming and validation agree with compile -----------------------------------------

#[test]
fn stream_and_validate_agree_with_compile() {
    let mut text = String::new();
    for k in 0..2000 {
        text.push_str(&format!(
            "N{k} G1 X{}.{} Y{} F{}\n",
            k % 97,
            k % 10,
            k % 13,
            100 + k
        ));
        if k % 500 == 0 {
            text.push_str("G2 X-1 Y0 I1 J1\n"); // wrong circle → error every 500 blocks
        }
    }
    let setup = mill();
    let c = compile(&text, &setup);
    assert_eq!(validate(&text, &setup), c.diagnostics);
    assert_eq!(c.diagnostics.len(), 4);
    let good = text.replace("G2 X-1 Y0 I1 J1\n", "");
    let c = compile(&good, &setup);
    let streamed: Vec<Block> = stream(&good, &setup).map(Result::unwrap).collect();
    assert_eq!(streamed, c.blocks);
    assert_eq!(streamed.len(), 2000);
}

#[test]
fn a_flood_of_errors_is_capped() {
    let text = "Q\n".repeat(5000);
    let d = validate(&text, &mill());
    assert_eq!(d.len(), kernel::program::MAX_DIAGNOSTICS + 1);
    assert_eq!(d.last().unwrap().code, DiagCode::TooManyErrors);
}

#[test]
fn many_warnings_do_not_stop_a_valid_program() {
    // 3000 warnings (G92 writing nothing), then an error at the very end that must be found.
    let text = format!("{}G1 X1\n", "G92 D1\n".repeat(3000));
    let d = validate(&text, &mill());
    let errors: Vec<_> = d.iter().filter(|d| d.is_error()).collect();
    assert_eq!(errors.len(), 1, "{:?}", errors);
    assert_eq!(errors[0].line, 3001);
    assert_eq!(d.last().unwrap().code, DiagCode::MessagesNotListed);
    let ok_text = "G92 D1\n".repeat(3000);
    assert!(!validate(&ok_text, &mill()).iter().any(Diagnostic::is_error));
}

#[test]
fn offsets_table_default_is_zero() {
    assert_eq!(OffsetTable::new().entry(1).unwrap().radius_mm, 0.0);
    assert!(OffsetTable::new().entry(0).is_none());
}

#[test]
fn setup_from_machine_constants_and_bom() {
    let mut c = kernel::constants::Constants::new();
    c.set(0, 1.0);
    c.set(1, 3.0); // lathe: X, Z
    c.set(2, 0.0);
    let s = Setup::from_machine(c, OffsetTable::new());
    assert_eq!(s.axis_names, ['X', 'Z']);
    let b = ok("\u{FEFF}N1 G0 X10 Z5", &s);
    assert_eq!(&b[0].motion().unwrap().1.0[..2], &[10.0, 5.0]);
}

#[test]
fn the_interpreter_paths_of_callers_stay() {
    // Callers name these paths; the dialect's code lives in program::cnc836.
    assert_eq!(
        kernel::program::interpreter::RESERVED_LETTERS,
        "NGIJEFSMDRLP"
    );
    let _: Option<kernel::program::interpreter::Interpreter> = None;
    let _: Option<kernel::program::interpreter::Modal> = None;
    let t: Vec<_> = kernel::program::words::Lexer::new("X1").collect();
    assert!(matches!(
        t[0],
        Ok(kernel::program::words::Lexed {
            token: kernel::program::words::Token::Word { letter: b'X', .. },
            ..
        })
    ));
}
