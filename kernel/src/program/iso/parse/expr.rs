//! Values and expressions: numbers, parameters, `[…]`, functions, signs, and binary
//! operators by precedence climbing (LinuxCNC's classes).

use super::Cursor;
use crate::diag::DiagCode;
use crate::program::iso::Fail;
use crate::program::iso::ast::{BinOp, Expr, Func, ParamRef};

/// Deepest nesting of brackets, functions, signs and `#` in one value: bounds the
/// parser's recursion.
const MAX_NESTING: usize = 64;

/// Tallest expression tree: bounds the recursion of evaluating and dropping it (a chain
/// `[1+1+…]` is as tall as it has operators).
const MAX_HEIGHT: u32 = 256;

/// A parsed value and the height of its tree.
pub(super) struct Node {
    pub(super) e: Expr,
    h: u32,
}

/// What a function name stands for.
#[derive(Clone, Copy)]
pub(super) enum FuncKind {
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
    pub(super) fn value(&mut self) -> Result<Node, Fail> {
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
    pub(super) fn param_ref(&mut self) -> Result<(ParamRef, u32), Fail> {
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
    pub(super) fn name(&mut self) -> Result<String, Fail> {
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

    pub(super) fn function_name(&self) -> Option<(&'static str, FuncKind)> {
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
