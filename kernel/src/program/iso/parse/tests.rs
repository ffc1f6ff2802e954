//! Tests of the parser.

use super::line;
use crate::diag::DiagCode;
use crate::program::iso::Fail;
use crate::program::iso::ast::{Comment, Expr, Label, Line, OKeyword, OWord, ParamRef};
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
    // Blanks do not count: `sub G1` reads `subg1`, no keyword.
    assert_eq!(code("O100 sub G1"), DiagCode::ExpressionSyntax);
    assert_eq!(code("O100 sub (c) G1"), DiagCode::UnexpectedCharacter);
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
