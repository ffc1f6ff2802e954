//! Machine constants ("R constants", SPEC §1) and their decade accessors.
//!
//! A constant's value is written `±xxxxx.xxx`. Decade 1 is the last decimal digit, decade 3 the
//! first decimal digit, decade 4 the units digit, decade 8 the leftmost digit. We hold each value
//! as an integer count of thousandths so decades are exact.

use std::collections::BTreeMap;

/// Highest constant number.
pub const MAX_R: u16 = 999;

/// Store of R constants. Constants that were never set read as their default (see [`default_of`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Constants {
    /// Value in thousandths (`-21140.000` → `-21_140_000`).
    milli: BTreeMap<u16, i64>,
}

/// Default value of a constant, in thousandths. Constants SPEC does not name default to zero.
pub fn default_of(r: u16) -> i64 {
    match r {
        // R52: acceleration without continuity, mm/s² (SPEC §7); a sensible default for a mill.
        52 => 500_000,
        // R39: angle limit of automatic continuity, degrees (SPEC §7.1 recommends 60).
        39 => 60_000,
        _ => 0,
    }
}

impl Constants {
    pub fn new() -> Self {
        Self::default()
    }

    /// Sets constant `r` to `value` (rounded to thousandths). Values beyond ±99999.999 are
    /// clamped to the field width.
    pub fn set(&mut self, r: u16, value: f64) {
        let milli = (value * 1000.0).round().clamp(-99_999_999.0, 99_999_999.0) as i64;
        self.milli.insert(r, milli);
    }

    /// Value of constant `r`.
    pub fn get(&self, r: u16) -> f64 {
        self.milli_of(r) as f64 / 1000.0
    }

    fn milli_of(&self, r: u16) -> i64 {
        self.milli.get(&r).copied().unwrap_or_else(|| default_of(r))
    }

    /// Digit at `decade` (1..=8) of constant `r`: "8.R95" is `decade(95, 8)`.
    pub fn decade(&self, r: u16, decade: u32) -> u8 {
        debug_assert!((1..=8).contains(&decade));
        ((self.milli_of(r).unsigned_abs() / 10u64.pow(decade - 1)) % 10) as u8
    }

    /// The digits of decades `lo..=hi` read as a whole number (e.g. R384 d5..6 = 20 percent).
    pub fn field_digits(&self, r: u16, lo: u32, hi: u32) -> u64 {
        debug_assert!(lo >= 1 && hi <= 8 && lo <= hi);
        (self.milli_of(r).unsigned_abs() / 10u64.pow(lo - 1)) % 10u64.pow(hi - lo + 1)
    }

    /// Decades `lo..=hi` read with the decimal point where it stands in the constant
    /// (`R339 = -21140.000`, decades 1..6 → 140.0).
    pub fn field_value(&self, r: u16, lo: u32, hi: u32) -> f64 {
        (self.field_digits(r, lo, hi) * 10u64.pow(lo - 1)) as f64 / 1000.0
    }

    /// Whether the constant carries the sign `-` (used as a flag by several constants).
    pub fn is_negative(&self, r: u16) -> bool {
        self.milli_of(r) < 0
    }

    /// Constants explicitly set, in number order.
    pub fn iter(&self) -> impl Iterator<Item = (u16, f64)> + '_ {
        self.milli.iter().map(|(&r, &m)| (r, m as f64 / 1000.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // SPEC §1 worked examples.
    #[test]
    fn decades_of_r339() {
        let mut c = Constants::new();
        c.set(339, -21140.000);
        assert_eq!(c.decade(339, 8), 2);
        assert_eq!(c.decade(339, 7), 1);
        assert_eq!(c.field_value(339, 1, 6), 140.0);
        assert!(c.is_negative(339));
    }

    #[test]
    fn decades_of_r397() {
        let mut c = Constants::new();
        c.set(397, 1011.110);
        let d: Vec<u8> = (1..=8).map(|d| c.decade(397, d)).collect();
        assert_eq!(d, [0, 1, 1, 1, 1, 0, 1, 0]);
    }

    #[test]
    fn field_digits_reads_percent() {
        let mut c = Constants::new();
        c.set(384, 200.010);
        assert_eq!(c.field_digits(384, 5, 6), 20);
        assert_eq!(c.field_digits(384, 1, 4), 10);
    }
}
