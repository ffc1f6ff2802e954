//! TAB0.KOR file vs memory table (SPEC §3 (a)-(c)) and the constants file.

use std::path::PathBuf;

use daemon::runtime::storage::{
    OffsetStore, StorageError, load_constants, save_constants, temp_path, write_atomic,
};
use kernel::constants::Constants;
use kernel::offsets::{OffsetEntry, TableEdit};

const AXES: [char; 3] = ['X', 'Y', 'Z'];

fn dir(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("storage_tables_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

const FILE: &str = "machine 1\n$KOR\n01: R=10.0 X=20.0 Y=30.0 Z=40.0\n12: R=1.0 X=2.0\n";

#[test]
fn g92_writes_memory_only_and_saving_the_file_replaces_memory() {
    let d = dir("g92");
    let path = d.join("TAB0.KOR");
    std::fs::write(&path, FILE).unwrap();
    let mut s = OffsetStore::load(&path, &AXES).unwrap();
    assert_eq!(s.memory(), &s.file().table);

    // (c) N10 G92 D12 R0=10.0 R2=25.5 R3=-5.0
    s.program_write(&TableEdit {
        entry: 12,
        values: [Some(10.0), None, Some(25.5), Some(-5.0), None],
    })
    .unwrap();
    assert_eq!(
        s.memory().entry(12),
        Some(&OffsetEntry {
            radius_mm: 10.0,
            length_mm: [2.0, 25.5, -5.0, 0.0]
        })
    );
    assert_eq!(
        std::fs::read_to_string(&path).unwrap(),
        FILE,
        "file untouched"
    );

    // (b) operator edit of another entry: file and memory; the G92 value in memory stays.
    s.operator_edit_text("05: R=3.5").unwrap();
    assert_eq!(s.memory().entry(5).unwrap().radius_mm, 3.5);
    assert_eq!(s.memory().entry(12).unwrap().radius_mm, 10.0);
    let reloaded = OffsetStore::load(&path, &AXES).unwrap();
    assert_eq!(reloaded.memory().entry(5).unwrap().radius_mm, 3.5);
    assert_eq!(
        reloaded.memory().entry(12).unwrap().radius_mm,
        1.0,
        "G92 never reaches the file"
    );
    assert!(
        reloaded.file().comment.starts_with("machine 1"),
        "comment kept"
    );

    // (a) saving the file replaces memory, G92 values included.
    s.save_file_text("$KOR\n12: R=2.0\n").unwrap();
    assert_eq!(s.memory().entry(12).unwrap().radius_mm, 2.0);
    assert!(s.memory().entry(5).unwrap().is_zero());
    assert_eq!(std::fs::read_to_string(&path).unwrap(), "$KOR\n12: R=2.0\n");
    assert!(!temp_path(&path).exists());
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn rejected_edits_change_neither_file_nor_memory() {
    let d = dir("reject");
    let path = d.join("TAB0.KOR");
    std::fs::write(&path, FILE).unwrap();
    let mut s = OffsetStore::load(&path, &AXES).unwrap();
    let mem = s.memory().clone();
    for bad in [
        "00: R=1",
        "100: R=1",
        "01: R=abc",
        "01 R=1",
        "01: R=",
        "01: Q=1",
    ] {
        let e = s.operator_edit_text(bad).unwrap_err();
        assert!(matches!(e, StorageError::Invalid { .. }), "{bad}: {e}");
    }
    let e = s
        .operator_edit(&TableEdit {
            entry: 100,
            values: [Some(1.0); 5],
        })
        .unwrap_err();
    assert!(e.to_string().contains("01..99"), "{e}");
    for bad in ["$KOR\n00: R=1\n", "no keyword\n", "$KOR\n01: R=1,5\n"] {
        assert!(s.save_file_text(bad).is_err(), "{bad}");
    }
    assert!(
        s.program_write(&TableEdit {
            entry: 0,
            values: [Some(1.0); 5]
        })
        .is_err()
    );
    assert_eq!(s.memory(), &mem);
    assert_eq!(std::fs::read_to_string(&path).unwrap(), FILE);
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn a_missing_file_is_an_empty_table_until_the_first_save() {
    let d = dir("missing");
    let path = d.join("TAB0.KOR");
    assert!(OffsetStore::load(&path, &AXES).is_err());
    let mut s = OffsetStore::load_or_empty(&path, &AXES).unwrap();
    assert!(s.memory().iter_nonzero().next().is_none());
    s.operator_edit_text("07: Z=1.5").unwrap();
    assert_eq!(std::fs::read_to_string(&path).unwrap(), "$KOR\n07: Z=1.5\n");
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn constants_file_round_trip_and_refusal() {
    let d = dir("consts");
    let path = d.join("TAB0.REK");
    let mut c = Constants::new();
    c.set(339, -21140.0);
    c.set(325, 20003.0);
    save_constants(&path, &c).unwrap();
    assert_eq!(load_constants(&path).unwrap(), c);
    let mut bad = c.clone();
    bad.set(325, 10004.0); // refinement limit above 3 mm
    assert!(save_constants(&path, &bad).is_err());
    assert_eq!(
        load_constants(&path).unwrap(),
        c,
        "refused save leaves the file"
    );
    write_atomic(&path, b"R325=10004.000\n").unwrap();
    assert!(
        load_constants(&path)
            .unwrap_err()
            .to_string()
            .contains("3.000 mm")
    );
    std::fs::remove_dir_all(&d).unwrap();
}
