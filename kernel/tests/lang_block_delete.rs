//! Block delete (issue #31, docs/language.md "Block delete"): a block whose first character
//! (after spaces) is `/` is skipped while the switch is on, and runs as if the `/` were not
//! there while it is off. Line numbers and columns stay those of the text.

use kernel::DiagCode;
use kernel::program::{Setup, compile};

fn mill(block_delete: bool) -> Setup {
    let mut s = Setup::new(&['X', 'Y', 'Z']);
    s.block_delete = block_delete;
    s
}

const TEXT: &str = "N10 G1 X10 F500\n/N20 X20\n  / N30 Y5\nN40 X30\n";

#[test]
fn slashed_blocks_are_skipped_with_the_switch_on() {
    let c = compile(TEXT, &mill(true));
    assert!(!c.has_errors(), "{:?}", c.diagnostics);
    let ns: Vec<_> = c.blocks.iter().map(|b| (b.n, b.line)).collect();
    assert_eq!(ns, vec![(Some(10), 1), (Some(40), 4)]);
}

#[test]
fn slashed_blocks_run_with_the_switch_off() {
    let text = "N10 G1 X10 F500\n/N20 X20\n  / N30 Y5\n";
    let c = compile(text, &mill(false));
    assert!(!c.has_errors(), "{:?}", c.diagnostics);
    let ns: Vec<_> = c.blocks.iter().map(|b| (b.n, b.line)).collect();
    assert_eq!(ns, vec![(Some(10), 1), (Some(20), 2), (Some(30), 3)]);
}

#[test]
fn a_slash_inside_a_block_is_still_an_error_at_its_column() {
    let c = compile("N10 G1 X10 F500\n/N20 X20 /\n", &mill(false));
    let e = c.diagnostics.iter().find(|d| d.is_error()).unwrap();
    assert_eq!((e.line, e.column), (2, 10), "{e:?}");
    assert_eq!(e.code, DiagCode::UnexpectedCharacter);
}
