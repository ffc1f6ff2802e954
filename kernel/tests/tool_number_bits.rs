//! The automatic tool changer (docs/setup.md "Automatic tool changer"): M6 stays a tool
//! change (the daemon's RT core runs the changer's sequence at it); a tool its tool number
//! outputs cannot carry is refused with the program.

use kernel::DiagCode;
use kernel::block::BlockKind;
use kernel::offsets::OffsetEntry;
use kernel::program::{Dialect, Setup, compile};

fn setup(dialect: Dialect, bits: Option<u8>) -> Setup {
    let mut s = Setup::new(&['X', 'Y', 'Z']);
    s.dialect = dialect;
    for n in 1..=4 {
        let e = OffsetEntry {
            radius_mm: 1.0,
            length_mm: [0.0, 0.0, 10.0, 0.0],
        };
        s.offsets.set_entry(n, e).unwrap();
    }
    s.tool_number_bits = bits;
    s
}

#[test]
fn a_tool_beyond_the_number_outputs_is_a_program_error() {
    for dialect in [Dialect::Cnc836, Dialect::Iso] {
        let c = compile("T4 M6\n", &setup(dialect, Some(2)));
        assert_eq!(
            c.diagnostics.iter().map(|d| d.code).collect::<Vec<_>>(),
            [DiagCode::ToolNumberBeyondOutputs],
            "{dialect:?}"
        );
        let c = compile("T3 M6\n", &setup(dialect, Some(2)));
        assert!(!c.has_errors(), "{dialect:?}: {:?}", c.diagnostics);
        assert!(
            c.blocks
                .iter()
                .any(|b| matches!(b.kind, BlockKind::ToolChange { tool: 3 })),
            "{dialect:?}: M6 stays one tool change"
        );
        let c = compile("T4 M6\n", &setup(dialect, None));
        assert!(!c.has_errors(), "{dialect:?}: no limit without a changer");
    }
}
