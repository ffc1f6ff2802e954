//! The one pipeline of the controller: interpret → compensate → plan, streaming (issue #14).
//!
//! Validation, upload, load, start, MDI, both previews and the daemon's run all go through
//! [`run`] with the job's [`MachineSetup`]; they differ only in their [`Observer`], which sees
//! what the stages produce (programmed blocks, tool-centre blocks, segments with their junction
//! class, diagnostics, `G92` writes) and answers the dynamic-set requests. So what is validated
//! is what runs, and a preview shows what runs.
//!
//! Memory stays bounded whatever the program's length: one block at a time from the text, the
//! compensator's window, the planner's look-ahead; segments go to the observer as soon as the
//! planner commits them.
//!
//! Errors: a block refused by a stage is reported to [`Observer::diagnostic`] and skipped (the
//! stage's state is unchanged), so one pass finds every error; an observer that runs the
//! program answers [`Flow::Stop`] to the first error.

pub mod split;

use crate::block::{Block, BlockKind, Continuity};
use crate::comp::{CompBlock, Compensator};
use crate::diag::{DiagCode, DiagCounts, Diagnostic};
use crate::machine::MachineSetup;
use crate::offsets::TableEdit;
use crate::plan::{Planner, Segment};
use crate::probe::ProbeResult;
use crate::program::{self, Modal};
use crate::restart::Restart;

/// Whether the pipeline goes on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Flow {
    Go,
    Stop,
}

/// What a caller sees of the stages. Every hook but [`Observer::segment`] has a default that
/// ignores it.
pub trait Observer {
    /// A programmed (interpreted, uncompensated) block and the modal state after it.
    fn programmed(&mut self, _b: &Block, _modal: &Modal) {}
    /// A tool-centre block from the compensator, with the programmed block it comes from.
    fn compensated(&mut self, _c: &CompBlock) {}
    /// A planned segment, in order, with its final junction class.
    fn segment(&mut self, s: &Segment) -> Flow;
    /// An error, warning or information from any stage, in the order found.
    fn diagnostic(&mut self, _d: Diagnostic) -> Flow {
        Flow::Go
    }
    /// A `G92 D..` block writes the offset table (SPEC §3 c): `b` is the block (its `seq`
    /// tells when it executes). The interpreter has applied it to its own copy already.
    fn table_write(&mut self, _b: &Block, _edit: &TableEdit) -> Flow {
        Flow::Go
    }
    /// The PLC's dynamic-set cell DYNAM_SET (0..3 = set 1..4, SPEC §7.4), asked before each
    /// block is planned; `None` keeps the program's own choice.
    fn dynam_set_cell(&mut self) -> Option<u8> {
        None
    }
    /// A leg of a restart's approach (issue #31, `kernel::restart`), before it is planned:
    /// previews draw it apart from the program's path. It also comes to
    /// [`Observer::compensated`] (a pass-through block) like any block that runs.
    fn approach(&mut self, _leg: &Block) {}
    /// A probing move (`crate::probe`) has been planned and every segment up to its end
    /// handed to [`Observer::segment`]: where did it end? The interpreter goes on from the
    /// answer. A pass without a machine keeps this default: the target reached without a
    /// change, as LinuxCNC's `rs274` assumes. An observer that runs the program waits for
    /// the machine and answers `None` to end the pass (no contact, the run stopped: it
    /// keeps its own error).
    fn probe(&mut self, b: &Block) -> Option<ProbeResult> {
        Some(ProbeResult::without_machine_for(b))
    }
}

/// Two observers of one pass (e.g. `LoadProgram` keeps the junction classes for status and
/// the preview data of the selected program from the same pass). The first one's `Flow::Stop`
/// and dynamic-set cell win.
impl<A: Observer, B: Observer> Observer for (A, B) {
    fn programmed(&mut self, b: &Block, modal: &Modal) {
        self.0.programmed(b, modal);
        self.1.programmed(b, modal);
    }
    fn compensated(&mut self, c: &CompBlock) {
        self.0.compensated(c);
        self.1.compensated(c);
    }
    fn segment(&mut self, s: &Segment) -> Flow {
        let a = self.0.segment(s);
        let b = self.1.segment(s);
        both(a, b)
    }
    fn diagnostic(&mut self, d: Diagnostic) -> Flow {
        let a = self.0.diagnostic(d.clone());
        let b = self.1.diagnostic(d);
        both(a, b)
    }
    fn table_write(&mut self, b: &Block, edit: &TableEdit) -> Flow {
        let x = self.0.table_write(b, edit);
        let y = self.1.table_write(b, edit);
        both(x, y)
    }
    fn dynam_set_cell(&mut self) -> Option<u8> {
        self.0.dynam_set_cell().or(self.1.dynam_set_cell())
    }
    fn approach(&mut self, leg: &Block) {
        self.0.approach(leg);
        self.1.approach(leg);
    }
    fn probe(&mut self, b: &Block) -> Option<ProbeResult> {
        let r = self.0.probe(b);
        let _ = self.1.probe(b);
        r
    }
}

fn both(a: Flow, b: Flow) -> Flow {
    if a == Flow::Stop || b == Flow::Stop {
        Flow::Stop
    } else {
        Flow::Go
    }
}

/// How a job runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Options {
    /// Job id stamped on the segments.
    pub job: u32,
    /// Every block ends at rest (G98): single-block runs.
    pub stop_at_blocks: bool,
    /// Restart from the block with this `N` number (issue #31, `kernel::restart`): the
    /// blocks before it are interpreted and compensated without motion, an approach leads to
    /// its start.
    pub from_block: Option<u32>,
}

/// What a pass found besides what the observer collected.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Summary {
    /// Programmed blocks the interpreter accepted.
    pub blocks: u32,
    /// Errors reported.
    pub errors: u32,
    /// The observer stopped the pass.
    pub stopped: bool,
}

/// Compensator and planner of one pass; the interpreter feeds it block by block.
pub struct Pipeline {
    comp: Compensator,
    planner: Planner,
    stop_at_blocks: bool,
    /// Gear ranges the machine has (`None`: no spindle configured, nothing checked).
    gears: Option<usize>,
    /// Travel limits: every planned segment (offsets and compensation applied) must stay
    /// inside them (issue #15).
    limits: crate::limits::SoftLimits,
    axis_names: Vec<char>,
    summary: Summary,
    restart: Option<Restart>,
    /// A probing move was handed out and waits for its result (`Observer::probe`).
    probing: bool,
}

impl Pipeline {
    pub fn new(setup: &MachineSetup, opts: Options) -> Self {
        Pipeline {
            comp: Compensator::new(setup.comp()),
            planner: Planner::new(setup.planner().clone(), opts.job),
            stop_at_blocks: opts.stop_at_blocks,
            gears: setup.kr().map(|k| k.gears.len()),
            limits: setup.program().soft_limits,
            axis_names: setup.program().axis_names.clone(),
            summary: Summary::default(),
            probing: false,
            restart: opts.from_block.map(|n| {
                let p = setup.program();
                let origin = setup.restart_origin().unwrap_or(p.start);
                Restart::new(n, p.start, origin, p.axis_names.len())
            }),
        }
    }

    pub fn summary(&self) -> Summary {
        self.summary
    }

    fn report(&mut self, d: Diagnostic, obs: &mut impl Observer) -> Flow {
        if d.is_error() {
            self.summary.errors += 1;
        }
        self.flow(obs.diagnostic(d))
    }

    fn flow(&mut self, f: Flow) -> Flow {
        if f == Flow::Stop {
            self.summary.stopped = true;
        }
        f
    }

    /// One programmed block in: compensated, planned, and every committed segment out.
    pub fn push(&mut self, mut b: Block, modal: &Modal, obs: &mut impl Observer) -> Flow {
        self.summary.blocks += 1;
        if self.stop_at_blocks {
            b.continuity = Continuity::G98;
        }
        if let Err(d) = self.check_machine(&b) {
            return self.report(d, obs);
        }
        obs.programmed(&b, modal);
        if let Some(r) = &mut self.restart {
            r.programmed(&b);
        }
        if let BlockKind::TableWrite { entry, values } = b.kind {
            let f = obs.table_write(&b, &TableEdit { entry, values });
            if self.flow(f) == Flow::Stop {
                return Flow::Stop;
            }
        }
        if let Err(d) = self.comp.push(&b)
            && self.report(d, obs) == Flow::Stop
        {
            return Flow::Stop;
        }
        self.drain_comp(obs)
    }

    /// What the interpreter cannot know about this machine: its gear ranges (a gear the
    /// machine lacks would stop the run with a KŘR fault, SPEC §6).
    fn check_machine(&self, b: &Block) -> Result<(), Diagnostic> {
        match self.gears {
            Some(n) if usize::from(b.spindle.gear) > n => Err(Diagnostic::error(
                DiagCode::GearNotConfigured,
                b.n,
                b.line,
                0,
                format!(
                    "gear range {} is not configured on this machine ({n} gear range(s) in [kr] gears)",
                    b.spindle.gear
                ),
            )),
            _ => Ok(()),
        }
    }

    /// Compensator diagnostics and tool-centre blocks into the planner.
    fn drain_comp(&mut self, obs: &mut impl Observer) -> Flow {
        for d in self.comp.take_diagnostics() {
            if self.report(d, obs) == Flow::Stop {
                return Flow::Stop;
            }
        }
        while let Some(cb) = self.comp.poll_traced() {
            let approach = match &mut self.restart {
                Some(r) => match r.compensated(&cb.block) {
                    Some(legs) => legs,
                    None => continue, // before the restart block: not run
                },
                None => Vec::new(),
            };
            for leg in approach {
                obs.approach(&leg);
                let c = CompBlock {
                    block: leg,
                    role: crate::comp::Role::Passthrough,
                    offset_mm: 0.0,
                };
                if self.plan(&c, obs) == Flow::Stop {
                    return Flow::Stop;
                }
            }
            if self.plan(&cb, obs) == Flow::Stop {
                return Flow::Stop;
            }
        }
        Flow::Go
    }

    /// One tool-centre block into the planner, and what it commits out.
    fn plan(&mut self, cb: &CompBlock, obs: &mut impl Observer) -> Flow {
        obs.compensated(cb);
        if let Some(cell) = obs.dynam_set_cell() {
            self.planner.set_dynam_set_cell(cell);
        }
        if let Err(d) = self.planner.push(&cb.block)
            && self.report(d, obs) == Flow::Stop
        {
            return Flow::Stop;
        }
        self.drain_planner(obs)
    }

    fn drain_planner(&mut self, obs: &mut impl Observer) -> Flow {
        while let Some(s) = self.planner.poll() {
            if let Some(hit) = self.limits.check_path(&s.path, self.axis_names.len()) {
                let d = hit.diagnostic(&s, &self.axis_names);
                if self.report(d, obs) == Flow::Stop {
                    return Flow::Stop;
                }
                continue;
            }
            self.probing |= s.probe.is_some();
            if self.flow(obs.segment(&s)) == Flow::Stop {
                return Flow::Stop;
            }
        }
        Flow::Go
    }

    /// After block `b`: when it was a probing move, the interpreter goes on from where it
    /// ended. One that did not run (the blocks a restart scans) has no result: a restart
    /// may not pass it, as what follows may depend on it (docs/language.md, "Probing").
    fn probe_result<L: program::Lines>(
        &mut self,
        b: &Block,
        stream: &mut program::Stream<L>,
        obs: &mut impl Observer,
    ) -> Flow {
        if !matches!(b.motion(), Some((_, _, crate::block::Path::Probe(_)))) {
            return Flow::Go;
        }
        if !std::mem::take(&mut self.probing) {
            stream.probe_result(&ProbeResult::without_machine_for(b));
            if self.restart.as_ref().is_some_and(|r| !r.reached()) {
                let d = Diagnostic::error(
                    DiagCode::RestartPastProbe,
                    b.n,
                    b.line,
                    0,
                    "the restart passes a probing move, whose result the blocks after it may use: restart at the probing block or before it",
                );
                return self.report(d, obs);
            }
            return Flow::Go;
        }
        match obs.probe(b) {
            Some(r) => {
                stream.probe_result(&r);
                Flow::Go
            }
            None => self.flow(Flow::Stop),
        }
    }

    /// The program ended: the compensator's and the planner's windows empty out.
    pub fn finish(&mut self, obs: &mut impl Observer) -> Flow {
        self.comp.finish();
        if self.drain_comp(obs) == Flow::Stop {
            return Flow::Stop;
        }
        if let Some(d) = self.restart.as_ref().and_then(Restart::finish)
            && self.report(d, obs) == Flow::Stop
        {
            return Flow::Stop;
        }
        self.planner.finish();
        self.drain_planner(obs)
    }
}

/// Streams `text` through the stages with `setup` into `obs`.
pub fn run(text: &str, setup: &MachineSetup, opts: Options, obs: &mut impl Observer) -> Summary {
    run_lines(program::StrLines::new(text), setup, opts, obs)
}

/// As [`run`], from lines the caller reads (a program file of any size, issue #19): the same
/// pass, memory bounded by the windows whatever the length.
pub fn run_lines<L: program::Lines>(
    lines: L,
    setup: &MachineSetup,
    opts: Options,
    obs: &mut impl Observer,
) -> Summary {
    // A restart scans the blocks before N from where the program's run started (its
    // incremental moves land where an uninterrupted run's do); the approach starts from
    // where the axes are (`setup.program().start`).
    let scan_setup = match (opts.from_block, setup.restart_origin()) {
        (Some(_), Some(origin)) => Some(program::Setup {
            start: origin,
            ..setup.program().clone()
        }),
        _ => None,
    };
    let mut stream = program::stream_lines(lines, scan_setup.as_ref().unwrap_or(setup.program()));
    let mut p = Pipeline::new(setup, opts);
    let notes = |stream: &mut program::Stream<L>, p: &mut Pipeline, obs: &mut _| {
        for d in stream.take_notes() {
            if p.report(d, obs) == Flow::Stop {
                return Flow::Stop;
            }
        }
        Flow::Go
    };
    while let Some(item) = stream.next() {
        if notes(&mut stream, &mut p, obs) == Flow::Stop {
            return p.summary;
        }
        let f = match item {
            Ok(b) => {
                let modal = stream.modal();
                match p.push(b, &modal, obs) {
                    Flow::Go => p.probe_result(&b, &mut stream, obs),
                    stop => stop,
                }
            }
            Err(d) => p.report(d, obs),
        };
        if f == Flow::Stop {
            return p.summary;
        }
    }
    if notes(&mut stream, &mut p, obs) == Flow::Go {
        p.finish(obs);
    }
    p.summary
}

/// Diagnostics beyond this many are counted, not listed (issue #31): every door (validate,
/// upload, load, run, start) answers at most the first `MAX_LISTED` messages, the first error
/// always among them, and the totals by severity (docs/api.md "Diagnostics at any size").
pub const MAX_LISTED: usize = 200;

/// Outcome of validating a program: the verdict of validate, upload, load, start and MDI.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Validation {
    /// Programmed blocks (the interpreter's count).
    pub blocks: u32,
    /// The first [`MAX_LISTED`] errors, warnings and notes in the order found (the first
    /// error always listed), then a `messages_not_listed` note counting the rest.
    pub diagnostics: Vec<Diagnostic>,
    /// Messages found but not listed, by severity.
    unlisted: DiagCounts,
    /// Whether an error is listed.
    error_listed: bool,
}

impl Validation {
    pub fn has_errors(&self) -> bool {
        self.error_listed
    }

    /// Every message found, listed or not, by severity.
    pub fn counts(&self) -> DiagCounts {
        DiagCounts::of(&self.diagnostics)
    }

    /// Keeps `d` unless the list is full (the first error is kept whatever came before it,
    /// so that a program with many warnings still lists why it is refused).
    pub fn add(&mut self, d: Diagnostic) {
        let n = self.diagnostics.len();
        if n < MAX_LISTED || d.is_error() && !self.error_listed {
            self.error_listed |= d.is_error();
            self.diagnostics.push(d);
        } else if let Some(c) = d.not_listed {
            self.unlisted.errors += c.errors;
            self.unlisted.warnings += c.warnings;
            self.unlisted.infos += c.infos;
        } else {
            self.unlisted.add(d.severity);
        }
    }

    fn close(&mut self, s: Summary) {
        self.blocks = s.blocks;
        let u = self.unlisted;
        if u.total() > 0 {
            let mut note = Diagnostic::info(
                DiagCode::MessagesNotListed,
                None,
                0,
                0,
                format!(
                    "{} more messages not listed ({} errors, {} warnings, {} notes)",
                    u.total(),
                    u.errors,
                    u.warnings,
                    u.infos
                ),
            );
            note.not_listed = Some(u);
            self.diagnostics.push(note);
        }
    }
}

impl Observer for Validation {
    fn segment(&mut self, _s: &Segment) -> Flow {
        Flow::Go
    }

    fn diagnostic(&mut self, d: Diagnostic) -> Flow {
        self.add(d);
        Flow::Go
    }
}

/// Validates `text`: the whole pipeline without motion, every error and warning.
pub fn validate(text: &str, setup: &MachineSetup, opts: Options) -> Validation {
    let mut v = Validation::default();
    let s = run(text, setup, opts, &mut v);
    v.close(s);
    v
}

/// An observer that validates and passes everything on to `inner` (previews collect what
/// they draw and get the verdict of the same pass).
pub struct Validating<'a, O: Observer> {
    pub inner: &'a mut O,
    pub validation: Validation,
}

impl<'a, O: Observer> Validating<'a, O> {
    pub fn new(inner: &'a mut O) -> Self {
        Validating {
            inner,
            validation: Validation::default(),
        }
    }
}

impl<O: Observer> Observer for Validating<'_, O> {
    fn programmed(&mut self, b: &Block, modal: &Modal) {
        self.inner.programmed(b, modal);
    }
    fn compensated(&mut self, c: &CompBlock) {
        self.inner.compensated(c);
    }
    fn approach(&mut self, leg: &Block) {
        self.inner.approach(leg);
    }
    /// The pass goes on whatever `inner` says: the verdict covers the whole program.
    fn segment(&mut self, s: &Segment) -> Flow {
        self.inner.segment(s);
        Flow::Go
    }
    fn diagnostic(&mut self, d: Diagnostic) -> Flow {
        self.validation.add(d);
        Flow::Go
    }
}

/// Runs `text` into `inner` and returns the validation of the same pass.
pub fn validate_into(
    text: &str,
    setup: &MachineSetup,
    opts: Options,
    inner: &mut impl Observer,
) -> Validation {
    validate_lines_into(program::StrLines::new(text), setup, opts, inner)
}

/// As [`validate_into`], from lines the caller reads (a program file of any size).
pub fn validate_lines_into<L: program::Lines>(
    lines: L,
    setup: &MachineSetup,
    opts: Options,
    inner: &mut impl Observer,
) -> Validation {
    let mut v = Validating::new(inner);
    let s = run_lines(lines, setup, opts, &mut v);
    v.validation.close(s);
    v.validation
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::comp::CompConfig;
    use crate::constants::Constants;
    use crate::plan::{Junction, PlannerConfig};
    use crate::program::Setup;

    pub(super) fn setup(c: Constants) -> MachineSetup {
        let mut s = Setup::new(&['X', 'Y', 'Z']);
        s.offsets
            .set_entry(
                1,
                crate::offsets::OffsetEntry {
                    radius_mm: 2.0,
                    length_mm: [0.0; 4],
                },
            )
            .unwrap();
        let comp = CompConfig::from_constants(&c);
        s.constants = c;
        MachineSetup::from_stages(s, comp, PlannerConfig::uniform(3, 200.0, 800.0))
    }

    #[derive(Default)]
    struct Count {
        segments: Vec<Segment>,
        stop_after: Option<usize>,
    }

    impl Observer for Count {
        fn segment(&mut self, s: &Segment) -> Flow {
            self.segments.push(*s);
            match self.stop_after {
                Some(n) if self.segments.len() >= n => Flow::Stop,
                _ => Flow::Go,
            }
        }
    }

    #[test]
    fn validation_lists_the_errors_of_every_stage() {
        let mut c = Constants::new();
        c.set(95, 0.0); // 8.R95 = 0: compensation refused by the compensator
        let text = "N10 G1 X10 F500\nN20 G7\nN30 D1 G41 X20 Y5\nN40 G40 X30\n";
        let v = validate(text, &setup(c), Options::default());
        let errors: Vec<_> = v.diagnostics.iter().filter(|d| d.is_error()).collect();
        assert_eq!(errors.len(), 2, "{:?}", v.diagnostics);
        assert_eq!(errors[0].block, Some(20), "interpreter");
        assert_eq!(errors[1].block, Some(30), "compensator");
        assert_eq!(v.blocks, 3);
    }

    #[test]
    fn an_observer_stops_the_pass_and_single_block_stops_at_every_block() {
        let text = "G23 G1 X10 F3000\nX20\nX30\nX40\n";
        let s = setup(Constants::new());
        let mut all = Count::default();
        let sum = run(text, &s, Options::default(), &mut all);
        assert_eq!((sum.blocks, sum.errors, sum.stopped), (4, 0, false));
        assert!(
            all.segments[..3]
                .iter()
                .any(|s| s.junction != Junction::Stop)
        );
        let mut one = Count {
            stop_after: Some(1),
            ..Count::default()
        };
        assert!(run(text, &s, Options::default(), &mut one).stopped);
        assert_eq!(one.segments.len(), 1);
        let mut sb = Count::default();
        let opts = Options {
            job: 7,
            stop_at_blocks: true,
            ..Options::default()
        };
        run(text, &s, opts, &mut sb);
        assert!(
            sb.segments
                .iter()
                .all(|s| s.junction == Junction::Stop && s.job == 7)
        );
    }

    /// Collects a restart's approach legs and the segments.
    #[derive(Default)]
    struct Legs(Vec<Block>, Vec<Segment>);

    impl Observer for Legs {
        fn approach(&mut self, leg: &Block) {
            self.0.push(*leg);
        }
        fn segment(&mut self, s: &Segment) -> Flow {
            self.1.push(*s);
            Flow::Go
        }
    }

    #[test]
    fn a_restart_scans_incremental_blocks_from_the_runs_origin_and_approaches_from_the_axes() {
        let text = "N10 G91 G1 X10 F600\nN20 Y5\nN30 X10\n";
        let mut here = crate::units::AxesMm::default();
        here[0] = 50.0; // the axes stand at X50 (the run started at X0)
        let base = setup(Constants::new());
        let mut p = base.program().clone();
        p.start = here;
        let s = MachineSetup::from_stages(p, base.comp(), base.planner().clone())
            .with_restart_origin(Some(crate::units::AxesMm::default()));
        let opts = Options {
            from_block: Some(30),
            ..Options::default()
        };
        let mut legs = Legs::default();
        let sum = run(text, &s, opts, &mut legs);
        assert_eq!(sum.errors, 0);
        let start = legs.0[0].motion().unwrap().0;
        assert_eq!((start[0], start[1]), (50.0, 0.0), "from where the axes are");
        let last = legs.0.last().unwrap().motion().unwrap().1;
        assert_eq!(
            (last[0], last[1]),
            (10.0, 5.0),
            "to where N30 starts in the run"
        );
        let n30 = legs.1.iter().find(|s| s.n == Some(30)).unwrap();
        assert_eq!((n30.path.end()[0], n30.path.end()[1]), (20.0, 5.0));
    }
}
