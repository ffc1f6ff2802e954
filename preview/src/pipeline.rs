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
#[derive(Clone, Debug, Default)]
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
    fn segment(&mut self, s: &Segment) -> Flow {
        if !self.0.done() {
            self.0.segment(s);
        }
        Flow::Go
    }
}

/// One output of a stage, in the order the pass gave it. (Unboxed: each event is moved once;
/// a box would allocate per segment of a million-block program.)
#[derive(Clone, Debug)]
#[allow(clippy::large_enum_variant)]
enum Event {
    Programmed(Block),
    Compensated(CompBlock),
    Segment(Segment),
}

/// The outputs of a valid pass, kept to be read again (the daemon's `LoadProgram` keeps the
/// selected program's, so that its previews read that pass instead of making another).
#[derive(Clone, Debug)]
pub struct Recording {
    events: Vec<Event>,
    outcome: Outcome,
}

impl Recording {
    /// Gives `sink` the recorded outputs, in their order, as a pass would.
    pub fn replay(&self, sink: &mut impl Sink) -> Outcome {
        for e in &self.events {
            if sink.done() {
                return self.outcome.clone();
            }
            match e {
                Event::Programmed(b) => sink.programmed(b),
                Event::Compensated(c) => sink.compensated(c),
                Event::Segment(s) => sink.segment(s),
            }
        }
        sink.finish();
        self.outcome.clone()
    }
}

/// Records a pass's outputs, up to a budget of bytes (a larger program is not recorded).
#[derive(Debug)]
pub struct Recorder {
    events: Vec<Event>,
    limit: usize,
    overflow: bool,
}

impl Recorder {
    /// A recorder that keeps at most `max_bytes` of outputs (an output takes
    /// [`Recorder::OUTPUT_BYTES`]): the recording of a larger pass is dropped at once, and
    /// the buffer never grows past the budget.
    pub fn new(max_bytes: usize) -> Self {
        Recorder {
            events: Vec::new(),
            limit: max_bytes / Self::OUTPUT_BYTES,
            overflow: false,
        }
    }

    /// Bytes one recorded output takes.
    pub const OUTPUT_BYTES: usize = std::mem::size_of::<Event>();

    fn push(&mut self, e: Event) {
        if self.events.len() >= self.limit {
            self.overflow = true;
            self.events = Vec::new();
            return;
        }
        if self.events.len() == self.events.capacity() {
            // Doubling, but not past the budget.
            let more = self
                .events
                .capacity()
                .max(64)
                .min(self.limit - self.events.len());
            self.events.reserve_exact(more);
        }
        self.events.push(e);
    }

    /// The recording of a valid pass of `blocks` blocks with diagnostics `notes`; `None` when
    /// it had more outputs than the budget.
    pub fn finish(mut self, blocks: u32, notes: Vec<Diagnostic>) -> Option<Recording> {
        self.events.shrink_to_fit();
        (!self.overflow).then_some(Recording {
            events: self.events,
            outcome: Outcome { blocks, notes },
        })
    }
}

// Past the budget nothing is copied any more (a pass goes on for every block).
impl Observer for Recorder {
    fn programmed(&mut self, b: &Block, _modal: &Modal) {
        if !self.overflow {
            self.push(Event::Programmed(*b));
        }
    }
    fn compensated(&mut self, c: &CompBlock) {
        if !self.overflow {
            self.push(Event::Compensated(*c));
        }
    }
    fn segment(&mut self, s: &Segment) -> Flow {
        if !self.overflow {
            self.push(Event::Segment(*s));
        }
        Flow::Go
    }
}

/// Where a picture's data comes from: a pass over a program text, or a recorded pass.
#[derive(Clone, Copy)]
pub enum Source<'a> {
    Text(&'a str),
    Recorded(&'a Recording),
}

/// Gives `sink` the outputs of `source`: a recorded pass is replayed; a text is streamed
/// through the pipeline.
pub fn run_source(
    source: Source<'_>,
    opts: &PreviewOptions,
    sink: &mut impl Sink,
) -> Result<Outcome, Vec<Diagnostic>> {
    match source {
        Source::Text(text) => run(text, opts, sink),
        Source::Recorded(r) => Ok(r.replay(sink)),
    }
}

/// Streams `text` through the pipeline into `sink`. A program with an error gives its every
/// diagnostic (the verdict of validation, with the same settings).
pub fn run(
    text: &str,
    opts: &PreviewOptions,
    sink: &mut impl Sink,
) -> Result<Outcome, Vec<Diagnostic>> {
    let setup = opts.machine.clone().unwrap_or_else(|| {
        MachineSetup::from_stages(opts.setup.clone(), opts.comp, opts.planner.clone())
    });
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
