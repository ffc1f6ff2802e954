//! The compensator's fuzzing entry (`kernel::comp::fuzz::fuzz_entry`, also the cargo-fuzz
//! target `fuzz/fuzz_targets/comp.rs`) on stable: random open and closed contours of lines
//! and arcs, both sides, every R339 mode and random R397/R764/R765/R234 settings. No panic,
//! no non-finite output, and every place where the tool centre comes closer than the radius
//! to the contour is named by a gouge message (issue #18).

use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(600))]

    #[test]
    fn compensator_fuzz_entry_on_random_bytes(data in prop::collection::vec(any::<u8>(), 0..200)) {
        kernel::comp::fuzz::fuzz_entry(&data);
    }
}

// Hand-picked inputs: an empty input, a closed polygon with arcs in every corner mode.
#[test]
fn compensator_fuzz_entry_on_fixed_inputs() {
    kernel::comp::fuzz::fuzz_entry(&[]);
    for mode in 0..4u8 {
        let mut d = vec![mode, 0, 80, 1, 0, 0, 0, 255, 40, 3, 1, 11, 1];
        d.extend((0..120).map(|i| (i * 37 % 251) as u8));
        kernel::comp::fuzz::fuzz_entry(&d);
    }
}

/// A cargo-fuzz finding: a closed polygon of arcs, tool radius 14.85 mm inside a concave arc
/// of R 15.49 (N40). Its tool-centre arc, joined to N30's within the arc-end tolerance, runs
/// 8 µm closer than the radius to N40 itself, and the gouge check did not measure a piece
/// against its own element: the gouges of N30 and N50 were reported, N40's was not. The entry
/// asserts that a gouge message names N40.
#[test]
fn a_tool_centre_arc_off_its_own_equidistant_is_named() {
    let data = std::fs::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/comp_fuzz_own_arc_gouge.bin"
    ))
    .unwrap();
    kernel::comp::fuzz::fuzz_entry(&data);
}
