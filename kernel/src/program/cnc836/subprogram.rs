//! The subprogram forms of the dialect (docs/language.md, "Subprograms and repeats"): a line
//! `%L<n>` starts subprogram n, a block `M17` ends it, a block `L<n>` calls it and
//! `L<n> P<count>` calls it `count` times. Running them is [`super::flow`]'s.
//!
//! Where a subprogram starts and ends is read from the text alone (the flow passes over
//! definitions and looks for labels without interpreting), so both forms are plain text:
//! a label line, and M17 written as a number.

use super::collect::{MAX_LABEL, Words};
use super::words::{Lexer, Num, Token, Value, remark_start};
use super::{Control, Fail, fail};
use crate::diag::DiagCode;

/// A line `%L<n>` (after blanks, before a remark): `Some(Ok(n))`; `Some(Err)`: `%L` written
/// wrong; `None`: not a label line (a bare `%` stays the lexer's business).
#[inline]
pub(super) fn label_line(text: &str) -> Option<Result<u16, Fail>> {
    // Bytes first: this runs for every line of every program.
    let b = text.as_bytes();
    let k = b.iter().position(|&c| c != b' ' && c != b'\t')?;
    if b[k] != b'%' {
        return None;
    }
    let rest = text[k + 1..].strip_prefix(['L', 'l'])?;
    let at = text.len() - rest.len();
    let digits = rest.len() - rest.trim_start_matches(|c: char| c.is_ascii_digit()).len();
    let tail = &rest[digits..];
    let tail = &tail[..remark_start(tail)];
    let n = rest[..digits].parse::<u32>().ok();
    match n {
        Some(n @ 1..=MAX_LABEL) if tail.trim().is_empty() => Some(Ok(n as u16)),
        _ => Some(fail(
            at,
            DiagCode::SubprogramSyntax,
            format!(
                "a subprogram starts with a line %L<n>, n a whole number 1..{MAX_LABEL}, alone on its line"
            ),
        )),
    }
}

/// Whether `text` is the end of a subprogram as the text shows it: it lexes without error and
/// has the word M17 (written as a number). What else is in the block is checked when it runs.
pub(super) fn is_return_line(text: &str) -> bool {
    let mut m17 = false;
    for t in Lexer::new(text) {
        match t {
            Ok(t) => m17 |= is_m17(&t.token),
            Err(_) => return false,
        }
    }
    m17
}

fn is_m17(t: &Token) -> bool {
    matches!(
        t,
        Token::Word {
            letter: b'M',
            value: Value::Num(Num {
                value: 17.0,
                point: false
            })
        }
    )
}

/// The call `L<n> [P<count>]` or the end M17 in the collected words of a block, checked to
/// stand alone (with N and a remark); `None`: the block is neither.
#[inline]
pub(super) fn form(w: &Words, text: &str) -> Result<Option<Control>, Fail> {
    if w.ret.is_none() && w.call.is_none() && w.count.is_none() {
        return Ok(None);
    }
    let n_word = usize::from(w.n.is_some());
    if let Some(at) = w.ret {
        if usize::from(w.words) > 1 + n_word {
            let other = first_other(text, is_m17);
            return fail(
                other.unwrap_or(at),
                DiagCode::SubprogramSyntax,
                "M17 ends a subprogram: it stands in a block of its own (N and a remark besides)",
            );
        }
        return Ok(Some(Control::Return));
    }
    if w.call.is_none()
        && let Some((_, at)) = w.count
    {
        return fail(
            at,
            DiagCode::SubprogramSyntax,
            "P is the number of passes of a subprogram call: L<n> P<count>",
        );
    }
    let Some((label, at)) = w.call else {
        return Ok(None);
    };
    if usize::from(w.words) > 1 + n_word + usize::from(w.count.is_some()) {
        let other = first_other(text, |t| {
            matches!(
                t,
                Token::Word {
                    letter: b'L' | b'P',
                    ..
                }
            )
        });
        return fail(
            other.unwrap_or(at),
            DiagCode::SubprogramSyntax,
            "a subprogram call L<n> P<count> stands in a block of its own (N and a remark besides)",
        );
    }
    Ok(Some(Control::Call {
        label,
        count: w.count.map_or(1, |c| c.0),
        n: w.n,
    }))
}

/// Where the first word of `text` that is neither N (first) nor `allowed` starts.
fn first_other(text: &str, allowed: impl Fn(&Token) -> bool) -> Option<usize> {
    Lexer::new(text)
        .enumerate()
        .map_while(|(k, t)| t.ok().map(|t| (k, t)))
        .find(|(k, t)| {
            !(allowed(&t.token) || (*k == 0 && matches!(t.token, Token::Word { letter: b'N', .. })))
        })
        .map(|(_, t)| t.at)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn label_lines() {
        assert_eq!(label_line("%L10").map(|r| r.ok()), Some(Some(10)));
        assert_eq!(label_line("  %l7 ; part B").map(|r| r.ok()), Some(Some(7)));
        assert_eq!(label_line("%L9999 “last").map(|r| r.ok()), Some(Some(9999)));
        for bad in ["%L", "%L0", "%L10000", "%L1.5", "%L10 X1", "%L-1"] {
            let f = label_line(bad).unwrap().err().unwrap();
            assert_eq!(f.code, DiagCode::SubprogramSyntax, "{bad}");
        }
        for other in ["%", "% 10", "%X", "/%L10", "N10 %L1", "L10"] {
            assert!(label_line(other).is_none(), "{other}");
        }
    }

    #[test]
    fn return_lines() {
        assert!(is_return_line("M17"));
        assert!(is_return_line("N90 M17 ; back"));
        assert!(
            is_return_line("G0 X1 M17"),
            "found, then refused when it runs"
        );
        assert!(!is_return_line("M17.0"));
        assert!(!is_return_line("M170"));
        assert!(!is_return_line("MR1"));
        assert!(!is_return_line("/M17"));
        assert!(!is_return_line("M17 X1.2.3"));
        assert!(!is_return_line("; M17"));
    }
}
