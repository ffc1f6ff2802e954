//! PLC memory area 1 as the API sees it (SPEC §6): listing, reads, and refused writes that
//! change nothing.

use kernel::plc::{Access, CATALOGUE, CellId, PlcArea, PlcError, PlcWrite};
use proptest::prelude::*;

/// An area with some history: ACT cells written by the controller, inputs in force and staged.
fn busy_area() -> PlcArea {
    let mut a = PlcArea::new();
    a.set_act(CellId::AkrrActS, 286_479);
    a.set_act(CellId::AkrrActOut, 3520);
    a.write_by_name("AKRR_V", 90_000).unwrap();
    a.write_by_name("AKRR_CNTR", 0b1).unwrap();
    a.begin_tick();
    a.write_by_name("AKRR_SMAX", 1_500_000).unwrap();
    a
}

/// The SPEC §6 table, and our addresses (AKRR_CNTR, DYNAM_SET, the I/O cells).
#[test]
fn catalogue_matches_the_spec_table() {
    let expect = [
        ("AKRR_ACT_V", 0xA178, "mm/min", Access::ReadOnly),
        ("AKRR_ACT_SMAX", 0xA17C, "1/1000 rpm", Access::ReadOnly),
        ("AKRR_ACT_DIST", 0xA180, "1/8 µm", Access::ReadOnly),
        ("AKRR_ACT_VCORR", 0xA184, "mm/min", Access::ReadOnly),
        ("AKRR_ACT_R", 0xA188, "1/8 µm", Access::ReadOnly),
        ("AKRR_ACT_P", 0xA18C, "1/1000 rpm", Access::ReadOnly),
        ("AKRR_ACT_U", 0xA190, "0..7FFFh", Access::ReadOnly),
        ("AKRR_ACT_S", 0xA194, "1/1000 rpm", Access::ReadOnly),
        ("AKRR_ACT_OUT", 0xA198, "0..7FFFh", Access::ReadOnly),
        ("AKRR_V", 0xA19C, "mm/min", Access::ReadWrite),
        ("AKRR_SMAX", 0xA1A0, "1/1000 rpm", Access::ReadWrite),
        ("AKRR_DIST", 0xA1A4, "1/8 µm", Access::ReadWrite),
        ("AKRR_VCORR", 0xA1A8, "mm/min", Access::ReadWrite),
        ("AKRR_CNTR", 0xA1AC, "bits", Access::ReadWrite),
        ("DYNAM_SET", 0xA1B0, "index", Access::ReadWrite),
        ("IO_IN_LO", 0xA1B4, "bits", Access::ReadOnly),
        ("IO_IN_HI", 0xA1B8, "bits", Access::ReadOnly),
        ("IO_OUT_LO", 0xA1BC, "bits", Access::ReadOnly),
        ("IO_OUT_HI", 0xA1C0, "bits", Access::ReadOnly),
    ];
    let got: Vec<_> = PlcArea::new()
        .list()
        .map(|(c, v)| {
            assert_eq!(v, 0);
            (c.name, c.address, c.unit.symbol(), c.access)
        })
        .collect();
    assert_eq!(got, expect);
}

#[test]
fn reads_by_address_and_name() {
    let a = busy_area();
    assert_eq!(a.read(0xA194), Ok(286_479));
    assert_eq!(a.read_by_name("akrr_act_out"), Ok(3520));
    assert_eq!(a.read_by_name("AKRR_V"), Ok(90_000));
    // Staged write: the API reads what it wrote, the controller still the value in force.
    assert_eq!(a.read_by_name("AKRR_SMAX"), Ok(1_500_000));
    assert_eq!(a.input(CellId::AkrrSmax), 0);
    assert_eq!(
        a.read(0xA1C4),
        Err(PlcError::UnknownAddress { address: 0xA1C4 })
    );
}

#[test]
fn unknown_address_is_refused_and_changes_nothing() {
    let mut a = busy_area();
    let before = a;
    let e = a.write(0xA17A, 1).unwrap_err();
    assert_eq!(e, PlcError::UnknownAddress { address: 0xA17A });
    assert_eq!(
        e.to_string(),
        "there is no PLC cell at address A17Ah in memory area 1"
    );
    let e = a.write_by_name("AKRR_SPEED", 1).unwrap_err();
    assert_eq!(
        e.to_string(),
        "there is no PLC cell named \"AKRR_SPEED\" in memory area 1"
    );
    assert_eq!(a, before);
}

#[test]
fn act_cells_are_read_only_for_the_plc() {
    let mut a = busy_area();
    let before = a;
    for c in CATALOGUE.iter().filter(|c| c.access == Access::ReadOnly) {
        let e = a.write(c.address, 0).unwrap_err();
        assert_eq!(
            e,
            PlcError::ReadOnly {
                name: c.name,
                address: c.address
            }
        );
        assert!(a.write_by_name(c.name, 0).is_err());
    }
    assert_eq!(
        a.write_by_name("AKRR_ACT_S", 0).unwrap_err().to_string(),
        "AKRR_ACT_S (A194h) is written by the controller every tick and cannot be written by \
         the PLC"
    );
    a.begin_tick();
    let mut expect = before;
    expect.begin_tick();
    assert_eq!(a, expect);
    assert_eq!(a.input(CellId::AkrrActS), 286_479);
}

#[test]
fn out_of_range_values_are_refused_and_change_nothing() {
    let mut a = busy_area();
    let before = a;
    let cases: [(&str, i64); 9] = [
        ("AKRR_V", -1),
        ("AKRR_V", 9_999_901),
        ("AKRR_SMAX", 99_999_001),
        ("AKRR_DIST", 8_000_001),
        ("AKRR_DIST", -8_000_001),
        ("AKRR_VCORR", -9_999_901),
        ("AKRR_CNTR", 0x40),
        ("DYNAM_SET", 4),
        ("DYNAM_SET", i64::from(i32::MAX) + 1),
    ];
    for (name, value) in cases {
        let e = a.write_by_name(name, value).unwrap_err();
        assert!(
            matches!(e, PlcError::OutOfRange { value: v, .. } if v == value),
            "{name} = {value}: {e}"
        );
    }
    assert_eq!(a, before);
    assert_eq!(
        a.write_by_name("DYNAM_SET", 4).unwrap_err().to_string(),
        "4 is out of range for DYNAM_SET (A1B0h): allowed 0 to 3 index"
    );
    // The limits themselves are accepted.
    a.write_by_name("AKRR_DIST", -8_000_000).unwrap();
    a.write_by_name("AKRR_CNTR", 0x3F).unwrap();
    a.write_by_name("DYNAM_SET", 3).unwrap();
    a.begin_tick();
    assert_eq!(a.dynam_set(), 4);
    assert_eq!(a.cntr(), 0x3F);
}

proptest! {
    /// Any write by address either lands (input cell, value in range, visible after the next
    /// tick) or is refused with the area unchanged.
    #[test]
    fn every_write_lands_or_changes_nothing(
        address in 0xA170u32..0xA1C0,
        value in prop_oneof![-10_000_000i64..10_000_000, any::<i64>()],
    ) {
        let mut a = busy_area();
        let before = a;
        match a.write(address, value) {
            Ok(()) => {
                let c = CATALOGUE.iter().find(|c| c.address == address).unwrap();
                prop_assert_eq!(c.access, Access::ReadWrite);
                prop_assert!(i64::from(c.min) <= value && value <= i64::from(c.max));
                a.begin_tick();
                prop_assert_eq!(i64::from(a.input(c.id)), value);
            }
            Err(e) => {
                prop_assert_eq!(a, before);
                prop_assert!(!e.to_string().is_empty());
                prop_assert_eq!(PlcWrite::new(address, value), Err(e));
            }
        }
    }
}
