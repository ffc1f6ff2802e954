//! Evaluation of expressions and parameter references against [`Params`], as LinuxCNC 2.9
//! computes them (interp_execute.cc, interp_read.cc).

use super::Fail;
use super::ast::{BinOp, Expr, Func, ParamRef};
use super::params::{MAX_NUMBERED, Params, Target, read_only};
use crate::diag::DiagCode;

/// Two values closer than this are equal for EQ, NE, LE and GE (LinuxCNC TOLERANCE_EQUAL).
const TOLERANCE_EQUAL: f64 = 1e-6;

/// How far from a whole number a parameter number may be (LinuxCNC read_integer_value).
const WHOLE_TOLERANCE: f64 = 1e-4;

/// The value of `e`; `at` locates errors (the word's byte offset).
///
/// The tree comes from [`super::parse::line`], which bounds its height, so the recursion is
/// shallow.
pub fn eval(e: &Expr, p: &Params, at: usize) -> Result<f64, Fail> {
    let v = match e {
        Expr::Num(v) => *v,
        Expr::Param(r) => p.read(&target(r, p, at)?, at)?,
        Expr::Neg(x) => -eval(x, p, at)?,
        Expr::Bin(op, l, r) => binary(*op, eval(l, p, at)?, eval(r, p, at)?, at)?,
        Expr::Func(f, x) => unary(*f, eval(x, p, at)?, at)?,
        Expr::Atan2(y, x) => eval(y, p, at)?.atan2(eval(x, p, at)?).to_degrees(),
        Expr::Exists(name) => bool_value(p.get_named(&name.to_ascii_lowercase()).is_some()),
    };
    // LinuxCNC refuses any value that is not a number or infinite, wherever it arises.
    if v.is_finite() {
        Ok(v)
    } else {
        Err(domain(at, "the result is not a finite number"))
    }
}

/// Resolves a reference (evaluating a computed number) to its target: numbers must be whole
/// (within 0.0001, as LinuxCNC) and in 1..=5602; names are lower-cased.
pub fn target(r: &ParamRef, p: &Params, at: usize) -> Result<Target, Fail> {
    match r {
        ParamRef::Named(name) => Ok(Target::Named(name.to_ascii_lowercase())),
        ParamRef::Number(e) => {
            let v = eval(e, p, at)?;
            let n = whole(v).ok_or_else(|| {
                Fail::new(
                    at,
                    DiagCode::IsoParamOutOfRange,
                    format!("parameter number {v} is not a whole number"),
                )
            })?;
            if !(1.0..=MAX_NUMBERED as f64).contains(&n) {
                return Err(Fail::new(
                    at,
                    DiagCode::IsoParamOutOfRange,
                    format!("parameter #{n} is outside #1..#{MAX_NUMBERED}"),
                ));
            }
            Ok(Target::Numbered(n as usize))
        }
    }
}

/// Performs a line's assignments in parallel, as LinuxCNC: every target and value is
/// computed from the values before the line, then all are written in order (the last of two
/// writes to one parameter wins). Refuses writing a read-only numbered parameter.
pub fn assign(assigns: &[(ParamRef, Expr, usize)], p: &mut Params) -> Result<(), Fail> {
    let mut done = Vec::with_capacity(assigns.len());
    for (r, e, at) in assigns {
        let t = target(r, p, *at)?;
        match t {
            Target::Numbered(n) if read_only(n) => {
                return Err(Fail::new(
                    *at,
                    DiagCode::IsoParamOutOfRange,
                    format!("parameter #{n} is read-only"),
                ));
            }
            _ => done.push((t, eval(e, p, *at)?)),
        }
    }
    for (t, v) in &done {
        p.write(t, *v);
    }
    Ok(())
}

/// `v` rounded to the whole number it is within 0.0001 of, if any.
fn whole(v: f64) -> Option<f64> {
    let floor = v.floor();
    match v - floor {
        d if d > 1.0 - WHOLE_TOLERANCE => Some(floor + 1.0),
        d if d <= WHOLE_TOLERANCE => Some(floor),
        _ => None,
    }
}

fn binary(op: BinOp, a: f64, b: f64, at: usize) -> Result<f64, Fail> {
    Ok(match op {
        BinOp::Pow => {
            if a < 0.0 && b.fract() != 0.0 {
                return Err(domain(at, "a negative number raised to a fractional power"));
            }
            a.powf(b)
        }
        BinOp::Mul => a * b,
        BinOp::Div if b == 0.0 => return Err(domain(at, "division by zero")),
        BinOp::Div => a / b,
        BinOp::Mod if b == 0.0 => return Err(domain(at, "MOD by zero")),
        BinOp::Mod => modulo(a, b),
        BinOp::Add => a + b,
        BinOp::Sub => a - b,
        BinOp::Eq => bool_value((a - b).abs() < TOLERANCE_EQUAL),
        BinOp::Ne => bool_value((a - b).abs() >= TOLERANCE_EQUAL),
        BinOp::Gt => bool_value(a > b),
        BinOp::Ge => bool_value((a - b).abs() < TOLERANCE_EQUAL || a >= b),
        BinOp::Lt => bool_value(a < b),
        BinOp::Le => bool_value((a - b).abs() < TOLERANCE_EQUAL || a <= b),
        BinOp::And => bool_value(a != 0.0 && b != 0.0),
        BinOp::Or => bool_value(a != 0.0 || b != 0.0),
        BinOp::Xor => bool_value((a != 0.0) != (b != 0.0)),
    })
}

/// LinuxCNC's MOD: C's fmod (sign of `a`), then a negative result moved up by |b|, so that
/// the result lies in [0, |b|).
fn modulo(a: f64, b: f64) -> f64 {
    let r = a % b;
    if r < 0.0 { r + b.abs() } else { r }
}

fn unary(f: Func, x: f64, at: usize) -> Result<f64, Fail> {
    Ok(match f {
        Func::Abs => x.abs(),
        Func::Acos | Func::Asin if !(-1.0..=1.0).contains(&x) => {
            let name = format!("{f:?}").to_uppercase();
            return Err(domain(at, format!("{name} of {x}, outside -1..1")));
        }
        Func::Acos => x.acos().to_degrees(),
        Func::Asin => x.asin().to_degrees(),
        Func::Cos => x.to_radians().cos(),
        Func::Exp => x.exp(),
        Func::Fix => x.floor(),
        Func::Fup => x.ceil(),
        Func::Ln if x <= 0.0 => return Err(domain(at, format!("LN of {x}"))),
        Func::Ln => x.ln(),
        // Half away from zero, as LinuxCNC's (int)(x ± 0.5).
        Func::Round => x.round(),
        Func::Sin => x.to_radians().sin(),
        Func::Sqrt if x < 0.0 => return Err(domain(at, format!("SQRT of {x}"))),
        Func::Sqrt => x.sqrt(),
        Func::Tan => x.to_radians().tan(),
    })
}

fn bool_value(b: bool) -> f64 {
    if b { 1.0 } else { 0.0 }
}

fn domain(at: usize, msg: impl ToString) -> Fail {
    Fail::new(at, DiagCode::ExpressionDomain, msg)
}

/// The text of a `(DEBUG,…)` or `(PRINT,…)` comment with its parameters substituted, as
/// LinuxCNC's convert_param_comment: `#123` and `#<name>` become their values (`######`
/// when unset or out of range), printed `%lf`-like with 6 decimals until a `%d` (no
/// decimals), `%f` (4) or `%.Nf` (N) changes the format for the rest of the text.
pub fn substitute(text: &str, p: &Params) -> String {
    let mut out = String::with_capacity(text.len());
    let mut decimals = 6usize;
    let mut rest = text;
    while let Some(c) = rest.chars().next() {
        rest = &rest[c.len_utf8()..];
        match c {
            '%' => rest = format_spec(rest, &mut decimals, &mut out),
            '#' => rest = param_text(rest, p, decimals, &mut out),
            _ => out.push(c),
        }
    }
    out
}

/// After a `%`: a format (changes `decimals`) or the `%` kept as text.
fn format_spec<'a>(rest: &'a str, decimals: &mut usize, out: &mut String) -> &'a str {
    let b = rest.as_bytes();
    match b {
        [b'd', ..] => *decimals = 0,
        [b'f', ..] => *decimals = 4,
        [b'.', d @ b'0'..=b'9', b'f', ..] => {
            *decimals = usize::from(d - b'0');
            return &rest[3..];
        }
        // LinuxCNC keeps the `.` of an unfinished `%.` and drops the `%`.
        [b'.', ..] => out.push('.'),
        _ => {
            out.push('%');
            return rest;
        }
    }
    &rest[1..]
}

/// After a `#`: a number or `<name>` replaced by its value, or the `#` kept as text.
fn param_text<'a>(rest: &'a str, p: &Params, decimals: usize, out: &mut String) -> &'a str {
    let (value, rest) = if rest.starts_with(|c: char| c.is_ascii_digit()) {
        let end = rest
            .find(|c: char| !c.is_ascii_digit())
            .unwrap_or(rest.len());
        let n = rest[..end].parse::<usize>().ok();
        let v = n.filter(|n| *n <= MAX_NUMBERED);
        (v.map(|n| p.get_numbered(n)), &rest[end..])
    } else if let Some(inner) = rest.strip_prefix('<') {
        let Some(end) = inner.find('>') else {
            out.push_str("######");
            return "";
        };
        let name: String = inner[..end]
            .chars()
            .filter(|c| !c.is_whitespace())
            .map(|c| c.to_ascii_lowercase())
            .collect();
        (p.get_named(&name), &inner[end + 1..])
    } else {
        out.push('#');
        return rest;
    };
    match value {
        // LinuxCNC prints -0.0 and tiny values as 0.
        Some(v) if v.abs() < TOLERANCE_EQUAL => out.push_str(&format!("{:.*}", decimals, 0.0)),
        Some(v) => out.push_str(&format!("{v:.decimals$}")),
        None => out.push_str("######"),
    }
    rest
}

#[cfg(test)]
mod tests {
    use super::*;

    fn num(v: f64) -> Expr {
        Expr::Num(v)
    }

    fn bin(op: BinOp, a: f64, b: f64) -> Expr {
        Expr::Bin(op, Box::new(num(a)), Box::new(num(b)))
    }

    fn ev(e: &Expr) -> Result<f64, Fail> {
        eval(e, &Params::new(), 3)
    }

    fn code(e: &Expr) -> DiagCode {
        ev(e).unwrap_err().code
    }

    #[test]
    fn arithmetic_and_domain() {
        assert_eq!(ev(&bin(BinOp::Pow, 2.0, 10.0)), Ok(1024.0));
        assert_eq!(ev(&bin(BinOp::Pow, -2.0, 3.0)), Ok(-8.0));
        assert_eq!(
            code(&bin(BinOp::Pow, -2.0, 0.5)),
            DiagCode::ExpressionDomain
        );
        assert_eq!(ev(&bin(BinOp::Div, 1.0, 4.0)), Ok(0.25));
        assert_eq!(code(&bin(BinOp::Div, 1.0, 0.0)), DiagCode::ExpressionDomain);
        assert_eq!(code(&bin(BinOp::Mod, 1.0, 0.0)), DiagCode::ExpressionDomain);
        assert_eq!(
            code(&bin(BinOp::Mul, 1e300, 1e300)),
            DiagCode::ExpressionDomain
        );
        let e = ev(&bin(BinOp::Div, 1.0, 0.0)).unwrap_err();
        assert_eq!(e.at, 3);
    }

    #[test]
    fn modulo_as_linuxcnc() {
        assert_eq!(ev(&bin(BinOp::Mod, 7.0, 3.0)), Ok(1.0));
        assert_eq!(ev(&bin(BinOp::Mod, -7.0, 3.0)), Ok(2.0));
        // fmod(7, -3) = 1 stays; fmod(-7, -3) = -1 becomes 2.
        assert_eq!(ev(&bin(BinOp::Mod, 7.0, -3.0)), Ok(1.0));
        assert_eq!(ev(&bin(BinOp::Mod, -7.0, -3.0)), Ok(2.0));
        assert_eq!(ev(&bin(BinOp::Mod, 7.5, 2.0)), Ok(1.5));
        assert_eq!(ev(&bin(BinOp::Mod, -0.5, 360.0)), Ok(359.5));
    }

    #[test]
    fn comparisons_and_logic() {
        assert_eq!(ev(&bin(BinOp::Eq, 1.0, 1.0 + 1e-7)), Ok(1.0));
        assert_eq!(ev(&bin(BinOp::Ne, 1.0, 1.0 + 1e-7)), Ok(0.0));
        assert_eq!(ev(&bin(BinOp::Ne, 1.0, 2.0)), Ok(1.0));
        assert_eq!(ev(&bin(BinOp::Gt, 2.0, 1.0)), Ok(1.0));
        assert_eq!(ev(&bin(BinOp::Ge, 1.0, 1.0 + 1e-7)), Ok(1.0));
        assert_eq!(ev(&bin(BinOp::Lt, 1.0, 1.0)), Ok(0.0));
        assert_eq!(ev(&bin(BinOp::Le, 1.0 + 1e-7, 1.0)), Ok(1.0));
        assert_eq!(ev(&bin(BinOp::And, 2.0, -1.0)), Ok(1.0));
        assert_eq!(ev(&bin(BinOp::And, 2.0, 0.0)), Ok(0.0));
        assert_eq!(ev(&bin(BinOp::Or, 0.0, 0.0)), Ok(0.0));
        assert_eq!(ev(&bin(BinOp::Or, 0.0, 3.0)), Ok(1.0));
        assert_eq!(ev(&bin(BinOp::Xor, 1.0, 3.0)), Ok(0.0));
        assert_eq!(ev(&bin(BinOp::Xor, 0.0, 3.0)), Ok(1.0));
    }

    #[test]
    fn functions() {
        let f = |f: Func, x: f64| ev(&Expr::Func(f, Box::new(num(x))));
        let close = |r: Result<f64, Fail>, v: f64| (r.unwrap() - v).abs() < 1e-12;
        assert!(close(f(Func::Sin, 30.0), 0.5));
        assert!(close(f(Func::Cos, 60.0), 0.5));
        assert!(close(f(Func::Tan, 45.0), 1.0));
        assert!(close(f(Func::Asin, 0.5), 30.0));
        assert!(close(f(Func::Acos, 0.5), 60.0));
        assert!(close(f(Func::Exp, 1.0), std::f64::consts::E));
        assert!(close(f(Func::Ln, std::f64::consts::E), 1.0));
        assert_eq!(f(Func::Abs, -2.0), Ok(2.0));
        assert_eq!(f(Func::Fix, -2.5), Ok(-3.0));
        assert_eq!(f(Func::Fup, -2.5), Ok(-2.0));
        assert_eq!(f(Func::Fup, 2.1), Ok(3.0));
        assert_eq!(f(Func::Round, 2.5), Ok(3.0));
        assert_eq!(f(Func::Round, -2.5), Ok(-3.0));
        assert_eq!(f(Func::Round, 2.4), Ok(2.0));
        assert_eq!(f(Func::Sqrt, 0.0), Ok(0.0));
        assert_eq!(f(Func::Sqrt, 9.0), Ok(3.0));
        for (func, x) in [
            (Func::Sqrt, -1.0),
            (Func::Ln, 0.0),
            (Func::Ln, -1.0),
            (Func::Acos, 1.5),
            (Func::Asin, -1.01),
            (Func::Exp, 1000.0),
        ] {
            assert_eq!(f(func, x).unwrap_err().code, DiagCode::ExpressionDomain);
        }
    }

    #[test]
    fn atan2_in_degrees() {
        let a = |y: f64, x: f64| ev(&Expr::Atan2(Box::new(num(y)), Box::new(num(x)))).unwrap();
        assert!((a(1.0, 1.0) - 45.0).abs() < 1e-12);
        assert!((a(1.0, -1.0) - 135.0).abs() < 1e-12);
        assert!((a(-1.0, -1.0) + 135.0).abs() < 1e-12);
        assert_eq!(a(0.0, 0.0), 0.0);
    }

    #[test]
    fn params_and_targets() {
        let mut p = Params::new();
        p.set_numbered(1, 4.0);
        p.set_numbered(4, 9.0);
        p.set_named("abc", 2.0);
        let r1 = Expr::Param(ParamRef::Number(Box::new(num(1.0))));
        let indirect = Expr::Param(ParamRef::Number(Box::new(r1.clone())));
        assert_eq!(eval(&r1, &p, 0), Ok(4.0));
        assert_eq!(eval(&indirect, &p, 0), Ok(9.0));
        let named = Expr::Param(ParamRef::Named("ABC".into()));
        assert_eq!(eval(&named, &p, 0), Ok(2.0));
        let unset = Expr::Param(ParamRef::Named("nope".into()));
        let e = eval(&unset, &p, 7).unwrap_err();
        assert_eq!((e.code, e.at), (DiagCode::ParamUnassigned, 7));
        assert!(e.message.contains("nope"));
        assert_eq!(eval(&Expr::Exists("abc".into()), &p, 0), Ok(1.0));
        assert_eq!(eval(&Expr::Exists("nope".into()), &p, 0), Ok(0.0));
        let t = |v: f64| target(&ParamRef::Number(Box::new(num(v))), &p, 0);
        assert_eq!(t(5602.0), Ok(Target::Numbered(5602)));
        assert_eq!(t(2.99999), Ok(Target::Numbered(3)));
        assert_eq!(t(3.00001), Ok(Target::Numbered(3)));
        for bad in [0.0, -1.0, 5603.0, 2.5, 1e300] {
            assert_eq!(t(bad).unwrap_err().code, DiagCode::IsoParamOutOfRange);
        }
    }

    #[test]
    fn assignments_are_parallel_and_check_read_only() {
        let mut p = Params::new();
        p.set_numbered(1, 5.0);
        let n = |v: f64| ParamRef::Number(Box::new(num(v)));
        let read1 = Expr::Param(n(1.0));
        let assigns = vec![(n(1.0), num(10.0), 0), (n(2.0), read1.clone(), 5)];
        assign(&assigns, &mut p).unwrap();
        assert_eq!((p.get_numbered(1), p.get_numbered(2)), (10.0, 5.0));
        let bad = vec![(n(3.0), num(1.0), 0), (n(5420.0), num(1.0), 6)];
        let e = assign(&bad, &mut p).unwrap_err();
        assert_eq!((e.code, e.at), (DiagCode::IsoParamOutOfRange, 6));
        // Nothing of a failing line is written.
        assert_eq!(p.get_numbered(3), 0.0);
    }

    #[test]
    fn substitute_debug_text() {
        let mut p = Params::new();
        p.set_numbered(3, 1.5);
        p.set_named("x", -2.0);
        assert_eq!(substitute("a=#3 b=#< X >", &p), "a=1.500000 b=-2.000000");
        assert_eq!(substitute("%d#3 %f#3 %.2f#3", &p), "2 1.5000 1.50");
        assert_eq!(
            substitute("#<nope> #9999 # %x 100% %.x", &p),
            "###### ###### # %x 100% .x"
        );
        assert_eq!(substitute("#<x", &p), "######");
        assert_eq!(substitute("é#3ü", &p), "é1.500000ü");
    }
}
