//! O-word control flow (LinuxCNC 2.9): subroutines, `while`/`do`, `if`, `repeat`, `break`,
//! `continue`. Loops and calls go back in the source through [`Lines::mark`]/[`Lines::seek`],
//! so a program of any size is read line by line, never held whole.

use super::ast::{Label, OKeyword, OWord};
use super::{Fail, Interpreter, expr, parse};
use crate::diag::DiagCode;
use crate::program::{LineMark, Lines};
use std::collections::HashMap;

/// A place in the program: where a line starts and its number minus one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Place {
    pub mark: LineMark,
    pub line_no: u32,
}

/// Most iterations of one loop, and most nested calls: a program that loops for ever is an
/// error, not a hang of the validation.
pub const MAX_ITERATIONS: u64 = 1_000_000;
pub const MAX_CALL_DEPTH: usize = 64;

/// An open control structure.
#[derive(Clone, Debug)]
pub enum Frame {
    Call {
        label: Label,
        back: Place,
    },
    While {
        label: Label,
        at: Place,
        count: u64,
    },
    Do {
        label: Label,
        body: Place,
        count: u64,
    },
    Repeat {
        label: Label,
        body: Place,
        left: u64,
    },
    If {
        label: Label,
    },
}

impl Frame {
    fn label(&self) -> &Label {
        match self {
            Frame::Call { label, .. }
            | Frame::While { label, .. }
            | Frame::Do { label, .. }
            | Frame::Repeat { label, .. }
            | Frame::If { label } => label,
        }
    }
}

/// Control-flow state of a run.
#[derive(Default)]
pub struct Flow {
    pub frames: Vec<Frame>,
    /// Subroutine bodies seen so far: where the line after `sub` starts.
    pub subs: HashMap<Label, Place>,
}

fn mismatch<T>(o: &OWord, what: &str) -> Result<T, Fail> {
    Err(Fail::new(
        o.at,
        DiagCode::OWordMismatch,
        format!("{} {what}", show(&o.label)),
    ))
}

/// `o100` / `o<name>` as written.
pub fn show(l: &Label) -> String {
    match l {
        Label::Number(n) => format!("o{n}"),
        Label::Name(s) => format!("o<{s}>"),
    }
}

fn too_many<T>(o: &OWord) -> Result<T, Fail> {
    Err(Fail::new(
        o.at,
        DiagCode::LoopLimit,
        format!("{} ran more than {MAX_ITERATIONS} times", show(&o.label)),
    ))
}

impl Interpreter {
    /// Runs an O-word line; `here` is where the line started, `next` where the next starts.
    pub(super) fn oword<L: Lines>(
        &mut self,
        o: &OWord,
        lines: &mut L,
        line_no: &mut u32,
        here: Place,
    ) -> Result<(), Fail> {
        let next = self.place(lines, *line_no, o)?;
        match &o.keyword {
            OKeyword::Sub => {
                self.flow.subs.insert(o.label.clone(), next);
                self.skip_to(o, lines, line_no, &[Kind::EndSub]).map(|_| ())
            }
            OKeyword::EndSub(v) | OKeyword::Return(v) => {
                self.leave_sub(o, v.as_ref(), lines, line_no)
            }
            OKeyword::Call(args) => self.call(o, args, lines, line_no, next),
            OKeyword::Do => {
                self.flow.frames.push(Frame::Do {
                    label: o.label.clone(),
                    body: next,
                    count: 0,
                });
                Ok(())
            }
            OKeyword::While(cond) => self.while_line(o, cond, lines, line_no, here),
            OKeyword::EndWhile => match self.flow.frames.last() {
                Some(Frame::While { label, at, .. }) if *label == o.label => {
                    let at = *at;
                    self.seek(lines, line_no, at, o)
                }
                _ => mismatch(o, "endwhile without its while"),
            },
            OKeyword::If(cond) => self.if_line(o, cond, lines, line_no),
            OKeyword::ElseIf(_) | OKeyword::Else => match self.flow.frames.last() {
                // The branch taken ends here: on to endif.
                Some(Frame::If { label }) if *label == o.label => {
                    self.flow.frames.pop();
                    self.skip_to(o, lines, line_no, &[Kind::EndIf]).map(|_| ())
                }
                _ => mismatch(o, "elseif/else without its if"),
            },
            OKeyword::EndIf => match self.flow.frames.last() {
                Some(Frame::If { label }) if *label == o.label => {
                    self.flow.frames.pop();
                    Ok(())
                }
                _ => mismatch(o, "endif without its if"),
            },
            OKeyword::Repeat(n) => {
                let n = expr::eval(n, &self.params, o.at)?.round();
                if n <= 0.0 {
                    return self
                        .skip_to(o, lines, line_no, &[Kind::EndRepeat])
                        .map(|_| ());
                }
                if n > MAX_ITERATIONS as f64 {
                    return too_many(o);
                }
                self.flow.frames.push(Frame::Repeat {
                    label: o.label.clone(),
                    body: next,
                    left: n as u64,
                });
                Ok(())
            }
            OKeyword::EndRepeat => self.end_repeat(o, lines, line_no),
            OKeyword::Break => self.break_loop(o, lines, line_no),
            OKeyword::Continue => self.continue_loop(o, lines, line_no),
        }
    }

    fn place<L: Lines>(&self, lines: &L, line_no: u32, o: &OWord) -> Result<Place, Fail> {
        match lines.mark() {
            Some(mark) => Ok(Place { mark, line_no }),
            None => Err(Fail::new(
                o.at,
                DiagCode::SourceCannotSeek,
                "this program source cannot go back to a line: loops and calls need a program file",
            )),
        }
    }

    fn seek<L: Lines>(
        &mut self,
        lines: &mut L,
        line_no: &mut u32,
        p: Place,
        o: &OWord,
    ) -> Result<(), Fail> {
        if !lines.seek(p.mark) {
            return Err(Fail::new(
                o.at,
                DiagCode::SourceCannotSeek,
                "the program source cannot go back to a line",
            ));
        }
        *line_no = p.line_no;
        Ok(())
    }

    fn while_line<L: Lines>(
        &mut self,
        o: &OWord,
        cond: &super::ast::Expr,
        lines: &mut L,
        line_no: &mut u32,
        here: Place,
    ) -> Result<(), Fail> {
        let c = expr::eval(cond, &self.params, o.at)? != 0.0;
        match self.flow.frames.last_mut() {
            // The end of `do … while`.
            Some(Frame::Do { label, body, count }) if *label == o.label => {
                if !c {
                    self.flow.frames.pop();
                    return Ok(());
                }
                *count += 1;
                if *count >= MAX_ITERATIONS {
                    return too_many(o);
                }
                let body = *body;
                self.seek(lines, line_no, body, o)
            }
            // A `while` seen again from its endwhile.
            Some(Frame::While { label, count, .. }) if *label == o.label => {
                if !c {
                    self.flow.frames.pop();
                    return self
                        .skip_to(o, lines, line_no, &[Kind::EndWhile])
                        .map(|_| ());
                }
                *count += 1;
                if *count >= MAX_ITERATIONS {
                    return too_many(o);
                }
                Ok(())
            }
            _ => {
                if !c {
                    return self
                        .skip_to(o, lines, line_no, &[Kind::EndWhile])
                        .map(|_| ());
                }
                self.flow.frames.push(Frame::While {
                    label: o.label.clone(),
                    at: here,
                    count: 0,
                });
                Ok(())
            }
        }
    }

    fn if_line<L: Lines>(
        &mut self,
        o: &OWord,
        cond: &super::ast::Expr,
        lines: &mut L,
        line_no: &mut u32,
    ) -> Result<(), Fail> {
        let mut taken = expr::eval(cond, &self.params, o.at)? != 0.0;
        while !taken {
            let (kind, cond) =
                self.skip_to(o, lines, line_no, &[Kind::ElseIf, Kind::Else, Kind::EndIf])?;
            match kind {
                Kind::EndIf => return Ok(()),
                Kind::Else => taken = true,
                _ => {
                    let cond = cond.expect("elseif has its condition");
                    taken = expr::eval(&cond, &self.params, o.at)? != 0.0;
                }
            }
        }
        self.flow.frames.push(Frame::If {
            label: o.label.clone(),
        });
        Ok(())
    }

    fn end_repeat<L: Lines>(
        &mut self,
        o: &OWord,
        lines: &mut L,
        line_no: &mut u32,
    ) -> Result<(), Fail> {
        match self.flow.frames.last_mut() {
            Some(Frame::Repeat { label, body, left }) if *label == o.label => {
                *left -= 1;
                if *left == 0 {
                    self.flow.frames.pop();
                    return Ok(());
                }
                let body = *body;
                self.seek(lines, line_no, body, o)
            }
            _ => mismatch(o, "endrepeat without its repeat"),
        }
    }

    /// `break`: leaves the loop of the label (and any `if` inside it).
    fn break_loop<L: Lines>(
        &mut self,
        o: &OWord,
        lines: &mut L,
        line_no: &mut u32,
    ) -> Result<(), Fail> {
        let end = self.pop_to_loop(o)?;
        self.skip_to(o, lines, line_no, &[end]).map(|_| ())
    }

    /// `continue`: the loop's next iteration.
    fn continue_loop<L: Lines>(
        &mut self,
        o: &OWord,
        lines: &mut L,
        line_no: &mut u32,
    ) -> Result<(), Fail> {
        let end = self.pop_to_loop(o)?;
        match self.flow.frames.pop() {
            Some(Frame::While { at, .. }) => {
                // The while line runs again and pushes its frame anew.
                self.seek(lines, line_no, at, o)
            }
            Some(f) => {
                // do … while and repeat: go to their end line and run it.
                self.flow.frames.push(f);
                let (_, _) = self.skip_to(o, lines, line_no, &[end])?;
                let back = self.flow_rewind_one(lines, line_no, o)?;
                self.seek(lines, line_no, back, o)
            }
            None => mismatch(o, "continue outside a loop"),
        }
    }

    /// Pops frames down to the loop of `o`'s label (left on top); its closing keyword.
    fn pop_to_loop(&mut self, o: &OWord) -> Result<Kind, Fail> {
        while let Some(f) = self.flow.frames.last() {
            if f.label() == &o.label {
                return match f {
                    Frame::While { .. } => Ok(Kind::EndWhile),
                    Frame::Do { .. } => Ok(Kind::DoWhile),
                    Frame::Repeat { .. } => Ok(Kind::EndRepeat),
                    _ => mismatch(o, "break/continue outside its loop"),
                };
            }
            if matches!(f, Frame::Call { .. }) {
                break;
            }
            self.flow.frames.pop();
        }
        mismatch(o, "break/continue outside its loop")
    }

    /// The place of the line just read (skip_to leaves the source after it).
    fn flow_rewind_one<L: Lines>(
        &mut self,
        _lines: &mut L,
        _line_no: &mut u32,
        o: &OWord,
    ) -> Result<Place, Fail> {
        self.last_skipped
            .ok_or_else(|| Fail::new(o.at, DiagCode::OWordMismatch, "loop end not found"))
    }

    fn call<L: Lines>(
        &mut self,
        o: &OWord,
        args: &[super::ast::Expr],
        lines: &mut L,
        line_no: &mut u32,
        back: Place,
    ) -> Result<(), Fail> {
        let calls = self
            .flow
            .frames
            .iter()
            .filter(|f| matches!(f, Frame::Call { .. }))
            .count();
        if calls >= MAX_CALL_DEPTH {
            return Err(Fail::new(
                o.at,
                DiagCode::LoopLimit,
                format!("calls nested deeper than {MAX_CALL_DEPTH}"),
            ));
        }
        let mut values = Vec::with_capacity(args.len());
        for a in args {
            values.push(expr::eval(a, &self.params, o.at)?);
        }
        let body = match self.flow.subs.get(&o.label) {
            Some(p) => *p,
            None => self.find_sub(o, lines, line_no, back)?,
        };
        self.params.push_frame(&values);
        self.flow.frames.push(Frame::Call {
            label: o.label.clone(),
            back,
        });
        self.seek(lines, line_no, body, o)
    }

    /// A subroutine defined after its call: searched forward, then back to the call.
    fn find_sub<L: Lines>(
        &mut self,
        o: &OWord,
        lines: &mut L,
        line_no: &mut u32,
        back: Place,
    ) -> Result<Place, Fail> {
        let unknown = || {
            Fail::new(
                o.at,
                DiagCode::SubroutineUnknown,
                format!("{} is not defined in this program", show(&o.label)),
            )
        };
        while let Some(Ok(text)) = lines.next_line(*line_no + 1) {
            *line_no += 1;
            if let Ok(l) = parse::line(text)
                && let Some(ow) = l.oword
                && ow.label == o.label
                && ow.keyword == OKeyword::Sub
            {
                let place = self.place(lines, *line_no, o)?;
                self.flow.subs.insert(o.label.clone(), place);
                self.seek(lines, line_no, back, o)?;
                return Ok(place);
            }
        }
        self.seek(lines, line_no, back, o)?;
        Err(unknown())
    }

    fn leave_sub<L: Lines>(
        &mut self,
        o: &OWord,
        value: Option<&super::ast::Expr>,
        lines: &mut L,
        line_no: &mut u32,
    ) -> Result<(), Fail> {
        let v = value
            .map(|e| expr::eval(e, &self.params, o.at))
            .transpose()?;
        let endsub = matches!(o.keyword, OKeyword::EndSub(_));
        while let Some(f) = self.flow.frames.pop() {
            if let Frame::Call { label, back } = f {
                // LinuxCNC: `return` leaves the innermost call whatever its label names.
                if endsub && label != o.label {
                    return mismatch(o, "ends another subroutine than the one called");
                }
                self.params.pop_frame();
                // #<_value> is what the call returned, 0 when it returned nothing.
                self.params.set_named("_value", v.unwrap_or(0.0));
                let returned = if v.is_some() { 1.0 } else { 0.0 };
                self.params.set_named("_value_returned", returned);
                return self.seek(lines, line_no, back, o);
            }
        }
        mismatch(o, "endsub/return outside a call")
    }

    /// Reads on, without running, to the O-word of `o`'s label with one of `kinds` (nested
    /// structures of other labels pass). Returns the kind found and its condition, if any.
    fn skip_to<L: Lines>(
        &mut self,
        o: &OWord,
        lines: &mut L,
        line_no: &mut u32,
        kinds: &[Kind],
    ) -> Result<(Kind, Option<super::ast::Expr>), Fail> {
        loop {
            let here = lines.mark();
            let Some(item) = lines.next_line(*line_no + 1) else {
                return mismatch(o, "is not closed before the end of the program");
            };
            *line_no += 1;
            let Ok(text) = item else { continue };
            let Ok(l) = parse::line(text) else { continue };
            let letters = &self.machine.axis_letters[..self.machine.n_axes];
            let outputs = &self.machine.m_outputs;
            if let Err(f) = super::words::check_unrun(&l, letters, |m| outputs.get(m).is_some()) {
                self.fail_text = Some(text.to_string());
                return Err(f);
            }
            let Some(ow) = l.oword else { continue };
            if ow.label != o.label {
                continue;
            }
            let (kind, cond) = Kind::of(&ow.keyword);
            if kinds.contains(&kind) || (kind == Kind::While && kinds.contains(&Kind::DoWhile)) {
                self.last_skipped = here.map(|mark| Place {
                    mark,
                    line_no: *line_no - 1,
                });
                return Ok((kind, cond));
            }
        }
    }
}

/// O-word keywords as kinds, for skipping.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    Sub,
    EndSub,
    Other,
    Do,
    While,
    /// The `while` that closes a `do`.
    DoWhile,
    EndWhile,
    If,
    ElseIf,
    Else,
    EndIf,
    Repeat,
    EndRepeat,
}

impl Kind {
    fn of(k: &OKeyword) -> (Kind, Option<super::ast::Expr>) {
        match k {
            OKeyword::Sub => (Kind::Sub, None),
            OKeyword::EndSub(_) => (Kind::EndSub, None),
            OKeyword::Do => (Kind::Do, None),
            OKeyword::While(c) => (Kind::While, Some(c.clone())),
            OKeyword::EndWhile => (Kind::EndWhile, None),
            OKeyword::If(c) => (Kind::If, Some(c.clone())),
            OKeyword::ElseIf(c) => (Kind::ElseIf, Some(c.clone())),
            OKeyword::Else => (Kind::Else, None),
            OKeyword::EndIf => (Kind::EndIf, None),
            OKeyword::Repeat(_) => (Kind::Repeat, None),
            OKeyword::EndRepeat => (Kind::EndRepeat, None),
            _ => (Kind::Other, None),
        }
    }
}
