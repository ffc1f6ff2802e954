//! The same straight line of stages the daemon runs (parse → compensate → plan, see
//! `ARCHITECTURE.md`), streamed block by block into a [`Sink`], so memory does not grow with the
//! program: the preview reads the stages rather than recomputing them.

use kernel::Diagnostic;
use kernel::block::Block;
use kernel::comp::{CompBlock, Compensator};
use kernel::plan::{Planner, Segment};
use kernel::program::{self, MAX_DIAGNOSTICS};

use crate::PreviewOptions;

/// What a picture collects from the stages.
pub trait Sink {
    /// A programmed (interpreted, uncompensated) block.
    fn programmed(&mut self, _b: &Block) {}
    /// A tool-centre block from the compensator.
    fn compensated(&mut self, _c: &CompBlock) {}
    /// A planned segment, in order, with its final junction class.
    fn segment(&mut self, s: &Segment);
    /// The sink has all it needs (its page is over): the stages stop, parsing goes on to
    /// count the blocks and find errors.
    fn done(&self) -> bool {
        false
    }
    /// All segments have been delivered (not called when the sink said `done`).
    fn finish(&mut self) {}
}

/// What the run found besides the sink's data.
#[derive(Debug, Default)]
pub struct Outcome {
    /// Programmed blocks in the program.
    pub blocks: u32,
    /// Warnings and information (capped at [`MAX_DIAGNOSTICS`]).
    pub notes: Vec<Diagnostic>,
}

/// Streams `text` through the stages into `sink`. A program with an error gives every error
/// found (parse errors of the whole program; a compensation or planning error stops those
/// stages, since what follows it would be meaningless).
pub fn run(
    text: &str,
    opts: &PreviewOptions,
    sink: &mut impl Sink,
) -> Result<Outcome, Vec<Diagnostic>> {
    let mut stream = program::stream(text, &opts.setup);
    let mut comp = Compensator::new(opts.comp);
    let mut planner = Planner::new(opts.planner.clone(), 1);
    let mut errors: Vec<Diagnostic> = Vec::new();
    let mut out = Outcome::default();
    let mut stages_on = true;
    let note = |out: &mut Outcome, d: Diagnostic| {
        if out.notes.len() < MAX_DIAGNOSTICS {
            out.notes.push(d);
        }
    };
    while let Some(item) = stream.next() {
        for d in stream.take_notes() {
            note(&mut out, d);
        }
        match item {
            Ok(b) => {
                out.blocks = b.seq + 1;
                if stages_on && errors.is_empty() && !sink.done() {
                    sink.programmed(&b);
                    let fed = comp
                        .push(&b)
                        .and_then(|()| drain(&mut comp, &mut planner, sink));
                    if let Err(d) = fed {
                        errors.push(d);
                        stages_on = false;
                    }
                }
            }
            Err(d) => {
                errors.push(d);
                if errors.len() >= MAX_DIAGNOSTICS {
                    break;
                }
            }
        }
    }
    for d in stream.take_notes() {
        note(&mut out, d);
    }
    if stages_on && errors.is_empty() && !sink.done() {
        comp.finish();
        match drain(&mut comp, &mut planner, sink) {
            Ok(()) => {
                planner.finish();
                while let Some(s) = planner.poll() {
                    sink.segment(&s);
                }
                sink.finish();
            }
            Err(d) => errors.push(d),
        }
    }
    for d in comp.take_diagnostics() {
        note(&mut out, d);
    }
    if errors.is_empty() {
        Ok(out)
    } else {
        Err(errors)
    }
}

/// Moves every tool-centre block into the planner and every committed segment to the sink.
fn drain(
    comp: &mut Compensator,
    planner: &mut Planner,
    sink: &mut impl Sink,
) -> Result<(), Diagnostic> {
    while let Some(c) = comp.poll_traced() {
        sink.compensated(&c);
        planner.push(&c.block)?;
        while let Some(s) = planner.poll() {
            sink.segment(&s);
        }
    }
    Ok(())
}
