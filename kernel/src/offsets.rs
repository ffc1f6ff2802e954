//! Offset table TAB0.KOR (SPEC §3): the table of 99 tool offsets, its file format, and edits.
//!
//! The controller works on a copy of the table in memory. This module holds the pure parts:
//! [`OffsetTable`] (the memory copy), [`parse`] / [`write`] for the file, and [`TableEdit`]
//! (one entry's values, as written by an operator edit or by `G92 D<n> R0..R4`). Which copy an
//! edit reaches (file, memory or both) is decided by the daemon's storage (SPEC §3 (a)-(c)).

use crate::diag::{DiagCode, Diagnostic};

mod text_edit;
pub mod touch_off;
pub mod work;
pub mod work_file;
pub use text_edit::edit_text;
pub use work::WorkOffsets;

/// Entries 1..=99 (SPEC §3).
pub const ENTRIES: u8 = 99;

/// Largest absolute offset value we accept, mm (the controller's `±xxxxx.xxx` field width).
pub const MAX_VALUE_MM: f64 = 99_999.999;

/// Most decimals a value may have in the file (0.001 µm); more would not round-trip.
pub const MAX_DECIMALS: usize = 6;

/// Axis names usable in the file for ordinals 1..4, when the machine's axes are in this order
/// (SPEC §3).
const STANDARD_NAMES: [char; 4] = ['X', 'Y', 'Z', 'U'];

/// One entry: radius and lengths for axes 1..4 (no lengths for axes 5 and 6, SPEC §3).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OffsetEntry {
    pub radius_mm: f64,
    pub length_mm: [f64; 4],
}

impl OffsetEntry {
    /// The five values in table order: R0 radius, R1..R4 lengths.
    pub fn values(&self) -> [f64; 5] {
        let l = self.length_mm;
        [self.radius_mm, l[0], l[1], l[2], l[3]]
    }

    fn set(&mut self, k: usize, v: f64) {
        if k == 0 {
            self.radius_mm = v;
        } else {
            self.length_mm[k - 1] = v;
        }
    }

    pub fn is_zero(&self) -> bool {
        self.values().iter().all(|v| *v == 0.0)
    }
}

/// A write to one entry: only the values present change (G92 and operator edits, SPEC §3).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TableEdit {
    /// Entry 1..=99.
    pub entry: u8,
    /// R0 radius, R1..R4 lengths for axes 1..4; `None` keeps the old value.
    pub values: [Option<f64>; 5],
}

/// The table of 99 entries (the memory copy). Missing entries are zero.
#[derive(Clone, Debug, PartialEq)]
pub struct OffsetTable {
    entries: [OffsetEntry; ENTRIES as usize],
}

impl Default for OffsetTable {
    fn default() -> Self {
        OffsetTable {
            entries: [OffsetEntry::default(); ENTRIES as usize],
        }
    }
}

impl OffsetTable {
    pub fn new() -> Self {
        Self::default()
    }

    /// Entry `n` (1..=99), or `None` for a number outside the table.
    pub fn entry(&self, n: u8) -> Option<&OffsetEntry> {
        (1..=ENTRIES)
            .contains(&n)
            .then(|| &self.entries[n as usize - 1])
    }

    /// Replaces the whole entry `n`.
    pub fn set_entry(&mut self, n: u8, e: OffsetEntry) -> Result<(), OffsetError> {
        check_entry(n)?;
        for v in e.values() {
            check_value(v)?;
        }
        self.entries[n as usize - 1] = e;
        Ok(())
    }

    /// Applies an edit: the values present overwrite, the others stay. All-or-nothing: a bad
    /// entry number or value leaves the table unchanged.
    pub fn apply(&mut self, edit: &TableEdit) -> Result<(), OffsetError> {
        check_entry(edit.entry)?;
        for v in edit.values.iter().flatten() {
            check_value(*v)?;
        }
        let e = &mut self.entries[edit.entry as usize - 1];
        for (k, v) in edit.values.iter().enumerate() {
            if let Some(v) = v {
                e.set(k, *v);
            }
        }
        Ok(())
    }

    /// Non-zero entries with their numbers, in order.
    pub fn iter_nonzero(&self) -> impl Iterator<Item = (u8, &OffsetEntry)> {
        self.entries
            .iter()
            .enumerate()
            .filter(|(_, e)| !e.is_zero())
            .map(|(i, e)| (i as u8 + 1, e))
    }
}

/// Why an edit of the offset table was refused (the table is left unchanged).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum OffsetError {
    #[error("offset entry {0} does not exist: entries are 01..99")]
    NoEntry(u8),
    #[error("offset value {0} is outside ±{max} mm", max = MAX_VALUE_MM)]
    ValueOutOfRange(f64),
}

impl OffsetError {
    /// Stable code (tests and HMIs match it; the message may improve).
    pub fn code(&self) -> DiagCode {
        match self {
            OffsetError::NoEntry(_) => DiagCode::OffsetNoEntry,
            OffsetError::ValueOutOfRange(_) => DiagCode::OffsetValueOutOfRange,
        }
    }
}

fn check_entry(n: u8) -> Result<(), OffsetError> {
    if (1..=ENTRIES).contains(&n) {
        Ok(())
    } else {
        Err(OffsetError::NoEntry(n))
    }
}

fn check_value(v: f64) -> Result<(), OffsetError> {
    if v.is_finite() && v.abs() <= MAX_VALUE_MM {
        Ok(())
    } else {
        Err(OffsetError::ValueOutOfRange(v))
    }
}

/// A TAB0.KOR file: the free comment before `$KOR` and the table.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct KorFile {
    /// Everything before the `$KOR` line, verbatim (kept when the file is rewritten).
    pub comment: String,
    pub table: OffsetTable,
}

/// Parses a TAB0.KOR file for a machine with the given axis letters (R0..R5 order), SPEC §3.
///
/// Every problem is reported (line, column, message); on any error no table is returned, so a
/// bad file never half-replaces a good table.
pub fn parse(text: &str, axis_names: &[char]) -> Result<KorFile, Vec<Diagnostic>> {
    let mut errors = Vec::new();
    let mut file = KorFile::default();
    let mut seen = [false; ENTRIES as usize];
    let mut offset = 0;
    let mut in_table = false;
    for (i, raw) in text.split_inclusive('\n').enumerate() {
        let line_no = i as u32 + 1;
        let line = raw.trim_end_matches(['\n', '\r']);
        let start = offset;
        offset += raw.len();
        if !in_table {
            if line.trim_start().starts_with("$KOR") {
                let rest = line.trim_start()["$KOR".len()..].trim();
                if !rest.is_empty() && !rest.starts_with(';') {
                    errors.push(Diagnostic::error(
                        DiagCode::OffsetFileSyntax,
                        None,
                        line_no,
                        col_of(line, line.len() - line.trim_start().len() + 4),
                        format!("unexpected '{rest}' after $KOR: entries start on the next line"),
                    ));
                }
                file.comment = text[..start].to_string();
                in_table = true;
            }
            continue;
        }
        let code = line.split(';').next().unwrap_or("");
        if code.trim().is_empty() {
            continue;
        }
        if let Err(d) = table_line(code, line, line_no, axis_names, &mut seen, &mut file.table) {
            errors.push(d);
        }
    }
    if !in_table {
        errors.push(Diagnostic::error(
            DiagCode::OffsetKorMissing,
            None,
            text.lines().count().max(1) as u32,
            1,
            "keyword $KOR not found: the table must start with a line $KOR",
        ));
    }
    if errors.is_empty() {
        Ok(file)
    } else {
        Err(errors)
    }
}

/// One line of the table after `$KOR` (its code, without the remark): the entry it sets, which
/// must not be set before (`seen`).
fn table_line(
    code: &str,
    line: &str,
    line_no: u32,
    axis_names: &[char],
    seen: &mut [bool; ENTRIES as usize],
    table: &mut OffsetTable,
) -> Result<(), Diagnostic> {
    let lead_col = col_of(line, line.len() - line.trim_start().len());
    if code.trim_start().starts_with("$KOR") {
        return Err(Diagnostic::error(
            DiagCode::OffsetFileSyntax,
            None,
            line_no,
            lead_col,
            "a second $KOR: a file holds one table",
        ));
    }
    let edit = parse_entry_line(code, axis_names).map_err(|(byte, e)| {
        Diagnostic::error(e.code(), None, line_no, col_of(line, byte), e.to_string())
    })?;
    let k = edit.entry as usize - 1;
    if seen[k] {
        return Err(Diagnostic::error(
            DiagCode::OffsetEntryTwice,
            None,
            line_no,
            lead_col,
            format!("entry {:02} is listed twice", edit.entry),
        ));
    }
    seen[k] = true;
    // Values not listed are zero (SPEC §3): the entry starts from zero.
    let mut e = OffsetEntry::default();
    for (slot, v) in edit.values.iter().enumerate() {
        e.set(slot, v.unwrap_or(0.0));
    }
    table.entries[k] = e;
    Ok(())
}

/// Parses one operator edit written like a file line, e.g. `12: R=5.0 Z=-3` (only the values
/// written change, see [`OffsetTable::apply`]).
pub fn parse_edit(line: &str, axis_names: &[char]) -> Result<TableEdit, Diagnostic> {
    let code = line.split(';').next().unwrap_or("");
    parse_entry_line(code, axis_names)
        .map_err(|(b, e)| Diagnostic::error(e.code(), None, 1, col_of(line, b), e.to_string()))
}

/// Writes the file: the comment, `$KOR`, then one line per non-zero entry with all five values,
/// labelled by axis name where SPEC §3 allows it and by ordinal otherwise.
pub fn write(file: &KorFile, axis_names: &[char]) -> String {
    let mut out = String::with_capacity(file.comment.len() + 64 * 16);
    out.push_str(&file.comment);
    if !file.comment.is_empty() && !file.comment.ends_with('\n') {
        out.push('\n');
    }
    out.push_str("$KOR\n");
    for (n, e) in file.table.iter_nonzero() {
        out.push_str(&format!("{n:02}: R={}", fmt_value(e.radius_mm)));
        for (k, v) in e.length_mm.iter().enumerate() {
            out.push_str(&format!(" {}={}", label(k + 1, axis_names), fmt_value(*v)));
        }
        out.push('\n');
    }
    out
}

/// Label of axis ordinal `k` (1..4): its name if the machine's axis k has the standard name
/// for that position, else the digit (SPEC §3 lathe rule).
pub fn label(k: usize, axis_names: &[char]) -> String {
    let std = STANDARD_NAMES[k - 1];
    if axis_names.get(k - 1) == Some(&std) {
        std.to_string()
    } else {
        k.to_string()
    }
}

fn fmt_value(v: f64) -> String {
    let mut s = format!("{v:.prec$}", prec = MAX_DECIMALS);
    while s.ends_with('0') && !s.ends_with(".0") {
        s.pop();
    }
    if s == "-0.0" { "0.0".into() } else { s }
}

/// 1-based character column of byte offset `byte` in `line`.
pub(crate) fn col_of(line: &str, byte: usize) -> u32 {
    let b = byte.min(line.len());
    let b = (0..=b)
        .rev()
        .find(|&i| line.is_char_boundary(i))
        .unwrap_or(0);
    line[..b].chars().count() as u32 + 1
}

/// Why a line of a TAB0.KOR table (or an operator edit written like one) is refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum KorLineError {
    #[error("expected an entry line 'NN: R=.. X=..', found '{0}'")]
    NotAnEntryLine(String),
    #[error("'{0}' is not an entry number (01..99)")]
    NotAnEntryNumber(String),
    #[error("entry number '{written}' must have two digits (write {entry:02})")]
    EntryNotTwoDigits { written: String, entry: u64 },
    #[error("entry {0} does not exist: entries are 01..99")]
    NoEntry(String),
    #[error("'{0}' is not KEY=value (e.g. R=10.0 or X=20.0)")]
    NotKeyValue(String),
    #[error("'{0}' is not R, an axis name or an axis number 1..4")]
    KeyNotOneLetter(String),
    #[error("'{0}' is not R, an axis name (X Y Z U) or an axis number 1..4")]
    UnknownKey(String),
    #[error(
        "axis {name} is axis {ordinal} on this machine: write its length as {ordinal}= (names \
         X Y Z U are only for axes 1..4 in that order)"
    )]
    AxisByOrdinal { name: char, ordinal: usize },
    #[error("this machine has no axis {0}")]
    NoSuchAxis(char),
    #[error("{0}= appears twice in entry {1:02}")]
    KeyTwice(String, u8),
    #[error("{key}={value}: {why}")]
    Value {
        key: String,
        value: String,
        why: ValueError,
    },
}

/// Why the value of `KEY=value` is refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ValueError {
    #[error("no value after '='")]
    Missing,
    #[error("not a number")]
    NotANumber,
    #[error("more than {MAX_DECIMALS} decimals")]
    TooManyDecimals,
    #[error("beyond ±{MAX_VALUE_MM} mm")]
    OutOfRange,
    #[error(transparent)]
    Table(OffsetError),
}

impl KorLineError {
    /// Stable code (tests and HMIs match it; the message may improve).
    pub fn code(&self) -> DiagCode {
        match self {
            KorLineError::NotAnEntryLine(_)
            | KorLineError::NotAnEntryNumber(_)
            | KorLineError::NotKeyValue(_) => DiagCode::OffsetFileSyntax,
            KorLineError::EntryNotTwoDigits { .. } => DiagCode::OffsetEntryNotTwoDigits,
            KorLineError::NoEntry(_) => DiagCode::OffsetNoEntry,
            KorLineError::KeyNotOneLetter(_)
            | KorLineError::UnknownKey(_)
            | KorLineError::NoSuchAxis(_) => DiagCode::OffsetUnknownKey,
            KorLineError::AxisByOrdinal { .. } => DiagCode::OffsetAxisByOrdinal,
            KorLineError::KeyTwice(..) => DiagCode::OffsetKeyTwice,
            KorLineError::Value { why, .. } => why.code(),
        }
    }
}

impl ValueError {
    /// Stable code (tests and HMIs match it; the message may improve).
    pub fn code(&self) -> DiagCode {
        match self {
            ValueError::OutOfRange | ValueError::Table(_) => DiagCode::OffsetValueOutOfRange,
            _ => DiagCode::OffsetValueSyntax,
        }
    }
}

/// `NN: KEY=value ...`; errors carry the byte offset of the offending text.
fn parse_entry_line(code: &str, axis_names: &[char]) -> Result<TableEdit, (usize, KorLineError)> {
    let lead = code.len() - code.trim_start().len();
    let t = code.trim_start();
    let Some(colon) = t.find(':') else {
        return Err((lead, KorLineError::NotAnEntryLine(t.trim_end().into())));
    };
    let entry = entry_number(t[..colon].trim_end()).map_err(|e| (lead, e))?;
    let mut values = [None; 5];
    let body = &t[colon + 1..];
    let mut pos = lead + colon + 1;
    for tok in body.split_inclusive(char::is_whitespace) {
        let at = pos;
        pos += tok.len();
        let tok = tok.trim_end();
        if tok.is_empty() {
            continue;
        }
        let Some((key, val)) = tok.split_once('=') else {
            return Err((at, KorLineError::NotKeyValue(tok.into())));
        };
        let k = key_slot(key, axis_names).map_err(|e| (at, e))?;
        if values[k].is_some() {
            return Err((at, KorLineError::KeyTwice(key.into(), entry)));
        }
        let v = parse_value(val).map_err(|why| {
            let e = KorLineError::Value {
                key: key.into(),
                value: val.into(),
                why,
            };
            (at + key.len() + 1, e)
        })?;
        values[k] = Some(v);
    }
    Ok(TableEdit { entry, values })
}

/// The entry number `NN` of an entry line: two digits, 01..99.
fn entry_number(num: &str) -> Result<u8, KorLineError> {
    if num.is_empty() || !num.bytes().all(|c| c.is_ascii_digit()) {
        return Err(KorLineError::NotAnEntryNumber(num.into()));
    }
    let n: u64 = num.parse().unwrap_or(u64::MAX);
    if num.len() != 2 {
        return Err(if (1..=99).contains(&n) {
            KorLineError::EntryNotTwoDigits {
                written: num.into(),
                entry: n,
            }
        } else {
            KorLineError::NoEntry(num.into())
        });
    }
    if n == 0 {
        return Err(KorLineError::NoEntry(num.into()));
    }
    Ok(n as u8)
}

/// Slot of a key: `R` → 0, ordinal `1`..`4` or a standard axis name → 1..4.
fn key_slot(key: &str, axis_names: &[char]) -> Result<usize, KorLineError> {
    let mut cs = key.chars();
    let (Some(c), None) = (cs.next(), cs.next()) else {
        return Err(KorLineError::KeyNotOneLetter(key.into()));
    };
    let c = c.to_ascii_uppercase();
    match c {
        'R' => Ok(0),
        '1'..='4' => Ok(c as usize - '0' as usize),
        _ => {
            let Some(k) = STANDARD_NAMES.iter().position(|&s| s == c) else {
                return Err(KorLineError::UnknownKey(key.into()));
            };
            if axis_names.get(k) == Some(&c) {
                return Ok(k + 1);
            }
            match axis_names.iter().position(|&a| a == c) {
                Some(p) => Err(KorLineError::AxisByOrdinal {
                    name: c,
                    ordinal: p + 1,
                }),
                None => Err(KorLineError::NoSuchAxis(c)),
            }
        }
    }
}

/// A decimal number: optional sign, digits, optional point and up to 6 decimals. No exponent.
pub(crate) fn parse_value(v: &str) -> Result<f64, ValueError> {
    let body = v.strip_prefix(['+', '-']).unwrap_or(v);
    let (int, frac) = body.split_once('.').unwrap_or((body, ""));
    let digits = |s: &str| s.bytes().all(|c| c.is_ascii_digit());
    if v.is_empty() {
        return Err(ValueError::Missing);
    }
    if (int.is_empty() && frac.is_empty()) || !digits(int) || !digits(frac) {
        return Err(ValueError::NotANumber);
    }
    if frac.len() > MAX_DECIMALS {
        return Err(ValueError::TooManyDecimals);
    }
    if int.trim_start_matches('0').len() > 5 {
        return Err(ValueError::OutOfRange);
    }
    let x: f64 = v.parse().map_err(|_| ValueError::NotANumber)?;
    check_value(x).map_err(ValueError::Table)?;
    Ok(x)
}

/// Fuzzing entry: arbitrary bytes as a TAB0.KOR for a mill and a lathe; whatever parses must
/// write and parse back to the same table. Used by `fuzz/` and by a proptest in kernel/tests.
pub fn fuzz_entry(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    for axes in [&['X', 'Y', 'Z', 'U'][..], &['X', 'Z'][..]] {
        if let Ok(f) = parse(&text, axes) {
            let back = parse(&write(&f, axes), axes).expect("a written table must parse");
            assert_eq!(back.table, f.table, "table must round-trip");
        }
        let _ = parse_edit(&text, axes);
    }
}
