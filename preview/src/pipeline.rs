//! The preview reads the outputs of the controller's one pipeline (`kernel::pipeline`, the
//! same pass validate, load and the daemon's run make, see `ARCHITECTURE.md`): a [`Sink`]
//! collects what a picture needs, block by block, so memory does not grow with the program.

use kernel::Diagnostic;
use kernel::block::Block;
use kernel::comp::CompBlock;
use kernel::machine::MachineSetup;
use kernel::pipeline::{self, Flow, Observer, Options};
use kernel::plan::Segment;
use kernel::program::Modal;

use crate::PreviewOptions;

/// What a picture collects from the stages.
pub trait Sink {
    /// A programmed (interpreted, uncompensated) block.
    fn programmed(&mut self, _b: &Block) {}
    /// A tool-centre block from the compensator.
    fn compensated(&mut self, _c: &CompBlock) {}
    /// A planned segment, in order, with its final junction class.
    fn segment(&mut self, s: &Segment);
    /// The sink has all it needs (its page is over): it is given nothing more, while the pass
    /// goes on to count the blocks and find every error.
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
    /// Warnings and information.
    pub notes: Vec<Diagnostic>,
}

/// The sink as an observer of the pipeline.
struct Feed<'a, S: Sink>(&'a mut S);

impl<S: Sink> Observer for Feed<'_, S> {
    fn programmed(&mut self, b: &Block, _modal: &Modal) {
        if !self.0.done() {
            self.0.programmed(b);
        }
    }
    fn compensated(&mut self, c: &CompBlock) {
        if !self.0.done() {
            self.0.compensated(c);
        }
    }
    fn segment(&mut self, s: Segment) -> Flow {
        if !self.0.done() {
            self.0.segment(&s);
        }
        Flow::Go
    }
}

/// Streams `text` through the pipeline into `sink`. A program with an error gives its every
/// diagnostic (the verdict of validation, with the same settings).
pub fn run(
    text: &str,
    opts: &PreviewOptions,
    sink: &mut impl Sink,
) -> Result<Outcome, Vec<Diagnostic>> {
    let setup = MachineSetup::from_stages(opts.setup.clone(), opts.comp, opts.planner.clone());
    let v = pipeline::validate_into(text, &setup, Options::default(), &mut Feed(sink));
    if v.has_errors() {
        return Err(v.diagnostics);
    }
    if !sink.done() {
        sink.finish();
    }
    Ok(Outcome {
        blocks: v.blocks,
        notes: v.diagnostics,
    })
}
