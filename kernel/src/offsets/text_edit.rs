//! An operator edit of one entry applied to the text of TAB0.KOR in place (issue #31): the
//! file is what a person wrote (SPEC §3), so everything but the edited values stays byte for
//! byte — the free comment, other entries as written, remarks, blank lines, line endings.

use std::ops::Range;

use super::{KorFile, STANDARD_NAMES, TableEdit, fmt_value, key_slot, label, parse};
use crate::diag::Diagnostic;

/// Applies `edit` to `text` (a valid TAB0.KOR): the values written in the entry's line are
/// replaced where they stand, values the line lacks are appended to it, and an entry without a
/// line gets one, in entry order. Returns the new text and its parsed file. A text that does not
/// parse, or a value the table refuses, is an error and nothing is returned.
pub fn edit_text(
    text: &str,
    edit: &TableEdit,
    axis_names: &[char],
) -> Result<(String, KorFile), Vec<Diagnostic>> {
    let mut expected = parse(text, axis_names)?;
    expected
        .table
        .apply(edit)
        .map_err(|e| vec![Diagnostic::error(e.code(), None, 0, 0, e.to_string())])?;
    let eol = if text.contains("\r\n") { "\r\n" } else { "\n" };
    let out = match find_entry_line(text, edit.entry, axis_names) {
        Some(line) => rewrite_line(text, line, edit, axis_names),
        None => insert_line(text, edit, axis_names, eol),
    };
    let file = parse(&out, axis_names)?;
    debug_assert_eq!(file.table, expected.table);
    Ok((out, file))
}

/// Where one entry line stands: its byte range in the text and the value spans by slot.
struct EntryLine {
    /// Bytes of the line's code (before any `;` remark and the line end).
    code: Range<usize>,
    /// Byte range of each value written, by slot (R0 radius, R1..R4 lengths).
    values: [Option<Range<usize>>; 5],
}

/// Lines after `$KOR`: (byte offset of the line, its code without remark and line end).
fn table_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    let mut offset = 0;
    let mut in_table = false;
    text.split_inclusive('\n').filter_map(move |raw| {
        let start = offset;
        offset += raw.len();
        let line = raw.trim_end_matches(['\n', '\r']);
        if !in_table {
            in_table = line.trim_start().starts_with("$KOR");
            return None;
        }
        let code = line.split(';').next().unwrap_or("");
        (!code.trim().is_empty()).then_some((start, code))
    })
}

/// The entry number of a table line's code (`NN:` before the colon), if it is one.
fn entry_of(code: &str) -> Option<u8> {
    let t = code.trim_start();
    let n = t[..t.find(':')?].trim_end();
    (n.len() == 2 && n.bytes().all(|b| b.is_ascii_digit()))
        .then(|| n.parse().ok())
        .flatten()
}

fn find_entry_line(text: &str, entry: u8, axis_names: &[char]) -> Option<EntryLine> {
    let (start, code) = table_lines(text).find(|(_, code)| entry_of(code) == Some(entry))?;
    let colon = code.find(':')?;
    let mut values: [Option<Range<usize>>; 5] = Default::default();
    let mut pos = colon + 1;
    for tok in code[colon + 1..].split_inclusive(char::is_whitespace) {
        let at = pos;
        pos += tok.len();
        let tok = tok.trim_end();
        let Some((key, val)) = tok.split_once('=') else {
            continue;
        };
        if let Ok(slot) = key_slot(key, axis_names) {
            let v0 = start + at + key.len() + 1;
            values[slot] = Some(v0..v0 + val.len());
        }
    }
    Some(EntryLine {
        code: start..start + code.len(),
        values,
    })
}

/// The line with the edited values replaced in place and missing ones appended to its code.
fn rewrite_line(text: &str, line: EntryLine, edit: &TableEdit, axis_names: &[char]) -> String {
    let mut replacements: Vec<(Range<usize>, String)> = Vec::new();
    let code_end = line.code.start + text[line.code.clone()].trim_end().len();
    let mut appended = String::new();
    for (slot, v) in edit.values.iter().enumerate() {
        let Some(v) = v else { continue };
        match &line.values[slot] {
            Some(r) => replacements.push((r.clone(), fmt_value(*v))),
            None => appended.push_str(&format!(
                " {}={}",
                key_label(slot, axis_names),
                fmt_value(*v)
            )),
        }
    }
    if !appended.is_empty() {
        replacements.push((code_end..code_end, appended));
    }
    replacements.sort_by_key(|(r, _)| r.start);
    let mut out = String::with_capacity(text.len() + 32);
    let mut at = 0;
    for (r, s) in replacements {
        out.push_str(&text[at..r.start]);
        out.push_str(&s);
        at = r.end;
    }
    out.push_str(&text[at..]);
    out
}

/// A new line for an entry the file does not list, before the first entry with a higher
/// number (else at the end); only the values of the edit are written (the others are zero).
fn insert_line(text: &str, edit: &TableEdit, axis_names: &[char], eol: &str) -> String {
    let mut line = format!("{:02}:", edit.entry);
    for (slot, v) in edit.values.iter().enumerate() {
        if let Some(v) = v {
            line.push_str(&format!(
                " {}={}",
                key_label(slot, axis_names),
                fmt_value(*v)
            ));
        }
    }
    line.push_str(eol);
    let before = table_lines(text)
        .find(|(_, code)| entry_of(code).is_some_and(|n| n > edit.entry))
        .map(|(start, _)| start);
    let mut out = String::with_capacity(text.len() + line.len() + 1);
    match before {
        Some(at) => {
            out.push_str(&text[..at]);
            out.push_str(&line);
            out.push_str(&text[at..]);
        }
        None => {
            out.push_str(text);
            if !text.is_empty() && !text.ends_with('\n') {
                out.push_str(eol);
            }
            out.push_str(&line);
        }
    }
    out
}

/// `R` for the radius, the label of the axis ordinal for a length (SPEC §3).
fn key_label(slot: usize, axis_names: &[char]) -> String {
    if slot == 0 {
        "R".into()
    } else {
        debug_assert!(slot <= STANDARD_NAMES.len());
        label(slot, axis_names)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MILL: [char; 3] = ['X', 'Y', 'Z'];

    fn edit(entry: u8, values: [Option<f64>; 5]) -> TableEdit {
        TableEdit { entry, values }
    }

    #[test]
    fn an_edit_keeps_comment_other_entries_and_remarks() {
        let text = "my comment\n$KOR\n01: R=7 Z=-2   ; hand\n\n09: R=9\n";
        let (out, f) =
            edit_text(text, &edit(1, [Some(2.0), None, None, None, None]), &MILL).unwrap();
        assert_eq!(
            out,
            "my comment\n$KOR\n01: R=2.0 Z=-2   ; hand\n\n09: R=9\n"
        );
        assert_eq!(f.table.entry(1).unwrap().length_mm[2], -2.0);
        let (out, _) =
            edit_text(text, &edit(1, [None, Some(1.5), None, None, None]), &MILL).unwrap();
        assert_eq!(
            out,
            "my comment\n$KOR\n01: R=7 Z=-2 X=1.5   ; hand\n\n09: R=9\n"
        );
    }

    #[test]
    fn a_new_entry_goes_in_number_order() {
        let text = "c\r\n$KOR\r\n01: R=7\r\n09: R=9";
        let (out, _) =
            edit_text(text, &edit(3, [Some(2.0), None, None, None, None]), &MILL).unwrap();
        assert_eq!(out, "c\r\n$KOR\r\n01: R=7\r\n03: R=2.0\r\n09: R=9");
        let (out, _) =
            edit_text(text, &edit(12, [None, None, None, Some(-1.0), None]), &MILL).unwrap();
        assert_eq!(out, "c\r\n$KOR\r\n01: R=7\r\n09: R=9\r\n12: Z=-1.0\r\n");
    }

    #[test]
    fn a_lathe_length_is_written_by_ordinal() {
        let text = "$KOR\n";
        let (out, _) = edit_text(
            text,
            &edit(2, [None, None, Some(3.0), None, None]),
            &['X', 'Z'],
        )
        .unwrap();
        assert_eq!(out, "$KOR\n02: 2=3.0\n");
    }

    #[test]
    fn a_bad_text_or_value_is_refused() {
        assert!(
            edit_text(
                "no table\n",
                &edit(1, [Some(1.0), None, None, None, None]),
                &MILL
            )
            .is_err()
        );
        assert!(
            edit_text(
                "$KOR\n",
                &edit(1, [Some(1e9), None, None, None, None]),
                &MILL
            )
            .is_err()
        );
    }
}
