//! A bound on the lines a program reads again (docs/language.md, "Bounds"): loops, repeats
//! and calls go back in the source, so a program of a few lines can make the interpreter read
//! billions (counts nested in counts); each bound of one construct (passes, iterations) still
//! multiplies with the next. This one bounds their product: beyond the source's own length
//! (a label search reads it once more) plus [`MAX_LINES_AGAIN`] (`Setup::max_lines_again`),
//! the program stops with `loop_limit`.

use super::{LineMark, Lines};
use crate::diag::Diagnostic;

/// Lines a program may read again beyond its own length: about what a program of that many
/// lines costs to check (seconds), and far more than hand-written repeats of a real part.
/// Fuzzing builds bound it lower, so that every input is checked within the fuzzer's time.
pub const MAX_LINES_AGAIN: u64 = if cfg!(fuzzing) { 100_000 } else { 5_000_000 };

/// A program's lines, counted: a line read at a place before the furthest one reached is a
/// line read again.
pub struct CountedLines<L> {
    lines: L,
    /// The furthest line start read, and the lines read up to it for the first time.
    furthest: Option<u64>,
    first: u64,
    again: u64,
    bound: u64,
    spent: bool,
}

impl<L> CountedLines<L> {
    /// `bound`: lines that may be read again beyond the source's length.
    pub fn new(lines: L, bound: u64) -> Self {
        CountedLines {
            lines,
            bound,
            furthest: None,
            first: 0,
            again: 0,
            spent: false,
        }
    }

    pub fn bound(&self) -> u64 {
        self.bound
    }

    /// The program read more lines again than it may: the source reads as ended.
    pub fn spent(&self) -> bool {
        self.spent
    }
}

impl<L: Lines> Lines for CountedLines<L> {
    fn next_line(&mut self, line_no: u32) -> Option<Result<&str, Diagnostic>> {
        if self.spent {
            return None;
        }
        // A source that cannot go back reads every line once.
        if let Some(LineMark(at)) = self.lines.mark() {
            if self.furthest.is_some_and(|f| at <= f) {
                self.again += 1;
                if self.again > self.first.saturating_add(self.bound) {
                    self.spent = true;
                    return None;
                }
            } else {
                self.furthest = Some(at);
                self.first += 1;
            }
        }
        self.lines.next_line(line_no)
    }

    fn mark(&self) -> Option<LineMark> {
        self.lines.mark()
    }

    fn seek(&mut self, mark: LineMark) -> bool {
        self.lines.seek(mark)
    }
}
