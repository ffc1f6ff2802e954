//! The automatic tool changer (issue #47, docs/setup.md "Automatic tool changer"): M6 becomes
//! the configured steps (tool number outputs, then each M of the sequence) in both dialects,
//! without a hold; the outputs the steps leave are the program's afterwards.

use kernel::DiagCode;
use kernel::block::{Block, BlockKind, ProgramStop, SpindleDir};
use kernel::offsets::OffsetEntry;
use kernel::outputs::{MFunction, MFunctions};
use kernel::program::tool_changer::ToolChanger;
use kernel::program::{Dialect, Setup, compile};

/// Outputs: 0 coolant (M8/M9), 1 and 2 the tool number, 3 the unclamp valve (M61 on, M63
/// off). Inputs: 0 unclamped (confirms M62), 1 clamped (confirms M63).
fn setup(dialect: Dialect) -> Setup {
    let mut s = Setup::new(&['X', 'Y', 'Z']);
    s.dialect = dialect;
    for (n, z) in [(1, 10.0), (2, 25.5), (3, 30.0)] {
        let e = OffsetEntry {
            radius_mm: 1.0,
            length_mm: [0.0, 0.0, z, 0.0],
        };
        s.offsets.set_entry(n, e).unwrap();
    }
    let mut m = MFunctions::default();
    for f in [
        MFunction {
            code: 8,
            on: 0b1,
            ..Default::default()
        },
        MFunction {
            code: 9,
            off: 0b1,
            ..Default::default()
        },
        MFunction {
            code: 61,
            on: 0b1000,
            ..Default::default()
        },
        MFunction {
            code: 62,
            wait: 0b01,
            ..Default::default()
        },
        MFunction {
            code: 63,
            off: 0b1000,
            wait: 0b10,
            ..Default::default()
        },
    ] {
        m.add(f);
    }
    s.m_outputs = m;
    s.tool_changer = Some(ToolChanger {
        sequence: vec![61, 62, 63],
        tool_number_outputs: vec![1, 2],
    });
    s
}

/// (M codes, outputs on, waits) of the technology blocks of line `line`.
fn steps(blocks: &[Block], line: u32) -> Vec<(Vec<u16>, u64, u64)> {
    blocks
        .iter()
        .filter(|b| b.line == line && b.kind == BlockKind::Technology)
        .map(|b| {
            let m = b.m.iter().flatten().copied().collect();
            (m, b.spindle.outputs.on, b.spindle.outputs.wait)
        })
        .collect()
}

fn check(dialect: Dialect, text: &str) {
    let c = compile(text, &setup(dialect));
    assert!(!c.has_errors(), "{dialect:?}: {:?}", c.diagnostics);
    for (k, b) in c.blocks.iter().enumerate() {
        assert_eq!(b.seq as usize, k, "{dialect:?}: seq stays dense");
        assert!(
            !matches!(ProgramStop::of_block(b), ProgramStop::ToolChange { .. }),
            "{dialect:?}: no hold for the operator"
        );
    }
    // Line 2: T2 M6 with the coolant on: number 2 (output 2), unclamp, wait, clamp + wait.
    assert_eq!(
        steps(&c.blocks, 2),
        [
            (vec![6], 0b0101, 0),
            (vec![61], 0b1101, 0),
            (vec![62], 0b1101, 0b01),
            (vec![63], 0b0101, 0b10),
        ],
        "{dialect:?}"
    );
    // Line 5: T3 M6: both number bits.
    assert_eq!(steps(&c.blocks, 5)[0], (vec![6], 0b0111, 0), "{dialect:?}");
    let on_line = |line: u32| c.blocks.iter().find(|b| b.line == line).unwrap();
    // The spindle stops at the change; the tool's length is in force after it.
    assert_eq!(on_line(2).spindle.dir, SpindleDir::Stopped, "{dialect:?}");
    let cut = on_line(4);
    assert_eq!(cut.motion().unwrap().1[2], 25.5, "{dialect:?}");
    // Later blocks carry what the sequence left (coolant and number on, unclamp off).
    assert_eq!(cut.spindle.outputs.on, 0b0101, "{dialect:?}");
    assert_eq!(cut.spindle.outputs.wait, 0, "{dialect:?}");
    assert_eq!(
        on_line(6).spindle.outputs.on,
        0b0110,
        "{dialect:?}: M9 after T3"
    );
}

#[test]
fn m6_runs_the_sequence_in_both_dialects() {
    let cnc836 = "N10 M8\nN20 T2 M6\nN30 M3 S1000\nN40 G0 Z0\nN50 T3 M6\nN60 M9\nN70 M30\n";
    check(Dialect::Cnc836, cnc836);
    let iso = "M8\nT2 M6\nM3 S1000\nG43 H2 G0 Z0\nT3 M6\nM9\nM30\n";
    check(Dialect::Iso, iso);
}

#[test]
fn a_tool_beyond_the_number_outputs_is_a_program_error() {
    for dialect in [Dialect::Cnc836, Dialect::Iso] {
        let c = compile("T4 M6\n", &setup(dialect));
        assert_eq!(
            c.diagnostics.iter().map(|d| d.code).collect::<Vec<_>>(),
            [DiagCode::ToolNumberBeyondOutputs],
            "{dialect:?}"
        );
    }
}

#[test]
fn manual_mode_still_holds() {
    let mut s = setup(Dialect::Cnc836);
    s.tool_changer = None;
    let c = compile("T2 M6\n", &s);
    assert!(matches!(
        c.blocks[0].kind,
        BlockKind::ToolChange { tool: 2 }
    ));
}
