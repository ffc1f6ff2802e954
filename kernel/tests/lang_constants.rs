//! Machine constants file, decades and validation (SPEC §1, §4.6).

use kernel::DiagCode;
use kernel::constants::{Constants, Refinement, default_of, fmt_milli};

#[test]
fn file_round_trips_and_reads_the_manual_values() {
    let text = "; flame cutter\nR95=10000.000\nR234=00000.800\nR325=20003.000\nR339=-21140.000\nR397=01011.111\n R0 = 1 ; X\nR1=2\nR2=3\n";
    let c = Constants::parse(text).unwrap();
    assert_eq!(c.decade(95, 8), 1);
    assert_eq!(c.get(234), 0.8);
    assert_eq!(c.refinement(), Refinement::Unlimited);
    assert_eq!(c.field_value(339, 1, 6), 140.0);
    assert!(c.is_negative(339));
    assert_eq!(c.axis_names(), ['X', 'Y', 'Z']);
    assert!(c.validate().is_empty(), "{:?}", c.validate());
    let back = Constants::parse(&c.to_text()).unwrap();
    assert_eq!(back, c);
    assert!(c.to_text().contains("R339=-21140.000\n"));
}

#[test]
fn fixed_format_is_enforced() {
    let cases = [
        ("R1=123456.0", 1, 4, DiagCode::ConstantTooManyDigits),
        ("R1=1.2345", 1, 4, DiagCode::ConstantTooManyDecimals),
        ("R1000=1", 1, 2, DiagCode::ConstantUnknown),
        ("R1 1", 1, 3, DiagCode::ConstantSyntax),
        ("X1=1", 1, 1, DiagCode::ConstantSyntax),
        ("R5=1\nR5=2", 2, 1, DiagCode::ConstantSetTwice),
        ("R5=abc", 1, 4, DiagCode::ConstantNotANumber),
    ];
    for (text, line, col, code) in cases {
        let e = Constants::parse(text).unwrap_err();
        assert_eq!(
            (e[0].line, e[0].column),
            (line, col),
            "{text}: {}",
            e[0].message
        );
        assert_eq!(e[0].code, code, "{text}: {}", e[0].message);
    }
}

#[test]
fn validation_refuses_out_of_range_settings() {
    // Each refusal names its constant first ("R325: ..."); `_why` says what the case checks.
    let check = |r: u16, v: f64, _why: &str| {
        let mut c = Constants::new();
        c.set(r, v);
        let errs = c.validate();
        assert!(
            errs.iter().any(|d| d.code == DiagCode::ConstantOutOfRange
                && d.message.starts_with(&format!("R{r}:"))),
            "R{r}={v}: {errs:?}"
        );
    };
    check(325, 10003.001, "at most 3.000 mm");
    check(325, 30000.0, "decade 8");
    check(97, 0.003, "decade 1 must be 0, 1 or 2");
    check(339, 30000.0, "decade 8 must be 0, 1, 2 or 4");
    check(67, 0.0, "controlling axis");
    check(1, 1.0, "configured twice");
    check(55, -0.01, "cannot be negative");
    check(580, 5.0, "KŘR version");
    check(580, 0.002, "KŘR version");
    let mut c = Constants::new();
    c.set(325, 10003.0);
    assert!(c.validate().is_empty());
    assert_eq!(c.refinement(), Refinement::Limited { limit_mm: 3.0 });
}

#[test]
fn defaults_for_named_constants() {
    let c = Constants::new();
    assert_eq!(c.axis_names(), ['X', 'Y', 'Z']);
    assert_eq!(c.arc_tolerance_mm(), 0.01);
    assert_eq!(c.refinement(), Refinement::Off);
    assert_eq!(c.decade(95, 8), 1);
    assert_eq!(c.decade(97, 1), 1);
    assert_eq!(default_of(39), 60_000);
    assert!(c.validate().is_empty(), "{:?}", c.validate());
    // Defaults are not written to the file: only what was set.
    assert_eq!(c.iter().count(), 0);
}

#[test]
fn css_decades_of_r329() {
    let mut c = Constants::new();
    for (v, swap, m) in [
        (0.0, false, false),
        (0.1, true, false),
        (0.2, false, true),
        (0.3, true, true),
    ] {
        c.set(329, v);
        assert_eq!(
            (c.css_g96_g97_swapped(), c.css_s_in_m_min()),
            (swap, m),
            "{v}"
        );
    }
    assert_eq!(fmt_milli(-21_140_000), "-21140.000");
    assert_eq!(fmt_milli(1_011_110), "01011.110");
}
