//! R325 circle refinement made visible (issue #18, SPEC §4.6): the interpreter reports each
//! refinement as address E, and the listing writes E into the program the way the manual
//! shows. The listing is faithful: read back without refinement, it gives the same blocks.

use kernel::program::arc::Corrected;
use kernel::program::{Setup, compile, refinement_listing};
use kernel::{DiagCode, Severity};

fn mill(refine: bool) -> Setup {
    let mut s = Setup::new(&['X', 'Y', 'Z']);
    s.constants.set(55, 0.0005); // 0.5 µm: only exact circles pass
    if refine {
        s.constants.set(325, 10000.010); // on, limit 10 µm
    }
    s
}

/// Quarter circle radius 10 about (0,10) from (0,0) to (10,10), centre written 3 µm off in I;
/// then an arc whose J is 6.992 µm too large (the manual's second example, J corrected).
const PROGRAM: &str = "N10 G1 X0 Y0 F100\n\
N20 G3 X10 Y10 I0.003 J10 ; fillet\n\
N30 G1 X20\n\
N40 G3 X20 Y30 I-10 J10.006992\n";

#[test]
fn refinements_are_reported_and_written_as_e() {
    let (text, refined, diags) = refinement_listing(PROGRAM, &mill(true));
    assert!(!diags.iter().any(|d| d.is_error()), "{diags:?}");
    assert_eq!(refined.len(), 2, "{refined:?}");
    assert_eq!((refined[0].n, refined[0].line), (Some(20), 2));
    assert_eq!(refined[0].refinement.which, Corrected::I);
    assert_eq!(refined[1].refinement.which, Corrected::J);
    // Validation reports each refinement on its block.
    let refined_blocks: Vec<_> = diags
        .iter()
        .filter(|d| d.severity == Severity::Info && d.code == DiagCode::ArcRefined)
        .map(|d| d.block)
        .collect();
    assert_eq!(refined_blocks, [Some(20), Some(40)], "{diags:?}");
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[1], "N20 G3 X10 Y10 I0.003 J10 E-3.000 ; fillet");
    assert_eq!(lines[3], "N40 G3 X20 Y30 I-10 J10.006992 E-10006.992");
    assert_eq!((lines[0], lines[2]), ("N10 G1 X0 Y0 F100", "N30 G1 X20"));
    // Read back with refinement off: the E words alone make the circles consistent, and the
    // blocks are exactly those of the refined original.
    let original = compile(PROGRAM, &mill(true));
    let listed = compile(&text, &mill(false));
    assert!(!listed.has_errors(), "{:?}", listed.diagnostics);
    assert_eq!(
        format!("{:?}", original.blocks),
        format!("{:?}", listed.blocks)
    );
    // Refinement on again: the listing needs none.
    let (again, refined, _) = refinement_listing(&text, &mill(true));
    assert!(refined.is_empty());
    assert_eq!(again, text);
}

// A programmed E on the same coordinate is replaced by the total.
#[test]
fn programmed_e_is_replaced_by_the_total() {
    // A half circle (horizontal chord): only I can be refined.
    let text = "N10 G1 X0 Y0 F100\nN20 G3 X20 Y0 I10.003 J0 E-1.000 F100\n";
    let (listing, refined, _) = refinement_listing(text, &mill(true));
    assert_eq!(refined.len(), 1, "{refined:?}");
    assert_eq!(
        listing.lines().nth(1),
        Some("N20 G3 X20 Y0 I10.003 J0 E-3.000 F100")
    );
    assert!(!compile(&listing, &mill(false)).has_errors());
}
