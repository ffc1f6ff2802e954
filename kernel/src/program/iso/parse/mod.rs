//! Text of one ISO line → [`Line`] (LinuxCNC 2.9's reading): case-insensitive, spaces ignored
//! outside comments, `(…)` and `;` comments, `/` block delete, `N`, words with numbers,
//! parameters or bracketed expressions, `#…=` assignments, O-words, `%`.
//!
//! As LinuxCNC (interp_read.cc), the line is first compacted (blanks dropped, letters
//! lower-cased, comments set aside), then read item by item; a value is a number, a
//! parameter, `[expression]`, a function or a signed value.

mod expr;
mod oword;
#[cfg(test)]
mod tests;

use super::Fail;
use super::ast::{Comment, Expr, Line, ParamRef, Word};
use crate::diag::DiagCode;

/// Parses one line. Nothing is evaluated.
///
/// The whole line is read even when it starts with `/`: skipping it under block delete is
/// the caller's decision.
pub fn line(text: &str) -> Result<Line, Fail> {
    let mut c = Cursor::new(text)?;
    let mut out = Line::default();
    if c.percent_only() {
        out.percent = true;
        c.pos = 0;
        c.only_comments(&mut out.comments, |b| b == b'%')?;
        return Ok(out);
    }
    out.block_delete = c.eat(b'/');
    if c.peek() == Some(b'n') {
        out.n = Some(c.n_number()?);
    }
    if c.peek() == Some(b'o') {
        let o = c.oword(&mut out.comments)?;
        c.only_comments(&mut out.comments, |_| false)?;
        out.oword = Some(o);
        return Ok(out);
    }
    while let Some(b) = c.peek() {
        c.item(b, &mut out)?;
    }
    Ok(out)
}

/// A character of the compacted line and its byte offset in the text. A comment is one
/// `(` (a `(` cannot appear otherwise), its text kept aside.
#[derive(Clone, Copy)]
struct Ch {
    b: u8,
    at: usize,
}

/// A comment that means something, recognised as LinuxCNC does (`msg,` right after the
/// leading blanks, any case); the text is trimmed.
fn classify(text: &str) -> Option<Comment> {
    let t = text.trim_start();
    type Make = fn(String) -> Comment;
    let kinds: [(&str, Make); 3] = [
        ("msg,", Comment::Msg),
        ("debug,", Comment::Debug),
        ("print,", Comment::Print),
    ];
    kinds.into_iter().find_map(|(kw, make)| {
        let head = t.as_bytes().get(..kw.len())?;
        head.eq_ignore_ascii_case(kw.as_bytes())
            .then(|| make(t[kw.len()..].trim().to_string()))
    })
}

/// Reading position in the compacted line.
struct Cursor<'a> {
    text: &'a str,
    chars: Vec<Ch>,
    /// Texts of the comments, in order.
    comments: Vec<&'a str>,
    pos: usize,
    /// Comments consumed so far.
    seen: usize,
    nesting: usize,
}

impl<'a> Cursor<'a> {
    /// Compacts `text`: blanks outside comments dropped, ASCII lower-cased, `;` ends the
    /// line; `(` inside a comment and an unclosed comment are errors (LinuxCNC).
    fn new(text: &'a str) -> Result<Self, Fail> {
        let bytes = text.as_bytes();
        let mut chars = Vec::with_capacity(bytes.len());
        let mut comments = Vec::new();
        let mut i = 0;
        while i < bytes.len() {
            match bytes[i] {
                b';' => break,
                b' ' | b'\t' | b'\r' | b'\n' => {}
                b'(' => {
                    let close = comment_end(bytes, i)?;
                    comments.push(&text[i + 1..close]);
                    chars.push(Ch { b: b'(', at: i });
                    i = close;
                }
                b => chars.push(Ch {
                    b: b.to_ascii_lowercase(),
                    at: i,
                }),
            }
            i += 1;
        }
        Ok(Cursor {
            text,
            chars,
            comments,
            pos: 0,
            seen: 0,
            nesting: 0,
        })
    }

    fn peek(&self) -> Option<u8> {
        self.peek_at(0)
    }

    fn peek_at(&self, k: usize) -> Option<u8> {
        self.chars.get(self.pos + k).map(|c| c.b)
    }

    /// Byte offset of the current character (the text's length at the end).
    fn at(&self) -> usize {
        self.chars.get(self.pos).map_or(self.text.len(), |c| c.at)
    }

    fn eat(&mut self, b: u8) -> bool {
        let hit = self.peek() == Some(b);
        if hit {
            self.pos += 1;
        }
        hit
    }

    fn looking_at(&self, s: &str) -> bool {
        let rest = self.chars.get(self.pos..).unwrap_or(&[]);
        rest.len() >= s.len() && rest.iter().zip(s.bytes()).all(|(c, b)| c.b == b)
    }

    fn fail(&self, code: DiagCode, msg: impl ToString) -> Fail {
        Fail::new(self.at(), code, msg)
    }

    /// The current character for messages: `'G'`, `'é'`, or "the end of the line".
    fn shown(&self) -> String {
        let at = self.at();
        match self.text.get(at..).and_then(|s| s.chars().next()) {
            _ if self.peek().is_none() => "the end of the line".to_string(),
            Some(c) if c.is_control() => format!("character {:#04x}", u32::from(c)),
            Some(c) => format!("'{}'", c.to_ascii_uppercase()),
            None => "a character".to_string(),
        }
    }

    /// The letters from here on, upper case, for messages.
    fn letters(&self) -> String {
        let rest = self.chars.get(self.pos..).unwrap_or(&[]);
        rest.iter()
            .map(|c| c.b)
            .take_while(u8::is_ascii_lowercase)
            .map(|b| char::from(b.to_ascii_uppercase()))
            .collect()
    }

    /// Only `%` and comments on the line.
    fn percent_only(&self) -> bool {
        let mut marks = self.chars.iter().filter(|c| c.b != b'(');
        matches!(marks.next(), Some(Ch { b: b'%', .. })) && marks.next().is_none()
    }

    fn comment(&mut self, into: &mut Vec<Comment>) {
        self.pos += 1;
        let text = self.comments.get(self.seen).copied().unwrap_or("");
        self.seen += 1;
        into.extend(classify(text));
    }

    /// The rest of the line holds comments only (and characters `skip` allows).
    fn only_comments(&mut self, into: &mut Vec<Comment>, skip: fn(u8) -> bool) -> Result<(), Fail> {
        while let Some(b) = self.peek() {
            match b {
                b'(' => self.comment(into),
                b if skip(b) => self.pos += 1,
                _ => {
                    return Err(self.fail(
                        DiagCode::UnexpectedCharacter,
                        format!(
                            "{} after an O-word: its line holds only comments",
                            self.shown()
                        ),
                    ));
                }
            }
        }
        Ok(())
    }
}

/// Index of the `)` closing the comment opened at `open`.
fn comment_end(bytes: &[u8], open: usize) -> Result<usize, Fail> {
    for (k, &b) in bytes.iter().enumerate().skip(open + 1) {
        match b {
            b')' => return Ok(k),
            b'(' => {
                return Err(Fail::new(
                    k,
                    DiagCode::UnexpectedCharacter,
                    "'(' inside a comment: comments do not nest",
                ));
            }
            _ => {}
        }
    }
    Err(Fail::new(
        open,
        DiagCode::UnexpectedCharacter,
        "comment not closed by ')'",
    ))
}

// Items of a line: N, words, assignments, O-words.
impl Cursor<'_> {
    /// The `N` number: digits; a fraction is accepted and ignored, as LinuxCNC does
    /// (`N10.5` is N10).
    fn n_number(&mut self) -> Result<u32, Fail> {
        let at = self.at();
        self.pos += 1;
        let mut s = String::new();
        if self.digits(&mut s) == 0 {
            return Err(match self.peek() {
                None | Some(b'(') => {
                    Fail::new(at, DiagCode::WordWithoutValue, "N without a number")
                }
                _ => self.fail(
                    DiagCode::NumberMalformed,
                    "N takes a whole number (digits only)",
                ),
            });
        }
        if self.eat(b'.') && self.digits(&mut String::new()) == 0 {
            return Err(self.fail(
                DiagCode::NumberMalformed,
                "digits missing after the '.' of N",
            ));
        }
        s.parse()
            .map_err(|_| Fail::new(at, DiagCode::NumberMalformed, format!("N{s} is too large")))
    }

    /// Appends the digits from here to `s`; how many.
    fn digits(&mut self, s: &mut String) -> usize {
        let start = self.pos;
        while let Some(b @ b'0'..=b'9') = self.peek() {
            s.push(char::from(b));
            self.pos += 1;
        }
        self.pos - start
    }

    fn item(&mut self, b: u8, out: &mut Line) -> Result<(), Fail> {
        match b {
            b'(' => self.comment(&mut out.comments),
            b'#' => {
                let a = self.assignment()?;
                out.assigns.push(a);
            }
            b'n' => {
                return Err(self.fail(
                    DiagCode::BlockNumberNotFirst,
                    "N must be the first word of the line",
                ));
            }
            b'o' => {
                return Err(self.fail(
                    DiagCode::UnexpectedCharacter,
                    "an O-word must begin its line (after '/' and N)",
                ));
            }
            b'a'..=b'z' => {
                let w = self.word()?;
                out.words.push(w);
            }
            b'@' | b'^' => {
                return Err(self.fail(
                    DiagCode::IsoUnsupported,
                    "polar coordinates ('@', '^') are not supported",
                ));
            }
            b'$' => {
                return Err(self.fail(
                    DiagCode::IsoUnsupported,
                    "spindle selection '$' is not supported",
                ));
            }
            _ => {
                return Err(self.fail(
                    DiagCode::UnexpectedCharacter,
                    format!("unexpected {}", self.shown()),
                ));
            }
        }
        Ok(())
    }

    fn word(&mut self) -> Result<Word, Fail> {
        let at = self.at();
        let letter = self.chars[self.pos].b.to_ascii_uppercase();
        self.pos += 1;
        if !self.starts_value() {
            return Err(Fail::new(
                at,
                DiagCode::WordWithoutValue,
                format!("{} without a value", char::from(letter)),
            ));
        }
        let v = self.value()?;
        Ok(Word {
            letter,
            value: v.e,
            at,
        })
    }

    /// Whether a value begins here (a letter only when it begins a function name).
    fn starts_value(&self) -> bool {
        match self.peek() {
            Some(b'[' | b'#' | b'+' | b'-' | b'.' | b'0'..=b'9') => true,
            Some(b'a'..=b'z') => self.function_name().is_some(),
            _ => false,
        }
    }

    /// `#ref = value`; LinuxCNC allows any number of them among the words.
    fn assignment(&mut self) -> Result<(ParamRef, Expr, usize), Fail> {
        let at = self.at();
        let (r, _) = self.param_ref()?;
        if !self.eat(b'=') {
            return Err(self.fail(
                DiagCode::ExpressionSyntax,
                format!("'=' expected after a parameter, found {}", self.shown()),
            ));
        }
        let v = self.value()?;
        Ok((r, v.e, at))
    }
}
