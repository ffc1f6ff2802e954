//! Running subprograms and repeats over a program's lines (docs/language.md, "Subprograms and
//! repeats"): the CNC836 side of [`crate::program::Stream`].
//!
//! A program without calls is read once, line by line, as before: nothing is kept of the
//! lines read. The first call looks for the labels `%L<n>` in one pass over the whole source
//! and keeps one entry per label (number, where its body starts); calls, repeats and returns
//! then seek in the source ([`Lines::mark`], [`Lines::seek`]). Memory is bounded whatever the
//! program's length: at most [`MAX_DEPTH`] frames and one entry per label (1..9999).

use super::subprogram::{is_return_line, label_line};
use super::{Control, Interpreter};
use crate::block::Block;
use crate::diag::{DiagCode, Diagnostic};
use crate::program::{LineMark, Lines, block_delete_slash};

/// Deepest nesting of subprogram calls (the main program calls at depth 0).
pub const MAX_DEPTH: usize = 8;

/// Most subprogram passes (calls and their repeats) in one program: a bound on nested
/// counts (`P9999` in `P9999` ...) that would otherwise run for days.
pub const MAX_PASSES: u32 = 1_000_000;

/// A running subprogram.
#[derive(Clone, Copy, Debug)]
struct Frame {
    label: u16,
    /// The line of its `%L<n>`; its body starts on the next one, at `body`.
    label_line: u32,
    body: LineMark,
    /// The line of the call; the caller goes on at `ret`, the next one.
    call_line: u32,
    ret: LineMark,
    /// Passes still to start after the one running.
    left: u16,
}

/// Where a subprogram is in the source.
#[derive(Clone, Copy, Debug)]
struct Label {
    n: u16,
    line: u32,
    body: LineMark,
}

/// The control flow of one CNC836 program: the call stack, the labels once looked for, and
/// a definition the main program is passing over.
#[derive(Debug, Default)]
pub(crate) struct Flow {
    started: bool,
    /// Where line 1 starts (`None`: the source cannot go back).
    origin: Option<LineMark>,
    labels: Option<Vec<Label>>,
    stack: [Option<Frame>; MAX_DEPTH],
    depth: usize,
    passes: u32,
    /// A definition the main program passes over (not run): its number and line.
    skipping: Option<(u16, u32)>,
    /// An error to give before reading on (a line gave two).
    pending: Option<Diagnostic>,
    stopped: bool,
}

impl Flow {
    /// The next block of the program read from `lines`; `line_no` is the number of the last
    /// line read (calls and returns set it back with the source).
    // Inlined into the stream (its only caller): the block is not copied once more (2 % of
    // the instructions of a validation).
    #[inline(always)]
    pub(crate) fn next<L: Lines>(
        &mut self,
        interp: &mut Interpreter,
        lines: &mut L,
        line_no: &mut u32,
        block_delete: bool,
    ) -> Option<Result<Block, Diagnostic>> {
        if !self.started {
            self.started = true;
            self.origin = lines.mark();
        }
        if let Some(e) = self.pending.take() {
            return Some(Err(e));
        }
        while !self.stopped {
            *line_no += 1;
            let n = *line_no;
            let line = match lines.next_line(n) {
                Some(Ok(l)) => source_line(n, l),
                Some(Err(d)) => return Some(Err(d)),
                None => match self.end_of_source(lines, line_no) {
                    Some(e) => return Some(Err(e)),
                    None => continue,
                },
            };
            if let Some((label, at)) = self.skipping {
                if is_return_line(line) {
                    self.skipping = None;
                } else if let Some(Ok(next)) = label_line(line) {
                    self.skipping = Some((next, n));
                    return Some(Err(without_return(label, at)));
                }
                continue;
            }
            let slash = block_delete_slash(line);
            let unslashed;
            let text = match slash {
                Some(_) if block_delete => continue,
                // Switch off: the block runs; the `/` becomes a space (columns stay).
                Some(k) => {
                    unslashed = format!("{} {}", &line[..k], &line[k + 1..]);
                    unslashed.as_str()
                }
                None => line,
            };
            let control = match interp.read_line(n, text) {
                Ok(Some(b)) => return Some(Ok(b)),
                Ok(None) => match interp.take_control() {
                    Some(c) => c,
                    None => continue,
                },
                Err(d) => {
                    // The text says where a subprogram ends, whatever else is wrong there.
                    if is_return_line(line) && self.depth > 0 {
                        self.pending = self.end_pass(lines, line_no);
                    }
                    return Some(Err(d));
                }
            };
            if let Some(e) = self.control(control, slash.is_some(), n, lines, line_no) {
                return Some(Err(e));
            }
        }
        None
    }

    /// A subprogram form read at line `n` (`slashed`: after a block-delete `/`): a
    /// definition, a call or a return.
    fn control<L: Lines>(
        &mut self,
        control: Control,
        slashed: bool,
        n: u32,
        lines: &mut L,
        line_no: &mut u32,
    ) -> Option<Diagnostic> {
        if slashed && matches!(control, Control::Label(_) | Control::Return) {
            return Some(error(
                DiagCode::SubprogramSyntax,
                None,
                n,
                "the start %L and the end M17 of a subprogram cannot be block-deleted",
            ));
        }
        match control {
            Control::Label(label) => self.label(label, n, lines, line_no),
            Control::Call {
                label,
                count,
                n: block,
            } => self.call((label, count, block), lines, line_no),
            Control::Return if self.depth == 0 => Some(error(
                DiagCode::ReturnWithoutCall,
                None,
                n,
                "M17 ends a subprogram, but this is the main program: no call to return from",
            )),
            Control::Return => self.end_pass(lines, line_no),
        }
    }

    /// After the last line: a definition passed over or a subprogram running has no end.
    fn end_of_source<L: Lines>(&mut self, lines: &mut L, line_no: &mut u32) -> Option<Diagnostic> {
        if let Some((label, at)) = self.skipping.take() {
            self.stopped = true;
            return Some(without_return(label, at));
        }
        let Some(frame) = self.top() else {
            self.stopped = true;
            return None;
        };
        let e = without_return(frame.label, frame.label_line);
        Some(self.leave(lines, line_no).unwrap_or(e))
    }

    /// `%L<label>` on line `n`: the main program passes over the definition; a running
    /// subprogram has run into the next one without its M17.
    fn label<L: Lines>(
        &mut self,
        label: u16,
        n: u32,
        lines: &mut L,
        line_no: &mut u32,
    ) -> Option<Diagnostic> {
        let Some(frame) = self.top() else {
            self.skipping = Some((label, n));
            return None;
        };
        let e = without_return(frame.label, frame.label_line);
        Some(self.leave(lines, line_no).unwrap_or(e))
    }

    /// `L<label> P<count>` in block `block` (the line just read): the first pass starts.
    fn call<L: Lines>(
        &mut self,
        (label, count, block): (u16, u16, Option<u32>),
        lines: &mut L,
        line_no: &mut u32,
    ) -> Option<Diagnostic> {
        let at = *line_no;
        let located = |code, message: String| Diagnostic::error(code, block, at, 1, message);
        if self.depth == MAX_DEPTH {
            let msg =
                format!("subprogram calls nest at most {MAX_DEPTH} deep: L{label} is one more");
            return Some(located(DiagCode::LoopLimit, msg));
        }
        let (Some(ret), Some(_)) = (lines.mark(), self.origin) else {
            let msg = "this program source cannot go back to a line: a subprogram call needs it";
            return Some(located(DiagCode::SourceCannotSeek, msg.into()));
        };
        if self.labels.is_none() {
            let Some((labels, twice)) = self.find_labels(lines, ret) else {
                self.stopped = true;
                let msg = "the program source could not go back to its start to find L{label}";
                return Some(located(DiagCode::SourceCannotSeek, msg.into()));
            };
            self.labels = Some(labels);
            if twice.is_some() {
                return twice;
            }
        }
        let found = self.labels.as_ref()?.iter().find(|l| l.n == label).copied();
        let Some(def) = found else {
            let msg = format!("subprogram L{label} is not in the program (a line %L{label})");
            return Some(located(DiagCode::SubroutineUnknown, msg));
        };
        if let Some(e) = self.count_pass(at, block) {
            return Some(e);
        }
        self.stack[self.depth] = Some(Frame {
            label,
            label_line: def.line,
            body: def.body,
            call_line: at,
            ret,
            left: count - 1,
        });
        self.depth += 1;
        self.go(lines, line_no, def.body, def.line)
    }

    /// M17 of the running subprogram: its next pass, or back to the caller.
    fn end_pass<L: Lines>(&mut self, lines: &mut L, line_no: &mut u32) -> Option<Diagnostic> {
        let frame = self.stack[self.depth.checked_sub(1)?].as_mut()?;
        if frame.left == 0 {
            return self.leave(lines, line_no);
        }
        frame.left -= 1;
        let (body, line) = (frame.body, frame.label_line);
        if let Some(e) = self.count_pass(*line_no, None) {
            return Some(e);
        }
        self.go(lines, line_no, body, line)
    }

    /// Ends the running subprogram (passes left or not): the caller goes on after the call.
    fn leave<L: Lines>(&mut self, lines: &mut L, line_no: &mut u32) -> Option<Diagnostic> {
        let frame = self.top()?;
        self.depth -= 1;
        self.stack[self.depth] = None;
        self.go(lines, line_no, frame.ret, frame.call_line)
    }

    /// Reads on from `mark`, whose line follows line `line`.
    fn go<L: Lines>(
        &mut self,
        lines: &mut L,
        line_no: &mut u32,
        mark: LineMark,
        line: u32,
    ) -> Option<Diagnostic> {
        if lines.seek(mark) {
            *line_no = line;
            return None;
        }
        self.stopped = true;
        Some(error(
            DiagCode::SourceCannotSeek,
            None,
            *line_no,
            "the program source could not go back to a line it had given",
        ))
    }

    /// One more subprogram pass; beyond [`MAX_PASSES`] the program stops with an error.
    fn count_pass(&mut self, line: u32, block: Option<u32>) -> Option<Diagnostic> {
        self.passes += 1;
        if self.passes <= MAX_PASSES {
            return None;
        }
        self.stopped = true;
        Some(Diagnostic::error(
            DiagCode::LoopLimit,
            block,
            line,
            1,
            format!("more than {MAX_PASSES} subprogram passes: checking stopped here"),
        ))
    }

    fn top(&self) -> Option<Frame> {
        self.stack[self.depth.checked_sub(1)?]
    }

    /// Every label of the source (one pass from its start), then back to `here`; the error
    /// for the first number defined twice (the first definition counts). `None`: the source
    /// could not go back.
    fn find_labels<L: Lines>(
        &mut self,
        lines: &mut L,
        here: LineMark,
    ) -> Option<(Vec<Label>, Option<Diagnostic>)> {
        let mut labels: Vec<Label> = Vec::new();
        let mut twice = None;
        let mut n = 0;
        if !lines.seek(self.origin?) {
            return None;
        }
        while let Some(l) = lines.next_line(n + 1) {
            n += 1;
            let Ok(l) = l else { continue };
            let Some(Ok(label)) = label_line(source_line(n, l)) else {
                continue;
            };
            if let Some(first) = labels.iter().find(|d| d.n == label) {
                let msg = format!(
                    "subprogram L{label} is defined twice, on lines {} and {n}",
                    first.line
                );
                twice = twice.or(Some(error(DiagCode::SubprogramTwice, None, n, &msg)));
            } else {
                let body = lines.mark()?;
                labels.push(Label {
                    n: label,
                    line: n,
                    body,
                });
            }
        }
        lines.seek(here).then_some((labels, twice))
    }

    /// Whether program code follows the end of the program (M2/M30) in `lines`, after line
    /// `line_no`: subprogram definitions are not code that is left out.
    pub(crate) fn code_after_end<L: Lines>(&self, lines: &mut L, line_no: u32) -> bool {
        let mut in_definition = false;
        let mut n = line_no;
        while let Some(l) = lines.next_line(n + 1) {
            n += 1;
            let Ok(l) = l else { continue };
            if label_line(l).is_some_and(|r| r.is_ok()) {
                in_definition = true;
            } else if in_definition {
                in_definition = !is_return_line(l);
            } else {
                let code = l.split(';').next().unwrap_or("").trim();
                if !code.is_empty() && code != "%" {
                    return true;
                }
            }
        }
        false
    }
}

/// A line as the program means it: a UTF-8 byte order mark (some PC editors write one) is
/// not part of line 1.
fn source_line(n: u32, line: &str) -> &str {
    if n == 1 {
        line.strip_prefix('\u{FEFF}').unwrap_or(line)
    } else {
        line
    }
}

fn error(code: DiagCode, block: Option<u32>, line: u32, message: &str) -> Diagnostic {
    Diagnostic::error(code, block, line, 1, message.to_string())
}

fn without_return(label: u16, line: u32) -> Diagnostic {
    let msg = format!(
        "subprogram L{label} has no end: write M17 before the next %L or the end of the program"
    );
    error(DiagCode::SubprogramWithoutReturn, None, line, &msg)
}
