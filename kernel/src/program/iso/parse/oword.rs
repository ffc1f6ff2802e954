//! O-word lines: label (`O100`, `O<name>`), keyword and its condition or call arguments.

use super::Cursor;
use crate::diag::DiagCode;
use crate::program::iso::Fail;
use crate::program::iso::ast::{Comment, Expr, Label, OKeyword, OWord};

/// Arguments of a call: they become #1..#30 of the subroutine.
const MAX_ARGS: usize = 30;

/// O-word keywords; the longest one written wins (`elseif` over `else`).
const KEYWORDS: [&str; 15] = [
    "sub",
    "endsub",
    "call",
    "do",
    "while",
    "repeat",
    "if",
    "elseif",
    "else",
    "endif",
    "break",
    "continue",
    "endwhile",
    "endrepeat",
    "return",
];

/// `O100` or `O<name>` for messages.
fn label_text(l: &Label) -> String {
    match l {
        Label::Number(n) => format!("O{n}"),
        Label::Name(s) => format!("O<{s}>"),
    }
}

// O-words.
impl Cursor<'_> {
    /// An O-word line: label, keyword and its arguments (comments among call arguments go
    /// to `comments`).
    pub(super) fn oword(&mut self, comments: &mut Vec<Comment>) -> Result<OWord, Fail> {
        let at = self.at();
        self.pos += 1;
        let label = match self.peek() {
            Some(b'<') => Label::Name(self.name()?),
            Some(b'0'..=b'9') => self.label_number()?,
            Some(b'#' | b'[') => {
                return Err(self.fail(
                    DiagCode::IsoUnsupported,
                    "a computed O-word label is not supported: write O100 or O<name>",
                ));
            }
            _ => {
                return Err(Fail::new(
                    at,
                    DiagCode::WordWithoutValue,
                    "O without its label (O100 or O<name>)",
                ));
            }
        };
        let keyword = self.okeyword(&label, comments)?;
        Ok(OWord { label, keyword, at })
    }

    /// A numbered label; `O100.0` is O100 (LinuxCNC reads it as a whole number).
    fn label_number(&mut self) -> Result<Label, Fail> {
        let at = self.at();
        let mut s = String::new();
        self.digits(&mut s);
        let mut frac = String::new();
        if self.eat(b'.') {
            self.digits(&mut frac);
        }
        if frac.bytes().any(|b| b != b'0') {
            return Err(Fail::new(
                at,
                DiagCode::WordNotWhole,
                format!("O-word label {s}.{frac} is not a whole number"),
            ));
        }
        s.parse().map(Label::Number).map_err(|_| {
            Fail::new(
                at,
                DiagCode::NumberMalformed,
                format!("O-word label {s} is too large"),
            )
        })
    }

    fn okeyword(&mut self, label: &Label, comments: &mut Vec<Comment>) -> Result<OKeyword, Fail> {
        let found = KEYWORDS
            .iter()
            // A keyword is a whole word: `callsub` is no `call`.
            .filter(|k| {
                self.looking_at(k)
                    && !self
                        .peek_at(k.len())
                        .is_some_and(|b| b.is_ascii_alphabetic())
            })
            .max_by_key(|k| k.len());
        let Some(&kw) = found else {
            return Err(self.unknown_keyword(label));
        };
        self.pos += kw.len();
        Ok(match kw {
            "sub" => OKeyword::Sub,
            "endsub" => OKeyword::EndSub(self.optional_expr()?),
            "call" => OKeyword::Call(self.call_args(comments)?),
            "return" => OKeyword::Return(self.optional_expr()?),
            "do" => OKeyword::Do,
            "while" => OKeyword::While(self.condition(kw)?),
            "endwhile" => OKeyword::EndWhile,
            "if" => OKeyword::If(self.condition(kw)?),
            "elseif" => OKeyword::ElseIf(self.condition(kw)?),
            "else" => OKeyword::Else,
            "endif" => OKeyword::EndIf,
            "repeat" => OKeyword::Repeat(self.condition(kw)?),
            "endrepeat" => OKeyword::EndRepeat,
            "break" => OKeyword::Break,
            _ => OKeyword::Continue,
        })
    }

    fn unknown_keyword(&self, label: &Label) -> Fail {
        let l = label_text(label);
        match self.peek() {
            None | Some(b'(') => self.fail(
                DiagCode::IsoUnsupported,
                format!("{l} without a keyword (a Fanuc-style program number) is not supported"),
            ),
            Some(b'a'..=b'z') => self.fail(
                DiagCode::ExpressionSyntax,
                format!("unknown O-word keyword {} after {l}", self.letters()),
            ),
            _ => self.fail(
                DiagCode::ExpressionSyntax,
                format!(
                    "a keyword (sub, call, if, while …) expected after {l}, found {}",
                    self.shown()
                ),
            ),
        }
    }

    /// `[expr]` that `while`, `if`, `elseif` and `repeat` need.
    fn condition(&mut self, kw: &str) -> Result<Expr, Fail> {
        if self.peek() != Some(b'[') {
            return Err(self.fail(
                DiagCode::ExpressionSyntax,
                format!("'[' missing after '{kw}'"),
            ));
        }
        Ok(self.value()?.e)
    }

    /// The optional `[expr]` of `endsub` and `return`.
    fn optional_expr(&mut self) -> Result<Option<Expr>, Fail> {
        if self.peek() != Some(b'[') {
            return Ok(None);
        }
        Ok(Some(self.value()?.e))
    }

    fn call_args(&mut self, comments: &mut Vec<Comment>) -> Result<Vec<Expr>, Fail> {
        let mut args = Vec::new();
        loop {
            match self.peek() {
                Some(b'[') if args.len() == MAX_ARGS => {
                    return Err(self.fail(
                        DiagCode::IsoParamOutOfRange,
                        "a call takes at most 30 arguments (#1..#30)",
                    ));
                }
                Some(b'[') => args.push(self.value()?.e),
                Some(b'(') => self.comment(comments),
                _ => return Ok(args),
            }
        }
    }
}
