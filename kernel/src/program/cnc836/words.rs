//! Words of one block: the lexical layer of the CNC836 dialect (SPEC §2).
//!
//! A block is one line. A word is an address letter and a value, with optional spaces between
//! them (`F 1000` is written in the manual). `R<n>=<value>` assigns a program parameter, `&<n>`
//! selects a length offset, `;` and a quote (`"`, `“`, `”`, `„`) start a remark that runs to the
//! end of the line. Numbers remember whether a decimal point was written: F depends on it (§5).
//! Nothing here allocates except the message of an error.

use crate::diag::DiagCode;

/// A number as written: its value and whether it had a decimal point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Num {
    pub value: f64,
    pub point: bool,
}

/// The value of a word: a number, or a reference to a program parameter (`XR5`, `X-R5`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Value {
    Num(Num),
    Param { index: u8, negate: bool },
}

/// One lexical item of a block.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Token {
    /// Address letter (upper case, or `&`) and its value.
    Word { letter: u8, value: Value },
    /// `R<index>=<value>`: program parameter assignment.
    Assign { index: u8, value: Value },
}

/// A token and the byte offset in the line where it starts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lexed {
    pub token: Token,
    pub at: usize,
}

/// A lexical error: where (byte offset) and what.
#[derive(Clone, Debug, PartialEq)]
pub struct LexError {
    pub at: usize,
    pub code: DiagCode,
    pub message: String,
}

/// Highest program parameter number (SPEC §2: R0...R94).
pub const MAX_PARAM: u8 = 94;

/// Most significant digits in a number; keeps the decimal → binary conversion exact.
const MAX_DIGITS: u32 = 15;

const POW10: [f64; 16] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
];

/// Iterator over the tokens of one line.
pub struct Lexer<'a> {
    b: &'a [u8],
    i: usize,
    done: bool,
}

impl<'a> Lexer<'a> {
    pub fn new(line: &'a str) -> Self {
        Lexer {
            b: line.as_bytes(),
            i: 0,
            done: false,
        }
    }

    fn skip_blanks(&mut self) {
        while self.i < self.b.len() && matches!(self.b[self.i], b' ' | b'\t' | b'\r') {
            self.i += 1;
        }
    }

    fn peek(&self) -> Option<u8> {
        self.b.get(self.i).copied()
    }

    /// `;` or a quote: the rest of the line is a remark.
    fn at_remark(&self) -> bool {
        match self.b[self.i] {
            b';' | b'"' => true,
            // “ ” „ in UTF-8: E2 80 9C / 9D / 9E.
            0xE2 => {
                self.b.get(self.i + 1) == Some(&0x80)
                    && matches!(self.b.get(self.i + 2), Some(0x9C..=0x9E))
            }
            _ => false,
        }
    }

    fn err(
        &mut self,
        at: usize,
        code: DiagCode,
        message: String,
    ) -> Option<Result<Lexed, LexError>> {
        self.done = true;
        Some(Err(LexError { at, code, message }))
    }

    /// A decimal number at the cursor, or `Ok(None)` if there is none.
    fn number(&mut self) -> Result<Option<Num>, LexError> {
        let start = self.i;
        let b = self.b;
        let mut i = self.i;
        let neg = match b.get(i) {
            Some(b'-') => {
                i += 1;
                true
            }
            Some(b'+') => {
                i += 1;
                false
            }
            _ => false,
        };
        let mut mant: u64 = 0;
        let mut sig = 0u32;
        let mut any = false;
        let mut frac = 0usize;
        let mut point = false;
        loop {
            match b.get(i) {
                Some(&c @ b'0'..=b'9') => {
                    any = true;
                    if mant != 0 || c != b'0' {
                        sig += 1;
                        if sig > MAX_DIGITS {
                            return Err(LexError {
                                at: start,
                                code: DiagCode::NumberMalformed,
                                message: format!(
                                    "number has more than {MAX_DIGITS} significant digits"
                                ),
                            });
                        }
                    }
                    mant = mant * 10 + u64::from(c - b'0');
                    if point {
                        frac += 1;
                    }
                }
                Some(b'.') if !point => point = true,
                _ => break,
            }
            i += 1;
        }
        if !any {
            return Ok(None);
        }
        if frac >= POW10.len() {
            return Err(LexError {
                at: start,
                code: DiagCode::NumberMalformed,
                message: "number has too many decimals".into(),
            });
        }
        self.i = i;
        // Both operands are exact in f64, so the quotient is correctly rounded.
        let v = mant as f64 / POW10[frac];
        Ok(Some(Num {
            value: if neg { -v } else { v },
            point,
        }))
    }

    /// `R<digits>` at the cursor: a parameter number 0..94.
    fn param_index(&mut self, at: usize) -> Result<u8, LexError> {
        let s = self.i;
        while self.i < self.b.len() && self.b[self.i].is_ascii_digit() {
            self.i += 1;
        }
        let digits = &self.b[s..self.i];
        let n = if digits.is_empty() || digits.len() > 2 {
            None
        } else {
            Some(digits.iter().fold(0u8, |a, d| a * 10 + (d - b'0')))
        };
        match n {
            Some(n) if n <= MAX_PARAM => Ok(n),
            _ => Err(LexError {
                at,
                code: DiagCode::ParamOutOfRange,
                message: format!("program parameters are R0..R{MAX_PARAM}"),
            }),
        }
    }

    /// The value after an address: a number or a parameter reference.
    fn value(&mut self, letter: u8, at: usize) -> Result<Value, LexError> {
        self.skip_blanks();
        // Parameter reference: [+-]R<n>, but not an assignment R<n>= that follows.
        let save = self.i;
        let negate = match self.peek() {
            Some(b'-') => {
                self.i += 1;
                true
            }
            Some(b'+') => {
                self.i += 1;
                false
            }
            _ => false,
        };
        if matches!(self.peek(), Some(b'R' | b'r')) {
            let r_at = self.i;
            self.i += 1;
            let index = self.param_index(r_at)?;
            self.skip_blanks();
            if self.peek() != Some(b'=') {
                return Ok(Value::Param { index, negate });
            }
        }
        self.i = save;
        match self.number()? {
            Some(n) => Ok(Value::Num(n)),
            None => Err(LexError {
                at,
                code: DiagCode::WordWithoutValue,
                message: format!("address {} has no value", letter as char),
            }),
        }
    }

    fn check_separator(&self) -> Result<(), LexError> {
        match self.peek() {
            None | Some(b' ' | b'\t' | b'\r' | b';' | b'"' | b'&' | 0xE2) => Ok(()),
            Some(c) if c.is_ascii_alphabetic() => Ok(()),
            Some(_) => Err(LexError {
                at: self.i,
                code: DiagCode::UnexpectedCharacter,
                message: format!("unexpected character '{}' after a number", self.char_at()),
            }),
        }
    }

    fn char_at(&self) -> char {
        let s = &self.b[self.i..];
        let n = s.len().min(4);
        (1..=n)
            .find_map(|k| std::str::from_utf8(&s[..k]).ok())
            .and_then(|t| t.chars().next())
            .unwrap_or('?')
    }
}

impl Iterator for Lexer<'_> {
    type Item = Result<Lexed, LexError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        self.skip_blanks();
        if self.i >= self.b.len() || self.at_remark() {
            self.done = true;
            return None;
        }
        let at = self.i;
        let c = self.b[self.i];
        let token = match c {
            b'&' => {
                self.i += 1;
                match self.value(b'&', at) {
                    Ok(value) => Token::Word {
                        letter: b'&',
                        value,
                    },
                    Err(e) => return self.err(e.at, e.code, e.message),
                }
            }
            b'R' | b'r' => {
                self.i += 1;
                let index = match self.param_index(at) {
                    Ok(i) => i,
                    Err(e) => {
                        return self.err(
                            at,
                            e.code,
                            "R is a program parameter assignment R0..R94: R<n>=<value>".into(),
                        );
                    }
                };
                self.skip_blanks();
                if self.peek() != Some(b'=') {
                    return self.err(
                        at,
                        DiagCode::ParamAssignmentSyntax,
                        format!("parameter R{index} needs '=' and a value (R{index}=10.0)"),
                    );
                }
                self.i += 1;
                match self.value(b'=', at) {
                    Ok(value) => Token::Assign { index, value },
                    Err(e) => return self.err(e.at, e.code, format!("R{index}=: {}", e.message)),
                }
            }
            c if c.is_ascii_alphabetic() => {
                self.i += 1;
                let letter = c.to_ascii_uppercase();
                match self.value(letter, at) {
                    Ok(value) => Token::Word { letter, value },
                    Err(e) => return self.err(e.at, e.code, e.message),
                }
            }
            _ => {
                let ch = self.char_at();
                return self.err(
                    at,
                    DiagCode::UnexpectedCharacter,
                    format!("unexpected character '{ch}'"),
                );
            }
        };
        if let Err(e) = self.check_separator() {
            return self.err(e.at, e.code, e.message);
        }
        Some(Ok(Lexed { token, at }))
    }
}

/// Byte offset where the remark of a line starts (`;` or a quote, as the lexer reads them),
/// or the line's length.
pub fn remark_start(line: &str) -> usize {
    let b = line.as_bytes();
    (0..b.len())
        .find(|&i| {
            matches!(b[i], b';' | b'"')
                || (b[i] == 0xE2
                    && b.get(i + 1) == Some(&0x80)
                    && matches!(b.get(i + 2), Some(0x9C..=0x9E)))
        })
        .unwrap_or(b.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn toks(s: &str) -> Vec<Token> {
        Lexer::new(s).map(|t| t.unwrap().token).collect()
    }

    fn num(value: f64, point: bool) -> Value {
        Value::Num(Num { value, point })
    }

    #[test]
    fn decimal_point_is_kept() {
        assert_eq!(
            toks("F1000 F.5 F1.2"),
            [
                Token::Word {
                    letter: b'F',
                    value: num(1000.0, false)
                },
                Token::Word {
                    letter: b'F',
                    value: num(0.5, true)
                },
                Token::Word {
                    letter: b'F',
                    value: num(1.2, true)
                },
            ]
        );
    }

    #[test]
    fn spaces_after_address_and_compact_words() {
        assert_eq!(toks("G94 F 1000"), toks("G94F1000"));
    }

    #[test]
    fn params_assignments_and_references() {
        assert_eq!(
            toks("R5=-2.5 X-R5 R6=R5"),
            [
                Token::Assign {
                    index: 5,
                    value: num(-2.5, true)
                },
                Token::Word {
                    letter: b'X',
                    value: Value::Param {
                        index: 5,
                        negate: true
                    }
                },
                Token::Assign {
                    index: 6,
                    value: Value::Param {
                        index: 5,
                        negate: false
                    }
                },
            ]
        );
    }

    #[test]
    fn remarks_end_the_block() {
        assert_eq!(toks("X1 ; cut"), toks("X1 “rapid to 300"));
        assert_eq!(toks("X1 „KŘR"), toks("X1"));
    }

    #[test]
    fn errors_are_located() {
        let e = Lexer::new("X1 Y").find_map(Result::err).unwrap();
        assert_eq!(
            (e.at, e.code),
            (3, DiagCode::WordWithoutValue),
            "{}",
            e.message
        );
        let e = Lexer::new("X1.2.3").find_map(Result::err).unwrap();
        assert_eq!(e.at, 4);
        let e = Lexer::new("R95=1").find_map(Result::err).unwrap();
        assert_eq!(e.code, DiagCode::ParamOutOfRange, "{}", e.message);
    }

    #[test]
    fn parsing_matches_std_for_short_numbers() {
        for s in [
            "0.1",
            "12.345",
            "-99999.999",
            "5.088",
            "0.0000001",
            "123456789012345",
        ] {
            let Some(Ok(Lexed {
                token:
                    Token::Word {
                        value: Value::Num(n),
                        ..
                    },
                ..
            })) = Lexer::new(&format!("X{s}")).next()
            else {
                panic!("{s}")
            };
            assert_eq!(n.value, s.parse::<f64>().unwrap(), "{s}");
        }
    }
}
