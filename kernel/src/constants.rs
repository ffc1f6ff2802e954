//! Machine constants ("R constants", SPEC §1) and their decade accessors.
//!
//! A constant's value is written `±xxxxx.xxx`. Decade 1 is the last decimal digit, decade 3 the
//! first decimal digit, decade 4 the units digit, decade 8 the leftmost digit. We hold each value
//! as an integer count of thousandths so decades are exact.

use std::collections::BTreeMap;

use crate::diag::{DiagCode, Diagnostic};

mod text_edit;
pub use text_edit::edit_text;

/// Highest constant number.
pub const MAX_R: u16 = 999;

/// Store of R constants. Constants that were never set read as their default (see [`default_of`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Constants {
    /// Value in thousandths (`-21140.000` → `-21_140_000`).
    milli: BTreeMap<u16, i64>,
}

/// Default value of a constant, in thousandths. Constants SPEC does not name default to zero.
///
/// Every constant SPEC names has a deliberate default here; the reasoning is in the comment.
pub fn default_of(r: u16) -> i64 {
    match r {
        // R0..R5: axis codes in machine order (see [`AXIS_CODES`]): a 3-axis mill X, Y, Z.
        0 => 1_000,
        1 => 2_000,
        2 => 3_000,
        // R6, R7: following error that counts as "arrived" for G24, mm (SPEC §7.1).
        6 | 7 => 10,
        // R39: angle limit of automatic continuity, degrees (SPEC §7.1 recommends 60).
        39 => 60_000,
        // R52: acceleration without continuity, mm/s² (SPEC §7); a sensible default for a mill.
        52 => 500_000,
        // R55: tolerance of the arc end point on the circle, mm (SPEC §2, seed 000 §7.2.5).
        55 => 10,
        // R67: controlling axis of constant cutting speed; may not be 0 (seed 002): axis 1 = X.
        67 => 1_000,
        // R95: 8.R95 = 1, radius compensation on equidistants (the only kind we implement).
        95 => 10_000_000,
        // R97: 1.R97 = 1, manual continuity with G23/G24 (0 is "do not use" in the manual).
        97 => 1,
        // R234: continuity test limit, degrees; the manual recommends about 0.005.
        234 => 5,
        // R237: rapid acceleration, mm/s².
        237 => 500_000,
        // R382, R383: negative = off (no continuity break / no merging of short blocks).
        382 | 383 => -1_000,
        // R580: version 2 of constant cutting speed (G76 limit, non-motion blocks).
        580 => 1_000,
        _ => 0,
    }
}

/// Axis code of constants R0..R5 and R67 (SPEC §1 leaves the encoding open; **decided**):
/// 0 = no axis, 1..9 = the letters below.
pub const AXIS_CODES: [char; 9] = ['X', 'Y', 'Z', 'U', 'V', 'W', 'A', 'B', 'C'];

/// Circle refinement by the preprocessor (R325, SPEC §4.6).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Refinement {
    /// 8.R325 = 0.
    Off,
    /// 8.R325 = 1: refine I or J by at most `limit_mm`.
    Limited { limit_mm: f64 },
    /// 8.R325 = 2: refine without the limit test.
    Unlimited,
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

    /// Value of constant `r` in thousandths, exactly as stored (or its default).
    pub fn milli(&self, r: u16) -> i64 {
        self.milli_of(r)
    }

    // ---- accessors named for what they mean -------------------------------------------------

    /// Axis letters in machine order from R0..R5 (codes of [`AXIS_CODES`]); stops at the first
    /// constant that is 0. Errors are reported by [`Constants::validate`].
    pub fn axis_names(&self) -> Vec<char> {
        (0..6)
            .map(|r| self.milli_of(r))
            .take_while(|&m| m != 0)
            .filter_map(axis_letter)
            .collect()
    }

    /// R55: largest distance of an arc's end point from its circle, mm (SPEC §2); 0 = exact.
    /// The interpreter and the compensator both read this one accessor (issue #14: R55 = 0
    /// meant 0 to one and 10 µm to the other).
    pub fn arc_tolerance_mm(&self) -> f64 {
        self.get(55).abs()
    }

    /// R6 (axes 1..3) and R7 (axes 4..6): following error under which an axis counts as
    /// arrived, the G24 in-position window (SPEC §7.1 "R06-R07"; the split by axis is
    /// **decided**, see docs/files.md). 0 reads as 1 nm (arrived only at rest).
    pub fn in_position_window_mm(&self) -> crate::units::AxesMm {
        let mut w = crate::units::AxesMm::ZERO;
        for (i, v) in w.0.iter_mut().enumerate() {
            let r = if i < 3 { 6 } else { 7 };
            *v = self.get(r).abs().max(1e-6);
        }
        w
    }

    /// R387: blocks per preview page, 0 = the whole program on one page (SPEC §7.5).
    ///
    /// **Decided**: R387 is read as its digit string like the other integer-unit constants of
    /// SPEC §7 (the manual's example `R387 50.000` means 50000 blocks, and its text says 50000).
    pub fn preview_page_blocks(&self) -> u32 {
        self.field_digits(387, 1, 8) as u32
    }

    /// 7.R397 = 1: an arc whose end point is not on the circle is replaced by a line (SPEC §4.5).
    pub fn bad_arc_becomes_line(&self) -> bool {
        self.decade(397, 7) == 1
    }

    /// 6.R397 = 1: G41 ↔ G42 may change directly (SPEC §4.2).
    pub fn comp_side_switch_allowed(&self) -> bool {
        self.decade(397, 6) == 1
    }

    /// 7.R339 = 1: G40 may stand in a block without motion in the plane (SPEC §4.2).
    pub fn g40_without_motion_allowed(&self) -> bool {
        self.decade(339, 7) == 1
    }

    /// R325: circle refinement setting (SPEC §4.6). Decades 1..7 are the limit in mm.
    pub fn refinement(&self) -> Refinement {
        match self.decade(325, 8) {
            1 => Refinement::Limited {
                limit_mm: self.field_value(325, 1, 7),
            },
            2 => Refinement::Unlimited,
            _ => Refinement::Off,
        }
    }

    /// 3.R329 bit 0: G96 and G97 swap meaning (G96 = feed per revolution), SPEC §6.
    pub fn css_g96_g97_swapped(&self) -> bool {
        self.decade(329, 3) & 1 == 1
    }

    /// 3.R329 bit 1: the cutting speed S is written in m/min instead of 0.1 m/min (SPEC §6).
    pub fn css_s_in_m_min(&self) -> bool {
        self.decade(329, 3) & 2 == 2
    }

    // ---- validation ---------------------------------------------------------------------------

    /// Checks the constants whose values have a restricted meaning. Messages name the constant;
    /// `line` is 0 (use [`Constants::parse`] to get file lines).
    pub fn validate(&self) -> Vec<Diagnostic> {
        let mut out = Vec::new();
        let mut bad = |r: u16, msg: String| {
            out.push(Diagnostic::error(
                DiagCode::ConstantOutOfRange,
                None,
                0,
                0,
                format!("R{r}: {msg}"),
            ));
        };
        self.check_axes(&mut bad);
        self.check_modes(&mut bad);
        out
    }

    /// R0..R5 (axis codes) and R67 (controlling axis of constant cutting speed).
    fn check_axes(&self, bad: &mut impl FnMut(u16, String)) {
        // R0..R5: axis codes, no gaps, no repeats.
        let mut seen = Vec::new();
        let mut ended = false;
        for r in 0..6u16 {
            let m = self.milli_of(r);
            if m == 0 {
                ended = true;
                continue;
            }
            match axis_letter(m) {
                None => bad(
                    r,
                    format!(
                        "axis code {} is not 0..9 (0 = none, 1 = X ... 9 = C)",
                        fmt_milli(m)
                    ),
                ),
                Some(_) if ended => bad(r, "an axis follows an unused axis slot".into()),
                Some(c) if seen.contains(&c) => bad(r, format!("axis {c} is configured twice")),
                Some(c) => seen.push(c),
            }
        }
        if seen.is_empty() {
            bad(0, "no axis configured (R0 = 0)".into());
        }
        // R67: must name a configured axis (seed 002: 0 is not allowed).
        match axis_letter(self.milli_of(67)) {
            Some(c) if seen.contains(&c) => {}
            _ => bad(
                67,
                format!(
                    "controlling axis of constant cutting speed must be the code of a configured axis, not {}",
                    fmt_milli(self.milli_of(67))
                ),
            ),
        }
    }

    /// Tolerances, acceleration and the mode decades (R52, R55, R97, R325, R329, R338, R339,
    /// R580): one check per constant, in the manual's order.
    fn check_modes(&self, bad: &mut impl FnMut(u16, String)) {
        if self.milli_of(55) < 0 {
            bad(55, "arc tolerance cannot be negative".into());
        }
        // R52/R237 = 0: the axes' own limits, no path-level bound (docs/planner.md, decided:
        // the manual gives 0 a meaning for R236 only, "take R52"; for these two it is the
        // value that leaves every move to the axes it moves, which stay bounded).
        for r in [52, 237] {
            if self.milli_of(r) < 0 {
                bad(
                    r,
                    "acceleration cannot be negative (0 = the axes' limits)".into(),
                );
            }
        }
        if self.decade(97, 1) > 2 {
            bad(
                97,
                format!("decade 1 must be 0, 1 or 2, not {}", self.decade(97, 1)),
            );
        }
        let d8 = self.decade(325, 8);
        if d8 > 2 {
            bad(325, format!("decade 8 must be 0, 1 or 2, not {d8}"));
        }
        if d8 == 1 && self.field_value(325, 1, 7) > 3.0 {
            bad(
                325,
                format!(
                    "largest circle refinement is {:.3} mm; at most 3.000 mm is allowed",
                    self.field_value(325, 1, 7)
                ),
            );
        }
        if self.is_negative(325) {
            bad(325, "cannot be negative".into());
        }
        if !matches!(self.decade(339, 8), 0 | 1 | 2 | 4) {
            bad(
                339,
                format!("decade 8 must be 0, 1, 2 or 4, not {}", self.decade(339, 8)),
            );
        }
        if self.decade(329, 3) > 3 {
            bad(
                329,
                format!("decade 3 must be 0..3, not {}", self.decade(329, 3)),
            );
        }
        if self.decade(338, 2) > 2 {
            bad(
                338,
                format!("decade 2 must be 0, 1 or 2, not {}", self.decade(338, 2)),
            );
        }
        // R580: decades 1..2 = 00 old, 01 version 2; the manual also says "set 1" (= 1.000).
        let m580 = self.milli_of(580);
        if !matches!(m580, 0 | 1 | 1000) {
            bad(
                580,
                format!(
                    "KŘR version must be 00000.000 (old), 00000.001 or 00001.000 (version 2), not {}",
                    fmt_milli(m580)
                ),
            );
        }
    }

    // ---- the constants file -------------------------------------------------------------------

    /// Parses a constants file (format **decided**, see `docs/files.md`): one `Rnnn=value` per
    /// line, value `±xxxxx.xxx` (up to 5 integer and 3 decimal digits), `;` starts a comment,
    /// blank lines are ignored, a constant may appear once. On any error nothing is returned.
    pub fn parse(text: &str) -> Result<Constants, Vec<Diagnostic>> {
        let mut c = Constants::new();
        let mut errors = Vec::new();
        for (i, raw) in text.lines().enumerate() {
            let line_no = i as u32 + 1;
            let code = raw.split(';').next().unwrap_or("");
            let trimmed = code.trim();
            if trimmed.is_empty() {
                continue;
            }
            let col = (code.len() - code.trim_start().len()) as u32 + 1;
            match parse_line(trimmed) {
                Ok((r, m)) => {
                    if c.milli.insert(r, m).is_some() {
                        errors.push(Diagnostic::error(
                            DiagCode::ConstantSetTwice,
                            None,
                            line_no,
                            col,
                            format!("R{r} is set twice; keep one line"),
                        ));
                    }
                }
                Err((off, e)) => errors.push(Diagnostic::error(
                    e.code(),
                    None,
                    line_no,
                    col + off as u32,
                    e.to_string(),
                )),
            }
        }
        if errors.is_empty() {
            Ok(c)
        } else {
            Err(errors)
        }
    }

    /// Writes the constants that were set, one canonical `Rnnn=±xxxxx.xxx` line each, after a
    /// comment line. [`Constants::parse`] reads it back to the same store.
    pub fn to_text(&self) -> String {
        let mut out = String::from("; machine constants (Rnnn=xxxxx.xxx), see docs/files.md\n");
        for (&r, &m) in &self.milli {
            out.push_str(&format!("R{r:03}={}\n", fmt_milli(m)));
        }
        out
    }
}

/// `±xxxxx.xxx` with five integer digits (sign only when negative): `-21140.000`, `01011.110`.
pub fn fmt_milli(m: i64) -> String {
    let sign = if m < 0 { "-" } else { "" };
    let a = m.unsigned_abs();
    format!("{sign}{:05}.{:03}", a / 1000, a % 1000)
}

fn axis_letter(m: i64) -> Option<char> {
    if m % 1000 != 0 || !(1..=9).contains(&(m / 1000)) {
        return None;
    }
    Some(AXIS_CODES[(m / 1000 - 1) as usize])
}

/// Why a line of a constants file is refused.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ConstantLineError {
    #[error("expected Rnnn=value, found '{0}'")]
    NotR(char),
    #[error("expected a constant number 0..999 after R")]
    NoNumber,
    #[error("R{0} does not exist (R0..R{MAX_R})")]
    Unknown(String),
    #[error("R{0}: expected '=' after the constant number")]
    NoEquals(u16),
    #[error("R{0}: {1}")]
    Value(u16, FixedValueError),
}

impl ConstantLineError {
    /// Stable code (tests and HMIs match it; the message may improve).
    pub fn code(&self) -> DiagCode {
        match self {
            ConstantLineError::NotR(_)
            | ConstantLineError::NoNumber
            | ConstantLineError::NoEquals(_) => DiagCode::ConstantSyntax,
            ConstantLineError::Unknown(_) => DiagCode::ConstantUnknown,
            ConstantLineError::Value(_, e) => e.code(),
        }
    }
}

/// One `Rnnn=value` line (already trimmed). Errors carry a byte offset into the line.
fn parse_line(t: &str) -> Result<(u16, i64), (usize, ConstantLineError)> {
    let b = t.as_bytes();
    if !matches!(b[0], b'R' | b'r') {
        return Err((0, ConstantLineError::NotR(first_char(t))));
    }
    let mut i = 1;
    while i < b.len() && b[i].is_ascii_digit() {
        i += 1;
    }
    if i == 1 {
        return Err((1, ConstantLineError::NoNumber));
    }
    let r: u32 = t[1..i].parse().unwrap_or(u32::MAX);
    if r > u32::from(MAX_R) {
        return Err((1, ConstantLineError::Unknown(t[1..i].into())));
    }
    let r = r as u16;
    let rest = &t[i..];
    let eq = rest.trim_start();
    if !eq.starts_with('=') {
        return Err((i, ConstantLineError::NoEquals(r)));
    }
    let v = eq[1..].trim();
    let voff = t.len() - eq[1..].trim_start().len();
    parse_fixed_milli(v)
        .map(|m| (r, m))
        .map_err(|e| (voff, ConstantLineError::Value(r, e)))
}

fn first_char(t: &str) -> char {
    t.chars().next().unwrap_or(' ')
}

/// Why a constant's value is not `±xxxxx.xxx` (the text as written is kept for the message).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FixedValueError {
    #[error("'{0}' is not a number of the form ±xxxxx.xxx")]
    NotANumber(String),
    #[error("'{0}' has more than 5 digits before the decimal point")]
    TooManyDigits(String),
    #[error("'{0}' has more than 3 decimals (constants are ±xxxxx.xxx)")]
    TooManyDecimals(String),
}

impl FixedValueError {
    /// Stable code (tests and HMIs match it; the message may improve).
    pub fn code(&self) -> DiagCode {
        match self {
            FixedValueError::NotANumber(_) => DiagCode::ConstantNotANumber,
            FixedValueError::TooManyDigits(_) => DiagCode::ConstantTooManyDigits,
            FixedValueError::TooManyDecimals(_) => DiagCode::ConstantTooManyDecimals,
        }
    }
}

/// Parses `±xxxxx.xxx` exactly into thousandths (no floating point on the way).
pub fn parse_fixed_milli(v: &str) -> Result<i64, FixedValueError> {
    let (neg, body) = match v.as_bytes().first() {
        Some(b'-') => (true, &v[1..]),
        Some(b'+') => (false, &v[1..]),
        _ => (false, v),
    };
    let (int, frac) = match body.split_once('.') {
        Some((a, b)) => (a, b),
        None => (body, ""),
    };
    let digits_ok = |s: &str| s.bytes().all(|c| c.is_ascii_digit());
    if int.is_empty() && frac.is_empty() || !digits_ok(int) || !digits_ok(frac) {
        return Err(FixedValueError::NotANumber(v.to_string()));
    }
    if int.len() > 5 && int.trim_start_matches('0').len() > 5 {
        return Err(FixedValueError::TooManyDigits(v.to_string()));
    }
    if frac.len() > 3 {
        return Err(FixedValueError::TooManyDecimals(v.to_string()));
    }
    let int_v: i64 = if int.is_empty() {
        0
    } else {
        int.trim_start_matches('0').parse().unwrap_or(0)
    };
    let mut frac_v: i64 = if frac.is_empty() {
        0
    } else {
        frac.parse().unwrap_or(0)
    };
    for _ in frac.len()..3 {
        frac_v *= 10;
    }
    let m = int_v * 1000 + frac_v;
    Ok(if neg { -m } else { m })
}

/// Fuzzing entry: parse arbitrary bytes as a constants file; whatever parses must write and
/// read back to the same store, and validation must not panic. Used by `fuzz/` and a proptest.
pub fn fuzz_entry(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    if let Ok(c) = Constants::parse(&text) {
        let _ = c.validate();
        let back = Constants::parse(&c.to_text()).expect("written constants must parse");
        assert_eq!(back, c, "constants must round-trip");
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
    fn zero_path_accelerations_are_the_axes_limits_and_negative_ones_refused() {
        let mut c = Constants::new();
        c.set(52, 0.0);
        c.set(237, 0.0);
        assert!(c.validate().is_empty(), "{:?}", c.validate());
        for r in [52, 237] {
            let mut c = Constants::new();
            c.set(r, -100.0);
            let d = c.validate();
            assert_eq!(d.len(), 1, "{d:?}");
            assert_eq!(d[0].code, DiagCode::ConstantOutOfRange);
        }
    }

    #[test]
    fn field_digits_reads_percent() {
        let mut c = Constants::new();
        c.set(384, 200.010);
        assert_eq!(c.field_digits(384, 5, 6), 20);
        assert_eq!(c.field_digits(384, 1, 4), 10);
    }
}
