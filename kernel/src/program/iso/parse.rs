//! Text of one ISO line → [`Line`] (LinuxCNC 2.9's reading): case-insensitive, spaces ignored
//! outside comments, `(…)` and `;` comments, `/` block delete, `N`, words with numbers,
//! parameters or bracketed expressions, `#…=` assignments, O-words, `%`.
//!
//! As LinuxCNC (interp_read.cc), the line is first compacted (blanks dropped, letters
//! lower-cased, comments set aside), then read item by item; a value is a number, a
//! parameter, `[expression]`, a function or a signed value.

use super::Fail;
use super::ast::{BinOp, Comment, Expr, Func, Label, Line, OKeyword, OWord, ParamRef, Word};
use crate::diag::DiagCode;

/// Deepest nesting of brackets, functions, signs and `#` in one value: bounds the
/// parser's recursion.
const MAX_NESTING: usize = 64;

/// Tallest expression tree: bounds the recursion of evaluating and dropping it (a chain
/// `[1+1+…]` is as tall as it has operators).
const MAX_HEIGHT: u32 = 256;

/// Arguments of a call: they become #1..#30 of the subroutine.
const MAX_ARGS: usize = 30;

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

/// A parsed value and the height of its tree.
struct Node {
    e: Expr,
    h: u32,
}

/// What a function name stands for.
#[derive(Clone, Copy)]
enum FuncKind {
    Unary(Func),
    Atan,
    Exists,
}

/// Function names (lower case); none is a prefix of another.
const FUNCS: [(&str, FuncKind); 14] = [
    ("abs", FuncKind::Unary(Func::Abs)),
    ("acos", FuncKind::Unary(Func::Acos)),
    ("asin", FuncKind::Unary(Func::Asin)),
    ("atan", FuncKind::Atan),
    ("cos", FuncKind::Unary(Func::Cos)),
    ("exp", FuncKind::Unary(Func::Exp)),
    ("exists", FuncKind::Exists),
    ("fix", FuncKind::Unary(Func::Fix)),
    ("fup", FuncKind::Unary(Func::Fup)),
    ("ln", FuncKind::Unary(Func::Ln)),
    ("round", FuncKind::Unary(Func::Round)),
    ("sin", FuncKind::Unary(Func::Sin)),
    ("sqrt", FuncKind::Unary(Func::Sqrt)),
    ("tan", FuncKind::Unary(Func::Tan)),
];

/// Binary operators written as words.
const WORD_OPS: [(&str, BinOp); 10] = [
    ("and", BinOp::And),
    ("mod", BinOp::Mod),
    ("xor", BinOp::Xor),
    ("or", BinOp::Or),
    ("eq", BinOp::Eq),
    ("ne", BinOp::Ne),
    ("gt", BinOp::Gt),
    ("ge", BinOp::Ge),
    ("lt", BinOp::Lt),
    ("le", BinOp::Le),
];

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

/// LinuxCNC's precedence classes, higher binds tighter.
fn precedence(op: BinOp) -> u8 {
    match op {
        BinOp::Pow => 5,
        BinOp::Mul | BinOp::Div | BinOp::Mod => 4,
        BinOp::Add | BinOp::Sub => 3,
        BinOp::Eq | BinOp::Ne | BinOp::Gt | BinOp::Ge | BinOp::Lt | BinOp::Le => 2,
        BinOp::And | BinOp::Or | BinOp::Xor => 1,
    }
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

/// `O100` or `O<name>` for messages.
fn label_text(l: &Label) -> String {
    match l {
        Label::Number(n) => format!("O{n}"),
        Label::Name(s) => format!("O<{s}>"),
    }
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

    /// An O-word line: label, keyword and its arguments (comments among call arguments go
    /// to `comments`).
    fn oword(&mut self, comments: &mut Vec<Comment>) -> Result<OWord, Fail> {
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
            .filter(|k| self.looking_at(k))
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

// Values and expressions.
impl Cursor<'_> {
    /// A node of height `h`, refused when too tall.
    fn node(&self, e: Expr, h: u32) -> Result<Node, Fail> {
        if h > MAX_HEIGHT {
            return Err(self.fail(
                DiagCode::ExpressionSyntax,
                format!("expression too long or deep (more than {MAX_HEIGHT} levels)"),
            ));
        }
        Ok(Node { e, h })
    }

    /// A value (LinuxCNC read_real_value), nesting bounded.
    fn value(&mut self) -> Result<Node, Fail> {
        if self.nesting >= MAX_NESTING {
            return Err(self.fail(
                DiagCode::ExpressionSyntax,
                format!("expression nested deeper than {MAX_NESTING} levels"),
            ));
        }
        self.nesting += 1;
        let v = self.value_inner();
        self.nesting -= 1;
        v
    }

    fn value_inner(&mut self) -> Result<Node, Fail> {
        match self.peek() {
            None => Err(self.fail(
                DiagCode::ExpressionSyntax,
                "value missing at the end of the line",
            )),
            Some(b'[') => self.bracketed(),
            Some(b'#') => {
                let (r, h) = self.param_ref()?;
                self.node(Expr::Param(r), h)
            }
            // A sign before a digit or '.' belongs to the number (`-2**2` is 4 as in
            // LinuxCNC); before anything else it is a unary operator on the next value.
            Some(s @ (b'+' | b'-'))
                if !matches!(self.peek_at(1), None | Some(b'0'..=b'9' | b'.')) =>
            {
                self.pos += 1;
                let v = self.value()?;
                if s == b'-' {
                    self.node(Expr::Neg(Box::new(v.e)), v.h + 1)
                } else {
                    Ok(v)
                }
            }
            Some(b'a'..=b'z') => self.function(),
            Some(b'+' | b'-' | b'.' | b'0'..=b'9') => self.number(),
            Some(_) => Err(self.fail(
                DiagCode::ExpressionSyntax,
                format!("a value expected, found {}", self.shown()),
            )),
        }
    }

    /// A number: optional sign, digits, optional `.` and digits; no exponent (`1E5` is 1 and
    /// a word E5, as LinuxCNC).
    fn number(&mut self) -> Result<Node, Fail> {
        let at = self.at();
        let mut s = String::new();
        if let Some(b @ (b'+' | b'-')) = self.peek() {
            s.push(char::from(b));
            self.pos += 1;
        }
        let mut count = self.digits(&mut s);
        if self.eat(b'.') {
            s.push('.');
            count += self.digits(&mut s);
        }
        if count == 0 {
            return Err(Fail::new(
                at,
                DiagCode::NumberMalformed,
                "a number without digits",
            ));
        }
        if self.peek() == Some(b'.') {
            return Err(self.fail(DiagCode::NumberMalformed, "a second '.' in a number"));
        }
        match s.parse::<f64>() {
            Ok(v) if v.is_finite() => self.node(Expr::Num(v), 1),
            _ => Err(Fail::new(
                at,
                DiagCode::NumberMalformed,
                format!("number {s} is too large"),
            )),
        }
    }

    /// `#` and what follows: `<name>` or a value giving the number (`#12`, `##1`, `#[…]`).
    fn param_ref(&mut self) -> Result<(ParamRef, u32), Fail> {
        self.pos += 1;
        if self.peek() == Some(b'<') {
            return Ok((ParamRef::Named(self.name()?), 1));
        }
        if !self.starts_value() {
            return Err(self.fail(
                DiagCode::ExpressionSyntax,
                format!(
                    "a parameter number or <name> expected after '#', found {}",
                    self.shown()
                ),
            ));
        }
        let n = self.value()?;
        Ok((ParamRef::Number(Box::new(n.e)), n.h + 1))
    }

    /// `<name>`: lower-cased, blanks removed (by the compaction), not empty.
    fn name(&mut self) -> Result<String, Fail> {
        let at = self.at();
        self.pos += 1;
        let mut bytes = Vec::new();
        loop {
            match self.peek() {
                None => {
                    return Err(Fail::new(
                        at,
                        DiagCode::ExpressionSyntax,
                        "'<' not closed by '>'",
                    ));
                }
                Some(b'(') => {
                    return Err(self.fail(DiagCode::ExpressionSyntax, "a comment inside a <name>"));
                }
                Some(b'>') => break,
                Some(b) => bytes.push(b),
            }
            self.pos += 1;
        }
        self.pos += 1;
        if bytes.is_empty() {
            return Err(Fail::new(at, DiagCode::ExpressionSyntax, "empty name <>"));
        }
        Ok(String::from_utf8_lossy(&bytes).into_owned())
    }

    /// `[expression]`, operators by LinuxCNC's precedence, left to right within a class.
    fn bracketed(&mut self) -> Result<Node, Fail> {
        self.pos += 1;
        let first = self.value()?;
        let v = self.climb(first, 0)?;
        // `climb` from class 0 stops only at `]` (or fails).
        self.pos += 1;
        Ok(v)
    }

    /// Precedence climbing: folds operators of class `min` and above into `lhs`. Recursion
    /// is bounded by the number of classes.
    fn climb(&mut self, mut lhs: Node, min: u8) -> Result<Node, Fail> {
        while let Some((op, len)) = self.peek_op()? {
            let p = precedence(op);
            if p < min {
                break;
            }
            self.pos += len;
            let mut rhs = self.value()?;
            while let Some((next, _)) = self.peek_op()? {
                if precedence(next) <= p {
                    break;
                }
                rhs = self.climb(rhs, p + 1)?;
            }
            let h = lhs.h.max(rhs.h) + 1;
            lhs = self.node(Expr::Bin(op, Box::new(lhs.e), Box::new(rhs.e)), h)?;
        }
        Ok(lhs)
    }

    /// The operator here and its length, `None` at `]`.
    fn peek_op(&self) -> Result<Option<(BinOp, usize)>, Fail> {
        let op = match self.peek() {
            None => return Err(self.fail(DiagCode::ExpressionSyntax, "'[' not closed by ']'")),
            Some(b']') => return Ok(None),
            Some(b'+') => (BinOp::Add, 1),
            Some(b'-') => (BinOp::Sub, 1),
            Some(b'/') => (BinOp::Div, 1),
            Some(b'*') if self.peek_at(1) == Some(b'*') => (BinOp::Pow, 2),
            Some(b'*') => (BinOp::Mul, 1),
            Some(_) => match WORD_OPS.iter().find(|(w, _)| self.looking_at(w)) {
                Some(&(w, op)) => (op, w.len()),
                None => {
                    return Err(self.fail(
                        DiagCode::ExpressionSyntax,
                        format!("an operator or ']' expected, found {}", self.shown()),
                    ));
                }
            },
        };
        Ok(Some(op))
    }

    fn function_name(&self) -> Option<(&'static str, FuncKind)> {
        FUNCS
            .iter()
            .copied()
            .find(|(name, _)| self.looking_at(name))
    }

    /// `NAME[…]`, `ATAN[…]/[…]` or `EXISTS[#<name>]`.
    fn function(&mut self) -> Result<Node, Fail> {
        let Some((name, kind)) = self.function_name() else {
            return Err(self.fail(
                DiagCode::ExpressionSyntax,
                format!(
                    "unknown function or operator {} where a value belongs",
                    self.letters()
                ),
            ));
        };
        self.pos += name.len();
        if self.peek() != Some(b'[') {
            return Err(self.fail(
                DiagCode::ExpressionSyntax,
                format!("'[' missing after {}", name.to_ascii_uppercase()),
            ));
        }
        match kind {
            FuncKind::Unary(f) => {
                let a = self.bracketed()?;
                self.node(Expr::Func(f, Box::new(a.e)), a.h + 1)
            }
            FuncKind::Atan => self.atan(),
            FuncKind::Exists => self.exists(),
        }
    }

    fn atan(&mut self) -> Result<Node, Fail> {
        let y = self.bracketed()?;
        if !self.eat(b'/') || self.peek() != Some(b'[') {
            return Err(self.fail(
                DiagCode::ExpressionSyntax,
                "ATAN[y] must be followed by /[x]",
            ));
        }
        let x = self.bracketed()?;
        let h = y.h.max(x.h) + 1;
        self.node(Expr::Atan2(Box::new(y.e), Box::new(x.e)), h)
    }

    fn exists(&mut self) -> Result<Node, Fail> {
        self.pos += 1;
        if !self.eat(b'#') {
            return Err(self.fail(
                DiagCode::ExpressionSyntax,
                "EXISTS takes a parameter: EXISTS[#<name>]",
            ));
        }
        if self.peek() != Some(b'<') {
            return Err(self.fail(
                DiagCode::IsoUnsupported,
                "EXISTS of a numbered parameter is not supported: EXISTS[#<name>]",
            ));
        }
        let name = self.name()?;
        if !self.eat(b']') {
            return Err(self.fail(
                DiagCode::ExpressionSyntax,
                "']' missing after EXISTS[#<name>",
            ));
        }
        self.node(Expr::Exists(name), 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::program::iso::expr::eval;
    use crate::program::iso::params::Params;

    fn ok(text: &str) -> Line {
        match line(text) {
            Ok(l) => l,
            Err(e) => panic!("{text:?}: {e:?}"),
        }
    }

    fn err(text: &str) -> Fail {
        match line(text) {
            Ok(l) => panic!("{text:?} parsed: {l:?}"),
            Err(e) => e,
        }
    }

    fn code(text: &str) -> DiagCode {
        err(text).code
    }

    /// The value of the only word of `text`.
    fn value_with(text: &str, p: &Params) -> Result<f64, Fail> {
        let l = ok(text);
        assert_eq!(l.words.len(), 1, "{text:?}");
        eval(&l.words[0].value, p, l.words[0].at)
    }

    fn value(text: &str) -> f64 {
        value_with(text, &Params::new()).unwrap()
    }

    fn num(v: f64) -> Expr {
        Expr::Num(v)
    }

    fn numbered(v: f64) -> ParamRef {
        ParamRef::Number(Box::new(num(v)))
    }

    #[test]
    fn words_numbers_and_offsets() {
        let l = ok("G1 X10.5 y-.5 Z+3 F5.");
        let got: Vec<(u8, Expr, usize)> = l
            .words
            .into_iter()
            .map(|w| (w.letter, w.value, w.at))
            .collect();
        assert_eq!(
            got,
            vec![
                (b'G', num(1.0), 0),
                (b'X', num(10.5), 3),
                (b'Y', num(-0.5), 9),
                (b'Z', num(3.0), 14),
                (b'F', num(5.0), 18),
            ]
        );
        assert_eq!(ok("G01").words[0].value, num(1.0));
        assert_eq!(value("X+.5"), 0.5);
        assert_eq!(value("X-0.5"), -0.5);
        assert_eq!(value("X007"), 7.0);
        // Two words of one letter are both kept.
        assert_eq!(ok("X1X2").words.len(), 2);
    }

    #[test]
    fn blanks_are_ignored_outside_comments() {
        let l = ok("G 1 X 1 0\t.2 5");
        assert_eq!(l.words[0].value, num(1.0));
        assert_eq!((l.words[1].value.clone(), l.words[1].at), (num(10.25), 4));
        let a = ok("#<my var> = 2");
        assert_eq!(a.assigns[0].0, ParamRef::Named("myvar".into()));
        assert_eq!(value("X [ 1 + 2 m o d 2 ]"), 1.0);
        assert_eq!(
            ok("o 1 0 0 e n d s u b").oword.unwrap().label,
            Label::Number(100)
        );
        assert_eq!(ok("  \t ").words.len(), 0);
        assert_eq!(ok(""), Line::default());
    }

    #[test]
    fn case_insensitive() {
        let l = ok("g1 x1 #<MyVar>=[SIN[90] Mod 2]");
        assert_eq!(l.words[0].letter, b'G');
        assert_eq!(l.words[1].letter, b'X');
        assert_eq!(l.assigns[0].0, ParamRef::Named("myvar".into()));
        assert_eq!(eval(&l.assigns[0].1, &Params::new(), 0), Ok(1.0));
    }

    #[test]
    fn precedence_as_linuxcnc() {
        assert_eq!(value("X[1+2*3]"), 7.0);
        assert_eq!(value("X[2**3**2]"), 64.0);
        assert_eq!(value("X[2*3**2]"), 18.0);
        assert_eq!(value("X[1 + 2 LT 4]"), 1.0);
        assert_eq!(value("X[1 + 2 GT 4]"), 0.0);
        assert_eq!(value("X[10-4-3]"), 3.0);
        assert_eq!(value("X[64/4/2]"), 8.0);
        assert_eq!(value("X[7 MOD 4 * 2]"), 6.0);
        assert_eq!(value("X[1 EQ 1 AND 2 GT 1]"), 1.0);
        assert_eq!(value("X[0 OR 1 XOR 1]"), 0.0);
        assert_eq!(value("X[1 LT 2 EQ 1]"), 1.0);
        assert_eq!(value("X[1+2*3**2-4/2]"), 17.0);
        assert_eq!(value("X[[1+2]*3]"), 9.0);
        // A word's value is one value: an operator outside brackets is not part of it.
        assert_eq!(code("X[1 GE 1]+[2]"), DiagCode::UnexpectedCharacter);
        assert_eq!(code("X#1+2"), DiagCode::UnexpectedCharacter);
    }

    #[test]
    fn signs() {
        // The sign of a number is part of it: -2**2 is (-2)**2.
        assert_eq!(value("X[-2**2]"), 4.0);
        assert_eq!(value("X[1--2]"), 3.0);
        assert_eq!(value("X-[1+2]"), -3.0);
        assert_eq!(value("X+[1+2]"), 3.0);
        assert_eq!(value("X--1"), 1.0);
        let mut p = Params::new();
        p.set_numbered(1, 4.0);
        assert_eq!(value_with("X-#1", &p), Ok(-4.0));
        assert_eq!(value_with("X[-#1**2]", &p), Ok(16.0));
        assert_eq!(value_with("X-SQRT[#1]", &p), Ok(-2.0));
        assert_eq!(
            ok("X-#1").words[0].value,
            Expr::Neg(Box::new(Expr::Param(numbered(1.0))))
        );
    }

    #[test]
    fn functions() {
        let close = |t: &str, v: f64| (value(t) - v).abs() < 1e-9;
        assert!(close("X SIN[30]", 0.5));
        assert!(close("X[COS[60]*2]", 1.0));
        assert!(close("XATAN[1]/[1]", 45.0));
        assert!(close("X[ATAN[-1]/[-1] + 1]", -134.0));
        assert!(close("X ATAN [0] / [-1]", 180.0));
        assert!(close("X TAN[45]", 1.0));
        assert!(close("X ASIN[1]", 90.0));
        assert!(close("X ACOS[0]", 90.0));
        assert!(close("X[LN[EXP[2]]]", 2.0));
        assert_eq!(value("X ABS[-2]"), 2.0);
        assert_eq!(value("X FIX[-2.5]"), -3.0);
        assert_eq!(value("X FUP[2.1]"), 3.0);
        assert_eq!(value("X ROUND[2.5]"), 3.0);
        assert_eq!(value("X ROUND[-2.5]"), -3.0);
        assert_eq!(value("X SQRT[SQRT[16]]"), 2.0);
        let mut p = Params::new();
        assert_eq!(value_with("X EXISTS[#<Foo>]", &p), Ok(0.0));
        p.set_named("foo", 1.0);
        assert_eq!(value_with("X EXISTS[ # < F o o > ]", &p), Ok(1.0));
        assert_eq!(value_with("X[EXISTS[#<foo>] + 1]", &p), Ok(2.0));
    }

    #[test]
    fn expression_domain_errors() {
        let p = Params::new();
        for t in [
            "X[1/0]",
            "XSQRT[-1]",
            "XLN[0]",
            "XACOS[2]",
            "XASIN[-2]",
            "X[-8**0.5]",
            "X[1 MOD 0]",
        ] {
            let e = value_with(t, &p).unwrap_err();
            assert_eq!((e.code, e.at), (DiagCode::ExpressionDomain, 0), "{t}");
        }
    }

    #[test]
    fn parameters() {
        let mut p = Params::new();
        p.set_numbered(1, 2.0);
        p.set_numbered(2, 5.0);
        p.set_numbered(3, 7.0);
        p.set_named("_g", 9.0);
        assert_eq!(value_with("X#1", &p), Ok(2.0));
        assert_eq!(value_with("X##1", &p), Ok(5.0));
        assert_eq!(value_with("X#[#1+1]", &p), Ok(7.0));
        assert_eq!(value_with("X#<_G>", &p), Ok(9.0));
        let e = value_with("X#<nope>", &p).unwrap_err();
        assert_eq!((e.code, e.at), (DiagCode::ParamUnassigned, 0));
        assert!(e.message.contains("nope"));
        for t in ["X#0", "X#5603", "X#[1.5]", "X#-1"] {
            assert_eq!(
                value_with(t, &p).unwrap_err().code,
                DiagCode::IsoParamOutOfRange,
                "{t}"
            );
        }
        let l = ok("X##1");
        let inner = Expr::Param(numbered(1.0));
        assert_eq!(
            l.words[0].value,
            Expr::Param(ParamRef::Number(Box::new(inner)))
        );
    }

    #[test]
    fn assignments() {
        let l = ok("#1 = 5 G1 X#1 #<a>=[#1+1] #[2+3]=-#2 ##4=SIN[0]");
        assert_eq!(l.words.len(), 2);
        assert_eq!(l.assigns.len(), 4);
        assert_eq!(l.assigns[0], (numbered(1.0), num(5.0), 0));
        assert_eq!(l.assigns[1].0, ParamRef::Named("a".into()));
        assert_eq!(l.assigns[1].2, 14);
        assert_eq!(
            l.assigns[2].1,
            Expr::Neg(Box::new(Expr::Param(numbered(2.0))))
        );
        let mut p = Params::new();
        p.set_numbered(1, 7.0);
        p.set_numbered(4, 6.0);
        crate::program::iso::expr::assign(&l.assigns, &mut p).unwrap();
        // Parallel: #<a> saw #1 from before the line.
        assert_eq!(p.get_named("a"), Some(8.0));
        assert_eq!(p.get_numbered(1), 5.0);
        assert_eq!(p.get_numbered(5), 0.0);
        assert_eq!(p.get_numbered(6), 0.0);
        for t in ["#1", "#1 5", "#1=", "#<a> G1", "#=1", "#1+2=3"] {
            assert_eq!(code(t), DiagCode::ExpressionSyntax, "{t}");
        }
    }

    #[test]
    fn comments() {
        let l = ok("G1 (plain) X1 ( MSG , no) (msg,  Hello World ) ; (MSG,not this)");
        assert_eq!(l.words.len(), 2);
        assert_eq!(l.comments, vec![Comment::Msg("Hello World".into())]);
        let l = ok("(DEBUG,x=#<x>)(PRINT,p)(  MsG,a)");
        assert_eq!(
            l.comments,
            vec![
                Comment::Debug("x=#<x>".into()),
                Comment::Print("p".into()),
                Comment::Msg("a".into())
            ]
        );
        // Text keeps its case and characters.
        assert_eq!(
            ok("(MSG,Drill Ø5 é;)").comments,
            vec![Comment::Msg("Drill Ø5 é;".into())]
        );
        assert_eq!(ok("; G1 X(").words.len(), 0);
        assert_eq!(ok("G1;X1").words.len(), 1);
        assert_eq!(code("G1 (a (b) c)"), DiagCode::UnexpectedCharacter);
        assert_eq!(err("G1 (open").at, 3);
        assert_eq!(code("X[1 (c) + 2]"), DiagCode::ExpressionSyntax);
        assert_eq!(code("X(c)1"), DiagCode::WordWithoutValue);
        assert_eq!(code("G1 X1)"), DiagCode::UnexpectedCharacter);
    }

    #[test]
    fn block_delete_percent_and_n() {
        let l = ok("/N10 G1");
        assert!(l.block_delete);
        assert_eq!(l.n, Some(10));
        assert!(!ok("N10").block_delete);
        assert!(ok(" / G1").block_delete);
        assert_eq!(ok("n 1 2 .5 g0").n, Some(12));
        assert!(ok("%").percent);
        let l = ok(" % (MSG,start)");
        assert!(l.percent);
        assert_eq!(l.comments, vec![Comment::Msg("start".into())]);
        assert!(!ok("G1").percent);
        assert_eq!(code("% G1"), DiagCode::UnexpectedCharacter);
        assert_eq!(code("%%"), DiagCode::UnexpectedCharacter);
        assert_eq!(code("G1 N10"), DiagCode::BlockNumberNotFirst);
        assert_eq!(code("N"), DiagCode::WordWithoutValue);
        assert_eq!(code("N-1"), DiagCode::NumberMalformed);
        assert_eq!(code("N10."), DiagCode::NumberMalformed);
        assert_eq!(code("N99999999999"), DiagCode::NumberMalformed);
        assert_eq!(code("(c)/G1"), DiagCode::UnexpectedCharacter);
    }

    fn oword(text: &str) -> OWord {
        ok(text)
            .oword
            .unwrap_or_else(|| panic!("{text:?}: no O-word"))
    }

    #[test]
    fn owords_of_every_keyword() {
        let l = |n: u32| Label::Number(n);
        let cases: Vec<(&str, Label, OKeyword)> = vec![
            ("O100 sub", l(100), OKeyword::Sub),
            ("o<My Sub> SUB", Label::Name("mysub".into()), OKeyword::Sub),
            ("O100 endsub", l(100), OKeyword::EndSub(None)),
            ("O100 endsub [2]", l(100), OKeyword::EndSub(Some(num(2.0)))),
            ("O100 call", l(100), OKeyword::Call(vec![])),
            (
                "O100 call [1] (c) [2]",
                l(100),
                OKeyword::Call(vec![num(1.0), num(2.0)]),
            ),
            ("O1 return", l(1), OKeyword::Return(None)),
            ("O1 return [3]", l(1), OKeyword::Return(Some(num(3.0)))),
            ("O2 do", l(2), OKeyword::Do),
            ("O2 while [1]", l(2), OKeyword::While(num(1.0))),
            ("O2 endwhile", l(2), OKeyword::EndWhile),
            ("O3 if [0]", l(3), OKeyword::If(num(0.0))),
            ("O3 elseif [1]", l(3), OKeyword::ElseIf(num(1.0))),
            ("O3 else", l(3), OKeyword::Else),
            ("O3 endif", l(3), OKeyword::EndIf),
            ("O4 repeat [5]", l(4), OKeyword::Repeat(num(5.0))),
            ("O4 endrepeat", l(4), OKeyword::EndRepeat),
            ("O4 break", l(4), OKeyword::Break),
            ("O4 continue", l(4), OKeyword::Continue),
            ("O100.0 sub", l(100), OKeyword::Sub),
        ];
        for (text, label, keyword) in cases {
            let o = oword(text);
            assert_eq!((o.label, o.keyword, o.at), (label, keyword, 0), "{text}");
        }
        let l = ok("/N5 O<x> if [#1 GT 2] (MSG,hi) ; rest");
        assert!(l.block_delete);
        assert_eq!(l.n, Some(5));
        assert_eq!(l.oword.unwrap().at, 4);
        assert_eq!(l.comments, vec![Comment::Msg("hi".into())]);
        assert!(l.words.is_empty());
        let args = match oword("o<s> call [1+1] [#2] [SIN[0]]").keyword {
            OKeyword::Call(a) => a,
            k => panic!("{k:?}"),
        };
        assert_eq!(args.len(), 3);
    }

    #[test]
    fn oword_errors() {
        assert_eq!(code("O100 sub G1"), DiagCode::UnexpectedCharacter);
        assert_eq!(code("O100 if [1] X1"), DiagCode::UnexpectedCharacter);
        assert_eq!(code("O100 endif [1]"), DiagCode::UnexpectedCharacter);
        assert_eq!(code("O100 loop"), DiagCode::ExpressionSyntax);
        assert!(err("O100 loop").message.contains("LOOP"));
        assert_eq!(code("O100 while"), DiagCode::ExpressionSyntax);
        assert_eq!(code("O100 if 1"), DiagCode::ExpressionSyntax);
        assert_eq!(code("O100 repeat"), DiagCode::ExpressionSyntax);
        assert_eq!(code("O100"), DiagCode::IsoUnsupported);
        assert_eq!(code("O#1 call"), DiagCode::IsoUnsupported);
        assert_eq!(code("O sub"), DiagCode::WordWithoutValue);
        assert_eq!(code("O1.5 sub"), DiagCode::WordNotWhole);
        assert_eq!(code("O<> sub"), DiagCode::ExpressionSyntax);
        assert_eq!(code("O<a sub"), DiagCode::ExpressionSyntax);
        assert_eq!(code("G1 O100 sub"), DiagCode::UnexpectedCharacter);
        let many = format!("O1 call {}", "[1]".repeat(31));
        assert_eq!(code(&many), DiagCode::IsoParamOutOfRange);
        let thirty = format!("O1 call {}", "[1]".repeat(30));
        assert!(ok(&thirty).oword.is_some());
    }

    #[test]
    fn syntax_errors_with_codes_and_offsets() {
        let cases: [(&str, DiagCode, usize); 19] = [
            ("G1 X", DiagCode::WordWithoutValue, 3),
            ("G1 X Y1", DiagCode::WordWithoutValue, 3),
            ("X]", DiagCode::WordWithoutValue, 0),
            ("X1.2.3", DiagCode::NumberMalformed, 4),
            ("X.", DiagCode::NumberMalformed, 1),
            ("X-", DiagCode::NumberMalformed, 1),
            ("G1 X[1+2", DiagCode::ExpressionSyntax, 8),
            ("X[1 [2]]", DiagCode::ExpressionSyntax, 4),
            ("X[1 + ]", DiagCode::ExpressionSyntax, 6),
            ("X[1 FOO 2]", DiagCode::ExpressionSyntax, 4),
            ("X[FOO[1]]", DiagCode::ExpressionSyntax, 2),
            ("X SIN 30", DiagCode::ExpressionSyntax, 6),
            ("X ATAN[1]", DiagCode::ExpressionSyntax, 9),
            ("X EXISTS[#1]", DiagCode::IsoUnsupported, 10),
            ("X EXISTS[1]", DiagCode::ExpressionSyntax, 9),
            ("G = 2", DiagCode::WordWithoutValue, 0),
            ("G1 X1 @2", DiagCode::IsoUnsupported, 6),
            ("G1 X1 é", DiagCode::UnexpectedCharacter, 6),
            ("G1 X1 \u{7}", DiagCode::UnexpectedCharacter, 6),
        ];
        for (text, c, at) in cases {
            let e = err(text);
            assert_eq!((e.code, e.at), (c, at), "{text:?}: {}", e.message);
        }
        let big = format!("X{}", "9".repeat(400));
        assert_eq!(code(&big), DiagCode::NumberMalformed);
    }

    #[test]
    fn nesting_and_height_are_bounded() {
        let deep = |n: usize| format!("X{}1{}", "[".repeat(n), "]".repeat(n));
        assert_eq!(value(&deep(60)), 1.0);
        assert_eq!(code(&deep(65)), DiagCode::ExpressionSyntax);
        assert_eq!(code(&deep(100_000)), DiagCode::ExpressionSyntax);
        assert_eq!(
            code(&format!("X{}1", "#".repeat(100_000))),
            DiagCode::ExpressionSyntax
        );
        assert_eq!(
            code(&format!("X{}1", "-".repeat(100_000))),
            DiagCode::ExpressionSyntax
        );
        assert_eq!(
            code(&format!("X{}1", "+".repeat(100_000))),
            DiagCode::ExpressionSyntax
        );
        let sins = format!("X{}0{}", "SIN[".repeat(1000), "]".repeat(1000));
        assert_eq!(code(&sins), DiagCode::ExpressionSyntax);
        assert_eq!(value(&format!("X[1{}]", "+1".repeat(200))), 201.0);
        let chain = format!("X[1{}]", "+1".repeat(100_000));
        assert_eq!(code(&chain), DiagCode::ExpressionSyntax);
    }

    /// A small deterministic generator (no dependency, no clock).
    fn next(state: &mut u64) -> u64 {
        *state ^= *state << 13;
        *state ^= *state >> 7;
        *state ^= *state << 17;
        *state
    }

    #[test]
    fn random_input_never_panics() {
        const ALPHABET: &[u8] =
            b"gxyzfnoO#<>[]()=+-*/.;%0123456789 \tabcdefghijklmnopqrstuvwxyz_@^$,\x00\xff";
        let p = Params::new();
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        for round in 0..20_000 {
            let len = (next(&mut state) % 40) as usize;
            let bytes: Vec<u8> = (0..len)
                .map(|_| {
                    let r = next(&mut state);
                    if round % 4 == 0 {
                        r as u8
                    } else {
                        ALPHABET[(r % ALPHABET.len() as u64) as usize]
                    }
                })
                .collect();
            let text = String::from_utf8_lossy(&bytes);
            if let Ok(l) = line(&text) {
                // Evaluating whatever parsed never panics either.
                for w in &l.words {
                    let _ = eval(&w.value, &p, w.at);
                }
                for (r, e, at) in &l.assigns {
                    let _ = crate::program::iso::expr::target(r, &p, *at);
                    let _ = eval(e, &p, *at);
                }
            }
        }
        for t in [
            "",
            "(",
            ")",
            "[",
            "]",
            "#",
            "#<",
            "#<>",
            "o",
            "o<",
            "%(",
            "/",
            "/n",
            "n1.",
            "x#[",
            "xatan[1]/",
            "o1call[",
            "\u{0}",
            "é(é)é",
        ] {
            let _ = line(t);
        }
    }
}
