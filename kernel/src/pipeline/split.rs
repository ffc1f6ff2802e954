//! A validation pass in two halves a caller may run on two threads (issue #49: the
//! interpreter is about half of a pass, compensation, planning and the observers the other
//! half, so on a 2-core controller a million blocks validate in a little over half the time).
//!
//! [`Interpreting`] reads and interprets the lines and hands out what the interpreter gives, in
//! its order ([`Interpreted`]); [`Checking`] takes those in the same order through the
//! compensator and the planner into a [`Validating`] observer and gives the [`Validation`].
//! The kernel moves nothing between threads itself: the caller carries the outputs across
//! (in batches, through a bounded queue) and so stays in charge of threads and memory.
//!
//! It is the pass of [`super::validate_lines_into`], to the message and the block: the
//! order of the outputs is the serial pass's (its notes before each block or error, all of
//! them before the program's end), and the two places where the serial pass answers the
//! interpreter are answered alike:
//! - a probing move ends where it was programmed, as in every pass without a machine
//!   (`ProbeResult::without_machine_for`; a validation never asks its observer);
//! - a validation never stops (its observer answers `Flow::Go` to everything).
//!
//! A restart's scan (`Options::from_block`) is not split: its probing check needs the
//! planner's answer before the interpreter goes on.

use super::{Observer, Options, Pipeline, Validating, Validation};
use crate::block::{Block, Path};
use crate::diag::Diagnostic;
use crate::machine::MachineSetup;
use crate::probe::ProbeResult;
use crate::program::{self, Lines, Modal, Stream};

/// One output of the interpreter, for [`Checking::take`].
#[derive(Clone, Debug)]
#[allow(clippy::large_enum_variant)] // moved once into a batch that is reused
pub enum Interpreted {
    /// A note, warning or error the interpreter found beside a block.
    Note(Diagnostic),
    /// A programmed block and the modal state after it.
    Block(Block, Modal),
    /// A line the interpreter refused.
    Refused(Diagnostic),
}

/// The interpreter's half of a validation pass.
pub struct Interpreting<L> {
    stream: Stream<L>,
    ended: bool,
}

impl<L: Lines> Interpreting<L> {
    /// A restart's pass (`opts.from_block`) is not split: its lines come back (`Err`) for
    /// the serial pass.
    pub fn new(lines: L, setup: &MachineSetup, opts: Options) -> Result<Self, L> {
        if opts.from_block.is_some() {
            return Err(lines);
        }
        Ok(Interpreting {
            stream: program::stream_lines(lines, setup.program()),
            ended: false,
        })
    }

    /// Appends the next outputs to `out` (the notes found with the next block, then the
    /// block); `false` once the program has ended and its last notes are out.
    pub fn next_into(&mut self, out: &mut Vec<Interpreted>) -> bool {
        if self.ended {
            return false;
        }
        let item = self.stream.next();
        out.extend(self.stream.take_notes().into_iter().map(Interpreted::Note));
        match item {
            Some(Ok(b)) => {
                if matches!(b.motion(), Some((_, _, Path::Probe(_)))) {
                    self.stream
                        .probe_result(&ProbeResult::without_machine_for(&b));
                }
                out.push(Interpreted::Block(b, self.stream.modal()));
            }
            Some(Err(d)) => out.push(Interpreted::Refused(d)),
            None => self.ended = true,
        }
        !self.ended
    }
}

/// The other half: compensation, planning and the observer.
pub struct Checking<'a, O: Observer> {
    pipeline: Pipeline,
    validating: Validating<'a, O>,
}

impl<'a, O: Observer> Checking<'a, O> {
    /// A pass with `setup` and `opts` (as given to [`Interpreting::new`]) into `inner`.
    pub fn new(setup: &MachineSetup, opts: Options, inner: &'a mut O) -> Self {
        Checking {
            pipeline: Pipeline::new(setup, opts),
            validating: Validating::new(inner),
        }
    }

    /// The next output of the interpreter, in its order.
    pub fn take(&mut self, item: Interpreted) {
        let obs = &mut self.validating;
        match item {
            Interpreted::Note(d) | Interpreted::Refused(d) => {
                self.pipeline.report(d, obs);
            }
            Interpreted::Block(b, modal) => {
                self.pipeline.push(b, &modal, obs);
                // The interpreter had its answer (`Interpreting::next_into`).
                if matches!(b.motion(), Some((_, _, Path::Probe(_)))) {
                    self.pipeline.probing = false;
                }
            }
        }
    }

    /// The program has ended: the windows empty out, and the verdict.
    pub fn finish(mut self) -> Validation {
        self.pipeline.finish(&mut self.validating);
        let mut v = self.validating.validation;
        v.close(self.pipeline.summary());
        v
    }
}

/// Both halves on the caller's thread, the interpreter's outputs handed over once at least
/// `batch` of them wait (as a caller's queue carries them between threads), and the verdict:
/// for a caller whose second thread cannot start, and to hold the split pass to the serial
/// one at any batch size.
pub fn run_here<L: Lines, O: Observer>(
    mut front: Interpreting<L>,
    mut back: Checking<'_, O>,
    batch: usize,
) -> Validation {
    let mut out = Vec::with_capacity(batch);
    loop {
        let more = front.next_into(&mut out);
        if out.len() >= batch || !more {
            out.drain(..).for_each(|item| back.take(item));
        }
        if !more {
            return back.finish();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::constants::Constants;
    use crate::plan::Segment;
    use crate::program::{Dialect, StrLines};

    /// Everything an observer is given, to compare passes.
    #[derive(Default)]
    struct Seen(Vec<String>);

    impl Observer for Seen {
        fn programmed(&mut self, b: &Block, modal: &Modal) {
            self.0.push(format!("{b:?} {modal:?}"));
        }
        fn compensated(&mut self, c: &crate::comp::CompBlock) {
            self.0.push(format!("{c:?}"));
        }
        fn segment(&mut self, s: &Segment) -> super::super::Flow {
            self.0.push(format!("{s:?}"));
            super::super::Flow::Go
        }
    }

    fn split(text: &str, setup: &MachineSetup) -> (Validation, Vec<String>) {
        let mut seen = Seen::default();
        let Ok(front) = Interpreting::new(StrLines::new(text), setup, Options::default()) else {
            panic!("not a restart");
        };
        let back = Checking::new(setup, Options::default(), &mut seen);
        let v = run_here(front, back, 1);
        (v, seen.0)
    }

    fn setup(dialect: Dialect) -> MachineSetup {
        super::super::tests::setup(Constants::new()).with_dialect(dialect)
    }

    #[test]
    fn the_split_pass_is_the_serial_pass() {
        let cnc836 = "N10 G1 X10 F500\nN20 G7\nN30 D1 G41 X20 Y5\nN40 G40 X30\n\
                      N50 G23 X40 Y10\nN60 G2 X50 Y0 I5 J-5\nN70 Q X0\nN80 M30\n";
        let iso = "G21 G90 G1 X10 F500\nG38.2 Z-5 F100\n#1 = [#5063 + 1]\nG0 Z#1\n\
                   o100 repeat [3]\nG91 G1 X1\no100 endrepeat\nG90 G1 Q7\nG200 X1\nM2\n";
        for (text, dialect) in [(cnc836, Dialect::Cnc836), (iso, Dialect::Iso)] {
            let s = setup(dialect);
            let mut seen = Seen::default();
            let serial = super::super::validate_lines_into(
                StrLines::new(text),
                &s,
                Options::default(),
                &mut seen,
            );
            let (v, split_seen) = split(text, &s);
            assert!(serial.has_errors(), "{dialect:?}: errors to compare too");
            assert_eq!(v, serial, "{dialect:?}");
            assert_eq!(split_seen, seen.0, "{dialect:?}");
        }
    }

    #[test]
    fn a_restart_is_not_split() {
        let opts = Options {
            from_block: Some(20),
            ..Options::default()
        };
        let s = setup(Dialect::Cnc836);
        assert!(Interpreting::new(StrLines::new("N10 X1\nN20 X2\n"), &s, opts).is_err());
    }
}
