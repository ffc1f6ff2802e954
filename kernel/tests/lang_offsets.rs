//! TAB0.KOR parsing and writing (SPEC §3), with the manual's example.

use kernel::DiagCode;
use kernel::offsets::{self, OffsetEntry, OffsetTable, TableEdit, parse, parse_edit, write};

const MILL: [char; 4] = ['X', 'Y', 'Z', 'U'];
const LATHE: [char; 2] = ['X', 'Z'];

/// The example file of seed 000 §7.1 (its first table).
const MANUAL: &str = "Offsets of machine 3, edited 12.5.\n$KOR      \n01: R=10.0 X=20.0 Y=30.0 Z=40.0  \n02: R=0.8 X=0.0 2=0.0   \n03: R=0.8 X=0.0 Y=120.0 Z=0.0 4=0.0 \n25:  X=85.0 Y=45.5 Z=0.0  \n95: R=0.0 1=12.55 2=0.0 3=0.0 4=0.0 \n";

fn e(r: f64, l: [f64; 4]) -> OffsetEntry {
    OffsetEntry {
        radius_mm: r,
        length_mm: l,
    }
}

#[test]
fn manual_example_parses_to_the_stated_values() {
    let f = parse(MANUAL, &MILL).unwrap();
    assert_eq!(f.comment, "Offsets of machine 3, edited 12.5.\n");
    let t = &f.table;
    assert_eq!(t.entry(1), Some(&e(10.0, [20.0, 30.0, 40.0, 0.0])));
    assert_eq!(t.entry(2), Some(&e(0.8, [0.0; 4])));
    assert_eq!(t.entry(3), Some(&e(0.8, [0.0, 120.0, 0.0, 0.0])));
    // Entry 25 has no R=: radius zero.
    assert_eq!(t.entry(25), Some(&e(0.0, [85.0, 45.5, 0.0, 0.0])));
    assert_eq!(t.entry(95), Some(&e(0.0, [12.55, 0.0, 0.0, 0.0])));
    // Every entry not listed is zero.
    for n in (1..=99).filter(|n| ![1, 2, 3, 25, 95].contains(n)) {
        assert!(t.entry(n).unwrap().is_zero(), "entry {n}");
    }
}

#[test]
fn lathe_rule_axis_two_must_be_written_2() {
    let ok = "$KOR\n02: R=0.8 X=1.0 2=2.0\n";
    let t = parse(ok, &LATHE).unwrap().table;
    assert_eq!(t.entry(2), Some(&e(0.8, [1.0, 2.0, 0.0, 0.0])));
    let errs = parse("$KOR\n02: R=0.8 X=1.0 Z=2.0\n", &LATHE).unwrap_err();
    assert_eq!((errs[0].line, errs[0].column), (2, 17));
    assert_eq!(
        errs[0].code,
        DiagCode::OffsetAxisByOrdinal,
        "{}",
        errs[0].message
    );
    // The manual's mixed example is a mill file: on a lathe its Y and Z names are refused.
    let errs = parse(MANUAL, &LATHE).unwrap_err();
    let lines: Vec<u32> = errs.iter().map(|d| d.line).collect();
    assert_eq!(lines, [3, 5, 6]);
}

#[test]
fn writer_uses_names_only_where_allowed() {
    let mut t = OffsetTable::new();
    t.set_entry(7, e(1.5, [2.0, -3.25, 4.0, 0.0])).unwrap();
    let f = offsets::KorFile {
        comment: "lathe 2\n".into(),
        table: t.clone(),
    };
    assert_eq!(
        write(&f, &LATHE),
        "lathe 2\n$KOR\n07: R=1.5 X=2.0 2=-3.25 3=4.0 4=0.0\n"
    );
    assert_eq!(
        write(&f, &MILL),
        "lathe 2\n$KOR\n07: R=1.5 X=2.0 Y=-3.25 Z=4.0 U=0.0\n"
    );
    assert_eq!(parse(&write(&f, &LATHE), &LATHE).unwrap(), f);
}

#[test]
fn rejected_files_name_line_and_column() {
    let cases: [(&str, u32, u32, DiagCode); 6] = [
        ("$KOR\n00: R=1\n", 2, 1, DiagCode::OffsetNoEntry),
        ("$KOR\n100: R=1\n", 2, 1, DiagCode::OffsetNoEntry),
        ("$KOR\n01: R=abc\n", 2, 7, DiagCode::OffsetValueSyntax),
        ("$KOR\n1: R=1\n", 2, 1, DiagCode::OffsetEntryNotTwoDigits),
        ("01: R=1\n", 1, 1, DiagCode::OffsetKorMissing),
        ("$KOR\n01: R=1\n01: R=2\n", 3, 1, DiagCode::OffsetEntryTwice),
    ];
    for (text, line, col, code) in cases {
        let errs = parse(text, &MILL).unwrap_err();
        assert_eq!((errs[0].line, errs[0].column), (line, col), "{text:?}");
        assert_eq!(errs[0].code, code, "{text:?}: {}", errs[0].message);
    }
}

#[test]
fn edits_change_only_the_values_present_and_bad_edits_nothing() {
    let mut t = parse(MANUAL, &MILL).unwrap().table;
    let before = t.clone();
    let ed = parse_edit("01: R=5.0 Z=-3", &MILL).unwrap();
    assert_eq!(
        ed,
        TableEdit {
            entry: 1,
            values: [Some(5.0), None, None, Some(-3.0), None]
        }
    );
    t.apply(&ed).unwrap();
    assert_eq!(t.entry(1), Some(&e(5.0, [20.0, 30.0, -3.0, 0.0])));
    for bad in [
        "00: R=1",
        "100: R=1",
        "01: R=x",
        "01 R=1",
        "01: Q=1",
        "01: R=1e3",
    ] {
        assert!(parse_edit(bad, &MILL).is_err(), "{bad}");
    }
    let mut t2 = before.clone();
    let bad = TableEdit {
        entry: 100,
        values: [Some(1.0); 5],
    };
    let refused = t2.apply(&bad).unwrap_err();
    assert_eq!(refused, offsets::OffsetError::NoEntry(100));
    assert_eq!(refused.code(), DiagCode::OffsetNoEntry);
    let bad = TableEdit {
        entry: 1,
        values: [Some(1.0), Some(f64::NAN), None, None, None],
    };
    let refused = t2.apply(&bad).unwrap_err();
    assert_eq!(refused.code(), DiagCode::OffsetValueOutOfRange);
    assert_eq!(t2, before, "a refused edit changes nothing");
}
