//! One line of an ISO program as parsed, before anything is evaluated: words whose values are
//! expressions, parameter assignments, an O-word and comments. Evaluation happens when the
//! line runs (a skipped `if` branch or subroutine body is never evaluated).

/// A parameter reference: `#12`, `#[#1+2]`, `#<name>` (local) or `#<_name>` (global).
#[derive(Clone, Debug, PartialEq)]
pub enum ParamRef {
    /// A numbered parameter, the number an expression (`#12` is `Number(Expr::Num(12))`).
    Number(Box<Expr>),
    /// A named parameter, lower-cased, spaces removed; a leading `_` makes it global.
    Named(String),
}

/// Binary operators in RS274-NGC precedence classes (LinuxCNC: `**`; `* / MOD`; `+ -`;
/// comparisons `EQ NE GT GE LT LE`; logical `AND OR XOR`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BinOp {
    Pow,
    Mul,
    Div,
    Mod,
    Add,
    Sub,
    Eq,
    Ne,
    Gt,
    Ge,
    Lt,
    Le,
    And,
    Or,
    Xor,
}

/// Unary functions (`ATAN[a]/[b]` is [`Expr::Atan2`], `EXISTS[#<x>]` is [`Expr::Exists`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Func {
    Abs,
    Acos,
    Asin,
    Cos,
    Exp,
    Fix,
    Fup,
    Ln,
    Round,
    Sin,
    Sqrt,
    Tan,
}

/// An expression.
#[derive(Clone, Debug, PartialEq)]
pub enum Expr {
    Num(f64),
    Param(ParamRef),
    Neg(Box<Expr>),
    Bin(BinOp, Box<Expr>, Box<Expr>),
    Func(Func, Box<Expr>),
    /// `ATAN[y]/[x]`, degrees.
    Atan2(Box<Expr>, Box<Expr>),
    /// `EXISTS[#<name>]`: 1 when the named parameter is set.
    Exists(String),
}

/// A word: letter (upper case) and value, `at` the byte offset of the letter in the line.
#[derive(Clone, Debug, PartialEq)]
pub struct Word {
    pub letter: u8,
    pub value: Expr,
    pub at: usize,
}

/// A label of an O-word: `o100` or `o<name>` (lower-cased).
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum Label {
    Number(u32),
    Name(String),
}

/// The keyword after an O-word label.
#[derive(Clone, Debug, PartialEq)]
pub enum OKeyword {
    Sub,
    EndSub(Option<Expr>),
    /// Arguments `[a] [b] …` become #1, #2, … of the subroutine.
    Call(Vec<Expr>),
    Return(Option<Expr>),
    Do,
    While(Expr),
    EndWhile,
    If(Expr),
    ElseIf(Expr),
    Else,
    EndIf,
    Repeat(Expr),
    EndRepeat,
    Break,
    Continue,
}

/// An O-word: label, keyword, byte offset of the `O`.
#[derive(Clone, Debug, PartialEq)]
pub struct OWord {
    pub label: Label,
    pub keyword: OKeyword,
    pub at: usize,
}

/// A comment that means something: `(MSG, text)`, `(DEBUG, text)` (parameters `#n`/`#<x>`
/// in it are substituted when it runs), `(PRINT, text)`. Plain comments are dropped.
#[derive(Clone, Debug, PartialEq)]
pub enum Comment {
    Msg(String),
    Debug(String),
    Print(String),
}

/// A parsed line. `words` keep their order; assignments take effect after the line's words
/// were read (LinuxCNC: every read in a line sees the values from before the line).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Line {
    /// A `/` at the start: skipped while block delete is on.
    pub block_delete: bool,
    /// The `N` number, if any.
    pub n: Option<u32>,
    pub oword: Option<OWord>,
    pub words: Vec<Word>,
    pub assigns: Vec<(ParamRef, Expr, usize)>,
    pub comments: Vec<Comment>,
    /// `%` alone on the line (program start/end marker).
    pub percent: bool,
}
