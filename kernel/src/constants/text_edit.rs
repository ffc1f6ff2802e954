//! Setting constants in the text of the constants file in place (issue #31): the file is what
//! a person wrote, so only the values set change; comments, other constants as written (e.g.
//! `R039=00045.000` typed by hand), blank lines and line endings stay byte for byte.

use std::ops::Range;

use super::{Constants, fmt_milli};
use crate::diag::Diagnostic;

/// Sets each `(constant, thousandths)` of `values` in `text` (a valid constants file): the value
/// of its line is replaced where it stands; a constant without a line gets one at the end.
/// Returns the new text and the constants it holds. A text that does not parse is an error.
pub fn edit_text(
    text: &str,
    values: &[(u16, i64)],
) -> Result<(String, Constants), Vec<Diagnostic>> {
    Constants::parse(text)?;
    let eol = if text.contains("\r\n") { "\r\n" } else { "\n" };
    let mut replacements: Vec<(Range<usize>, String)> = Vec::new();
    let mut missing: Vec<(u16, i64)> = Vec::new();
    for &(r, m) in values {
        // The last value given for a constant wins.
        missing.retain(|(n, _)| *n != r);
        match value_span(text, r) {
            Some(span) => {
                replacements.retain(|(s, _)| *s != span);
                replacements.push((span, fmt_milli(m)));
            }
            None => missing.push((r, m)),
        }
    }
    replacements.sort_by_key(|(r, _)| r.start);
    let mut out = String::with_capacity(text.len() + 16 * missing.len());
    let mut at = 0;
    for (r, s) in replacements {
        out.push_str(&text[at..r.start]);
        out.push_str(&s);
        at = r.end;
    }
    out.push_str(&text[at..]);
    if !missing.is_empty() && !out.is_empty() && !out.ends_with('\n') {
        out.push_str(eol);
    }
    for (r, m) in missing {
        out.push_str(&format!("R{r:03}={}{eol}", fmt_milli(m)));
    }
    let c = Constants::parse(&out)?;
    Ok((out, c))
}

/// Byte range of the value of constant `r`'s line in `text`, if a line sets it.
fn value_span(text: &str, r: u16) -> Option<Range<usize>> {
    let mut offset = 0;
    for raw in text.split_inclusive('\n') {
        let start = offset;
        offset += raw.len();
        let code = raw
            .split(';')
            .next()
            .unwrap_or("")
            .trim_end_matches(['\n', '\r']);
        let t = code.trim_start();
        let Some(rest) = t.strip_prefix(['R', 'r']) else {
            continue;
        };
        let digits = rest.bytes().take_while(u8::is_ascii_digit).count();
        if rest[..digits].parse::<u32>().ok() != Some(u32::from(r)) {
            continue;
        }
        let eq = code.find('=')?;
        let after = &code[eq + 1..];
        let v0 = eq + 1 + (after.len() - after.trim_start().len());
        let v1 = v0 + code[v0..].trim_end().len();
        return Some(start + v0..start + v1);
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_set_keeps_hand_written_lines() {
        let text = "; mine\nR039=00045.000\nR52 = 500   ; accel\n";
        let (out, c) = edit_text(text, &[(52, 600_000)]).unwrap();
        assert_eq!(out, "; mine\nR039=00045.000\nR52 = 00600.000   ; accel\n");
        assert_eq!(c.get(39), 45.0);
        let (out, _) = edit_text(text, &[(384, 200_010), (52, 1)]).unwrap();
        assert_eq!(
            out,
            "; mine\nR039=00045.000\nR52 = 00000.001   ; accel\nR384=00200.010\n"
        );
    }

    #[test]
    fn no_final_newline_and_crlf_are_kept() {
        let (out, _) = edit_text("R1=2\r\nR2=3", &[(7, 5)]).unwrap();
        assert_eq!(out, "R1=2\r\nR2=3\r\nR007=00000.005\r\n");
        assert!(edit_text("R1=x\n", &[(7, 5)]).is_err());
    }
}
