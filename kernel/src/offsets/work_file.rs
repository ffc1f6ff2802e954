//! The work offsets file (`WORK.OFS` in the daemon's storage dir, docs/files.md): the nine
//! coordinate systems G54..G59.3 of the ISO dialect as text a person can edit, one line per
//! system, like TAB0.KOR for tools:
//!
//! ```text
//! ; fixture plate 2
//! G54 X10.000 Y20.000 Z-5.000
//! G55 X250 Y-2.5      ; second vice
//! ```
//!
//! A line is a system name and `<axis><value>` items (`X10.000`, also `X=10.000`); `;` starts
//! a remark. Systems and axes not written are 0. Values are TAB0.KOR's numbers (sign, at most
//! 5 digits before and 6 after the point, |value| ≤ 99999.999 mm). An edit changes the values
//! it names in the text, where they stand ([`edit_text`]): every other byte stays.

use super::work::{SYSTEM_NAMES, SYSTEMS, WorkOffsets};
use super::{MAX_DECIMALS, ValueError, col_of, parse_value};
use crate::diag::{DiagCode, Diagnostic};
use crate::units::MAX_AXES;

/// An operator edit: new values of some axes of one system (`None` keeps the value).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorkEdit {
    /// 0 = G54 .. 8 = G59.3.
    pub system: usize,
    pub values: [Option<f64>; MAX_AXES],
}

/// One item of a system line: the axis, where its value stands (byte range in the line).
#[derive(Clone, Copy, Debug)]
struct Item {
    axis: usize,
    value_at: (usize, usize),
}

/// A parsed system line: the system, its items, and where its code ends (byte offset).
#[derive(Clone, Debug)]
struct SystemLine {
    system: usize,
    items: Vec<Item>,
    code_end: usize,
}

/// The first line a new file gets (the format in one line).
pub const HEADER: &str =
    "; work offsets G54..G59.3, mm: one line per system, e.g. G54 X10.000 Y20.000 Z-5.000\n";

/// Parses the file for a machine with `axis_names`: every problem with its line and column;
/// on any error no table (a bad file never half-replaces a good one). The system in force at
/// program start is G54.
pub fn parse(text: &str, axis_names: &[char]) -> Result<WorkOffsets, Vec<Diagnostic>> {
    let mut out = WorkOffsets::default();
    let mut seen = [false; SYSTEMS];
    let mut errors = Vec::new();
    for (i, raw) in text.split('\n').enumerate() {
        let line = raw.trim_end_matches('\r');
        let line_no = i as u32 + 1;
        match system_line(line, axis_names) {
            Ok(None) => {}
            Ok(Some(l)) if seen[l.system] => errors.push(Diagnostic::error(
                DiagCode::OffsetEntryTwice,
                None,
                line_no,
                col_of(line, line.len() - line.trim_start().len()),
                format!("{} is listed twice", SYSTEM_NAMES[l.system]),
            )),
            Ok(Some(l)) => {
                seen[l.system] = true;
                for it in &l.items {
                    let v = &line[it.value_at.0..it.value_at.1];
                    out.systems[l.system][it.axis] = parse_value(v).unwrap_or(0.0);
                }
            }
            Err((byte, code, msg)) => errors.push(Diagnostic::error(
                code,
                None,
                line_no,
                col_of(line, byte),
                msg,
            )),
        }
    }
    if errors.is_empty() {
        Ok(out)
    } else {
        Err(errors)
    }
}

/// A line's system and items; `None` for a blank or remark line. Errors: byte offset, code
/// and message.
fn system_line(
    line: &str,
    axis_names: &[char],
) -> Result<Option<SystemLine>, (usize, DiagCode, String)> {
    let code = line.split(';').next().unwrap_or("");
    let mut tokens = tokens(code);
    let Some((at, name)) = tokens.next() else {
        return Ok(None);
    };
    let system = WorkOffsets::index_of(name).ok_or_else(|| {
        let msg = format!("'{name}' is not a work offset system: G54 .. G59, G59.1 .. G59.3");
        (at, DiagCode::OffsetFileSyntax, msg)
    })?;
    let mut items: Vec<Item> = Vec::new();
    let mut code_end = at + name.len();
    for (at, tok) in tokens {
        code_end = at + tok.len();
        let item = axis_item(at, tok, axis_names)?;
        if items.iter().any(|i| i.axis == item.axis) {
            let msg = format!(
                "axis {} appears twice in {}",
                axis_names[item.axis], SYSTEM_NAMES[system]
            );
            return Err((at, DiagCode::OffsetKeyTwice, msg));
        }
        items.push(item);
    }
    Ok(Some(SystemLine {
        system,
        items,
        code_end,
    }))
}

/// One `X10.000` (or `X=10.000`) item starting at byte `at`.
fn axis_item(at: usize, tok: &str, axis_names: &[char]) -> Result<Item, (usize, DiagCode, String)> {
    let letter = tok.chars().next().unwrap_or(' ').to_ascii_uppercase();
    let axis = axis_names
        .iter()
        .take(MAX_AXES)
        .position(|a| a.to_ascii_uppercase() == letter)
        .ok_or_else(|| {
            let msg = if letter.is_ascii_alphabetic() {
                format!("this machine has no axis {letter}")
            } else {
                format!("'{tok}' is not an axis letter and a value, e.g. X10.000")
            };
            (at, DiagCode::OffsetUnknownKey, msg)
        })?;
    let mut start = at + letter.len_utf8();
    if tok[letter.len_utf8()..].starts_with('=') {
        start += 1;
    }
    let value = &tok[start - at..];
    parse_value(value).map_err(|why| {
        let code = why.code();
        let msg = match why {
            ValueError::Table(_) => format!("{letter}{value}: {}", ValueError::OutOfRange),
            other => format!("{letter}{value}: {other}"),
        };
        (start, code, msg)
    })?;
    Ok(Item {
        axis,
        value_at: (start, at + tok.len()),
    })
}

/// The whitespace-separated tokens of `code` with their byte offsets.
fn tokens(code: &str) -> impl Iterator<Item = (usize, &str)> {
    code.split_inclusive(char::is_whitespace)
        .scan(0usize, |pos, t| {
            let at = *pos;
            *pos += t.len();
            Some((at, t.trim_end()))
        })
        .filter(|(_, t)| !t.is_empty())
}

/// A value as the file writes it: at least 3 decimals, at most [`MAX_DECIMALS`].
pub fn fmt_mm(v: f64) -> String {
    let mut s = format!("{v:.prec$}", prec = MAX_DECIMALS);
    while s.ends_with('0') && s.len() - s.find('.').unwrap_or(s.len()) > 4 {
        s.pop();
    }
    if s.trim_start_matches('-')
        .bytes()
        .all(|b| b == b'0' || b == b'.')
    {
        s = s.trim_start_matches('-').to_string();
    }
    s
}

/// Applies `edit` to the file's `text` (as it is on disk): the values named change where they
/// stand, a value the line lacks is appended to it, a system without a line gets one before
/// the first line of a later system. Every other byte stays. Returns the new text and its
/// table; `text` must parse (its errors are returned otherwise).
pub fn edit_text(
    text: &str,
    edit: &WorkEdit,
    axis_names: &[char],
) -> Result<(String, WorkOffsets), Vec<Diagnostic>> {
    parse(text, axis_names)?;
    let nl = if text.contains("\r\n") { "\r\n" } else { "\n" };
    let mut lines: Vec<String> = text.split('\n').map(str::to_string).collect();
    let mut later = None;
    let mut done = false;
    for (k, raw) in lines.iter_mut().enumerate() {
        let Ok(Some(l)) = system_line(raw.trim_end_matches('\r'), axis_names) else {
            continue;
        };
        if l.system == edit.system {
            *raw = edited_line(raw, &l, edit, axis_names);
            done = true;
        } else if l.system > edit.system && later.is_none() {
            later = Some(k);
        }
    }
    if !done {
        let line = new_line(edit, axis_names, nl);
        match later {
            Some(k) => lines.insert(k, line.trim_end_matches('\n').to_string()),
            None => {
                // Nothing else changed: the line goes at the end.
                let mut t = text.to_string();
                if !t.is_empty() && !t.ends_with('\n') {
                    t.push_str(nl);
                }
                return finish(t + &line, axis_names);
            }
        }
    }
    finish(lines.join("\n"), axis_names)
}

/// The new text and its table (it parses: the edit wrote checked values).
fn finish(text: String, axis_names: &[char]) -> Result<(String, WorkOffsets), Vec<Diagnostic>> {
    let table = parse(&text, axis_names)?;
    Ok((text, table))
}

/// `line` (system line `l`) with the values of `edit`.
fn edited_line(line: &str, l: &SystemLine, edit: &WorkEdit, axis_names: &[char]) -> String {
    let mut out = line.to_string();
    // Appended at the end of the code (before trailing blanks and a remark).
    let mut appended = String::new();
    for (axis, v) in edit.values.iter().enumerate().take(axis_names.len()) {
        let Some(v) = v else { continue };
        if !l.items.iter().any(|i| i.axis == axis) {
            appended.push_str(&format!(" {}{}", axis_names[axis], fmt_mm(*v)));
        }
    }
    out.insert_str(l.code_end, &appended);
    // Replaced from the right, so earlier byte offsets stay valid.
    let mut items = l.items.clone();
    items.sort_by_key(|i| std::cmp::Reverse(i.value_at.0));
    for it in items {
        if let Some(v) = edit.values[it.axis] {
            out.replace_range(it.value_at.0..it.value_at.1, &fmt_mm(v));
        }
    }
    out
}

/// A line for a system the file does not list: the values of `edit`, ending with `nl`.
fn new_line(edit: &WorkEdit, axis_names: &[char], nl: &str) -> String {
    let mut s = SYSTEM_NAMES[edit.system].to_string();
    for (axis, v) in edit.values.iter().enumerate().take(axis_names.len()) {
        if let Some(v) = v {
            s.push_str(&format!(" {}{}", axis_names[axis], fmt_mm(*v)));
        }
    }
    s.push_str(nl);
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    const XYZ: [char; 3] = ['X', 'Y', 'Z'];

    fn edit(system: usize, vals: &[(usize, f64)]) -> WorkEdit {
        let mut values = [None; MAX_AXES];
        for &(a, v) in vals {
            values[a] = Some(v);
        }
        WorkEdit { system, values }
    }

    #[test]
    fn parses_systems_and_defaults_to_zero() {
        let w = parse(
            "; plate\nG54 X10.000 Y20 Z-5\n\ng59.1 x=1.5 ; remark\r\n",
            &XYZ,
        )
        .unwrap();
        assert_eq!(&w.systems[0].0[..3], &[10.0, 20.0, -5.0]);
        assert_eq!(w.systems[6][0], 1.5);
        assert_eq!(w.systems[1], crate::units::AxesMm::ZERO);
        assert_eq!(w.active, 0);
    }

    #[test]
    fn mistakes_are_located_and_coded() {
        let e = parse(
            "G54 X1\nG60 X1\nG55 A1\nG56 X1 X2\nG57 Xabc\nG54 Y1\n",
            &XYZ,
        )
        .unwrap_err();
        let got: Vec<_> = e.iter().map(|d| (d.line, d.column, d.code)).collect();
        assert_eq!(
            got,
            vec![
                (2, 1, DiagCode::OffsetFileSyntax),
                (3, 5, DiagCode::OffsetUnknownKey),
                (4, 8, DiagCode::OffsetKeyTwice),
                (5, 6, DiagCode::OffsetValueSyntax),
                (6, 1, DiagCode::OffsetEntryTwice),
            ]
        );
        let e = parse("G54 X123456\n", &XYZ).unwrap_err();
        assert_eq!(e[0].code, DiagCode::OffsetValueOutOfRange);
    }

    #[test]
    fn edits_keep_every_other_byte() {
        let text = "; my plate\r\nG55 X10   Y2 ; vice\r\nG57 Z1\r\n";
        let (t, w) = edit_text(text, &edit(1, &[(1, -2.5), (2, 3.0)]), &XYZ).unwrap();
        assert_eq!(
            t,
            "; my plate\r\nG55 X10   Y-2.500 Z3.000 ; vice\r\nG57 Z1\r\n"
        );
        assert_eq!(&w.systems[1].0[..3], &[10.0, -2.5, 3.0]);
        // A system without a line: before the first later one, or at the end.
        let (t, _) = edit_text(text, &edit(0, &[(0, 1.0)]), &XYZ).unwrap();
        assert_eq!(
            t,
            "; my plate\r\nG54 X1.000\r\nG55 X10   Y2 ; vice\r\nG57 Z1\r\n"
        );
        let (t, _) = edit_text("G54 X1", &edit(8, &[(0, 0.0001)]), &XYZ).unwrap();
        assert_eq!(t, "G54 X1\nG59.3 X0.0001\n");
        let (t, _) = edit_text("G54 X1\n", &edit(5, &[(1, 7.0)]), &XYZ).unwrap();
        assert_eq!(t, "G54 X1\nG59 Y7.000\n");
        let (t, _) = edit_text("", &edit(0, &[(2, -0.0)]), &XYZ).unwrap();
        assert_eq!(t, "G54 Z0.000\n");
        // A text that does not parse is not edited.
        assert!(edit_text("G99\n", &edit(0, &[(0, 1.0)]), &XYZ).is_err());
    }
}
