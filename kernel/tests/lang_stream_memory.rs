//! A program streams in constant memory, with and without subprograms (docs/language.md,
//! "Subprograms and repeats"): the lines are generated, never held as text, and the peak of
//! live bytes is measured while the blocks stream. One test in this binary, so no other test
//! allocates meanwhile.

use kernel::Diagnostic;
use kernel::program::{LineMark, Lines, Setup};

fn mill() -> Setup {
    Setup::new(&['X', 'Y', 'Z'])
}

/// A generated program, never held as text: `L1 P<passes>`, M30, then `%L1`, `body` lines
/// of motion, M17 (or, with `passes` 0, `body` lines of motion only).
struct Generated {
    passes: u32,
    body: u32,
    next: u64,
    line: String,
}

impl Generated {
    fn total(&self) -> u64 {
        if self.passes == 0 {
            self.body.into()
        } else {
            u64::from(self.body) + 4
        }
    }
}

impl Lines for Generated {
    fn next_line(&mut self, _: u32) -> Option<Result<&str, Diagnostic>> {
        if self.next >= self.total() {
            return None;
        }
        let k = self.next;
        self.next += 1;
        self.line.clear();
        use std::fmt::Write;
        match (self.passes, k) {
            (0, k) => write!(self.line, "N{} G1 X{}.5 Y1 F1000", k % 999_999, k % 100),
            (p, 0) => write!(self.line, "L1 P{p}"),
            (_, 1) => write!(self.line, "M30"),
            (_, 2) => write!(self.line, "%L1"),
            (_, k) if k == self.total() - 1 => write!(self.line, "M17"),
            (_, k) => write!(self.line, "G91 G1 X{}.25 F1000", k % 7),
        }
        .unwrap();
        Some(Ok(&self.line))
    }

    fn mark(&self) -> Option<LineMark> {
        Some(LineMark(self.next))
    }

    fn seek(&mut self, mark: LineMark) -> bool {
        self.next = mark.0;
        mark.0 <= self.total()
    }
}

#[test]
fn memory_stays_constant_with_and_without_subprograms() {
    for (passes, body) in [(0, 200_000), (2_000, 100)] {
        let lines = Generated {
            passes,
            body,
            next: 0,
            line: String::with_capacity(64),
        };
        let mut s = kernel::program::stream_lines(lines, &mill());
        let first = s.next().unwrap().unwrap();
        assert!(first.motion().is_some());
        let start = alloc_count::mark_peak();
        let mut blocks = 1u64;
        for item in s.by_ref() {
            item.unwrap();
            blocks += 1;
        }
        let grown = alloc_count::peak_bytes().saturating_sub(start);
        let expected = if passes == 0 {
            u64::from(body)
        } else {
            u64::from(passes) * u64::from(body) + 1
        };
        assert_eq!(blocks, expected);
        assert!(grown < 4096, "{grown} bytes more for {blocks} blocks");
    }
}

#[global_allocator]
static ALLOC: alloc_count::Counting = alloc_count::Counting;
