//! Part-program parser and interpreter (SPEC §2, §3, §4.6, §5): program text → canonical
//! [`Block`]s. The language is described for machinists in `docs/language.md`.
//!
//! Three ways in, one interpreter underneath:
//! - [`compile`]: whole program, all blocks and all messages (tests, preview, small programs);
//! - [`validate`]: whole program, messages only, no blocks kept (the daemon's check before a
//!   program may run; memory does not grow with the program);
//! - [`stream`]: an iterator of blocks for execution, one at a time (a 1,000,000-block program
//!   is never held as blocks).
//!
//! Submodules: [`cnc836`] (the CNC836 dialect: its lexer [`words`], modal state, one block
//! at a time), [`iso`] (the ISO dialect), [`feed`] (F units and limits), [`arc`] (E address,
//! R325 refinement, R55 check).

pub mod arc;
pub mod cnc836;
mod code_pages;
mod dialect;
pub mod dry_run;
pub mod encoding;
pub mod feed;
pub mod iso;
pub mod lines_again;

pub use cnc836::words;

/// The CNC836 interpreter's former path (before [`cnc836`]), kept for callers.
pub mod interpreter {
    pub use super::cnc836::{Interpreter, Modal, RESERVED_LETTERS};
}

pub use dialect::Dialect;

pub use cnc836::{Interpreter, Modal, ModalParts, Motion};
pub use feed::{
    FeedMode, MAX_FEED_MM_MIN, MAX_FEED_MM_REV, rotary_feed_factor, rotary_surface_speed_mm_min,
};

use crate::block::Block;
use crate::constants::Constants;
use crate::diag::{DiagCode, Diagnostic};
use crate::offsets::OffsetTable;
use crate::units::AxesMm;

/// Most errors collected for one program: then checking stops with one last error (a binary
/// file would otherwise produce a message per line). Warnings beyond this many are counted,
/// not listed, and never stop the check.
pub const MAX_DIAGNOSTICS: usize = 1000;

/// How the arc centre words I and J are read (SPEC §2: **decided**, a setting; default relative).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum IjMode {
    /// I, J are the centre minus the arc's start point (the common convention).
    #[default]
    RelativeToStart,
    /// I, J are the centre in program coordinates (like the axis words under G90).
    Absolute,
}

/// What the interpreter needs to know about the machine.
#[derive(Clone, Debug, PartialEq)]
pub struct Setup {
    /// The language of the program (`[program] dialect`, or the file's extension).
    pub dialect: Dialect,
    /// Work offsets G54..G59.3 (ISO dialect) at program start.
    pub work_offsets: crate::offsets::WorkOffsets,
    /// The block-delete switch (issue #31, docs/language.md "Block delete"): a block whose
    /// first character is `/` is skipped while on, and runs (the `/` ignored) while off.
    pub block_delete: bool,
    /// Axis letters in machine order (R0..R5), e.g. `['X', 'Y', 'Z']`.
    pub axis_names: Vec<char>,
    /// Position of the axes when the program starts (machine coordinates).
    pub start: AxesMm,
    /// Machine constants (R55 arc tolerance, R325 refinement, R397, R339, R329 ...).
    pub constants: Constants,
    /// The memory offset table at program start (D and & look-ups; G92 writes on a copy).
    pub offsets: OffsetTable,
    /// How I and J are read.
    pub ij: IjMode,
    /// The code page of program files (`[program] encoding`): the daemon's doors decode with
    /// it before the text reaches the stream.
    pub encoding: encoding::TextEncoding,
    /// The axis programmed as a diameter (`[kr] radius_input = "diameter"`: the controlling
    /// axis R67 of a lathe), `None` on a machine programmed in radius everywhere. Its words,
    /// its absolute arc centre and its TAB0.KOR length are diameters; the interpreter halves
    /// them, so every block it emits (and compensation, planning, setpoints after it) is in
    /// radius: the true geometry. A relative arc centre (I) is a radius. See docs/lathe.md.
    pub diameter_axis: Option<usize>,
    /// Thousands of encoder pulses per revolution of each rotary axis, 0 for a linear axis
    /// (`rotary_pulses_per_rev` of the axis / 1000). A rotary axis is positioned in degrees;
    /// its feed is in thousands of pulses per minute (SPEC §5, docs/lathe.md).
    pub rotary_kpulses_per_rev: [f64; crate::units::MAX_AXES],
    /// `$63` of CNC836.KNF: the preprocessor is on (default), needed for R325 refinement.
    pub preprocessor: bool,
    /// The spindle gear table (`[kr.gears]`): an M code selects the range whose `m_code` it
    /// is. Empty (unit tests, tools without a machine): M41..M44 select ranges 1..4 and feed
    /// per revolution is planned at the programmed S.
    pub gears: Vec<crate::kr::Gear>,
    /// M functions bound to the machine's outputs and inputs (`[io]`, docs/io.md); empty:
    /// every M without a meaning of its own passes through.
    pub m_outputs: crate::outputs::MFunctions,
    /// Highest path feed the machine can reach, mm/min (the fastest axis; 0 = unknown): a
    /// feed per revolution above βmax = Vmax/S is a warning (SPEC §5).
    pub max_feed_mm_min: f64,
    /// Modal state to start in (MDI inherits what the last program or MDI left); `None`: the
    /// power-on state.
    pub modal: Option<Modal>,
    /// Travel limits of the machine: the daemon's validation refuses a program whose planned
    /// path leaves them (the interpreter itself does not look at them).
    pub soft_limits: crate::limits::SoftLimits,
    /// Automatic tool changer: the tool of an M6 must fit in this many binary outputs
    /// (`None`: no limit).
    pub tool_number_bits: Option<u8>,
    /// Lines a program may read again beyond its own length ([`lines_again`]).
    pub max_lines_again: u64,
}

impl Setup {
    pub fn new(axis_names: &[char]) -> Self {
        Setup {
            dialect: Dialect::Cnc836,
            work_offsets: crate::offsets::WorkOffsets::default(),
            axis_names: axis_names.to_vec(),
            start: AxesMm::ZERO,
            constants: Constants::new(),
            offsets: OffsetTable::new(),
            ij: IjMode::default(),
            encoding: encoding::TextEncoding::Utf8,
            diameter_axis: None,
            rotary_kpulses_per_rev: [0.0; crate::units::MAX_AXES],
            preprocessor: true,
            gears: Vec::new(),
            m_outputs: crate::outputs::MFunctions::default(),
            max_feed_mm_min: 0.0,
            modal: None,
            soft_limits: crate::limits::SoftLimits::NONE,
            max_lines_again: lines_again::MAX_LINES_AGAIN,
            block_delete: false,
            tool_number_bits: None,
        }
    }

    /// A setup whose axes come from R0..R5 of `constants` and whose table is the daemon's
    /// memory offset table at program start.
    pub fn from_machine(constants: Constants, offsets: OffsetTable) -> Self {
        Setup {
            axis_names: constants.axis_names(),
            constants,
            offsets,
            ..Setup::new(&[])
        }
    }
}

/// A validated program: its canonical blocks and every message about it.
#[derive(Clone, Debug, Default)]
pub struct Compiled {
    pub blocks: Vec<Block>,
    pub diagnostics: Vec<Diagnostic>,
}

impl Compiled {
    pub fn has_errors(&self) -> bool {
        self.diagnostics.iter().any(Diagnostic::is_error)
    }
}

/// Parses and interprets a whole program. Blocks are kept only if there is no error.
pub fn compile(text: &str, setup: &Setup) -> Compiled {
    let mut out = Compiled::default();
    run(text, setup, |b| out.blocks.push(b), &mut out.diagnostics);
    if out.has_errors() {
        out.blocks.clear();
    }
    out
}

/// Checks a whole program without keeping its blocks: every error, warning and information,
/// in source order (see [`MAX_DIAGNOSTICS`]). The program may run iff none is an error.
pub fn validate(text: &str, setup: &Setup) -> Vec<Diagnostic> {
    let mut diags = Vec::new();
    run(text, setup, |_| {}, &mut diags);
    diags
}

fn run(text: &str, setup: &Setup, mut sink: impl FnMut(Block), diags: &mut Vec<Diagnostic>) {
    let mut s = stream(text, setup);
    let mut errors = 0usize;
    let mut dropped_notes = 0usize;
    let mut keep_notes = |diags: &mut Vec<Diagnostic>, notes: Vec<Diagnostic>| {
        for n in notes {
            if diags.len() < MAX_DIAGNOSTICS {
                diags.push(n);
            } else {
                dropped_notes += 1;
            }
        }
    };
    while let Some(item) = s.next() {
        if s.has_notes() {
            keep_notes(diags, s.take_notes());
        }
        match item {
            Ok(b) => sink(b),
            Err(d) => {
                diags.push(d);
                errors += 1;
                // The program cannot run anyway: stop before the list becomes useless.
                if errors >= MAX_DIAGNOSTICS {
                    diags.push(Diagnostic::error(
                        DiagCode::TooManyErrors,
                        None,
                        s.line_no,
                        0,
                        format!("more than {MAX_DIAGNOSTICS} errors: checking stopped here"),
                    ));
                    return;
                }
            }
        }
    }
    keep_notes(diags, s.take_notes());
    // Warnings never stop the check (a program with many warnings may still run); beyond the
    // cap they are only counted.
    if dropped_notes > 0 {
        diags.push(Diagnostic::info(
            DiagCode::MessagesNotListed,
            None,
            0,
            0,
            format!("{dropped_notes} more warnings or notes not listed"),
        ));
    }
}

/// The R325 listing (SPEC §4.6): the program text with the preprocessor's refinements written
/// as address E the way the manual shows (`E2.054`, `E-10006.992`), every refinement per block,
/// and the program's messages. A programmed E is replaced by the total; a refinement of the
/// other coordinate than a programmed E is listed but not written (one E per block).
pub fn refinement_listing(
    text: &str,
    setup: &Setup,
) -> (String, Vec<arc::Refined>, Vec<Diagnostic>) {
    let mut s = stream(text, setup);
    s.interp.record_refinements();
    let mut diags = Vec::new();
    let mut refined = Vec::new();
    while let Some(item) = s.next() {
        diags.extend(s.interp.take_notes());
        refined.extend(s.interp.take_refinements());
        if let Err(d) = item {
            diags.push(d);
        }
    }
    diags.extend(s.interp.take_notes());
    refined.extend(s.interp.take_refinements());
    (write_refinements(text, &refined), refined, diags)
}

/// `text` with the E words of `refined` written into their lines.
fn write_refinements(text: &str, refined: &[arc::Refined]) -> String {
    let mut out = String::with_capacity(text.len() + 16 * refined.len());
    let mut next = refined.iter().peekable();
    for (k, line) in text.split_inclusive('\n').enumerate() {
        let line_no = k as u32 + 1;
        let mut word = None;
        while let Some(r) = next.next_if(|r| r.line <= line_no) {
            if r.line == line_no {
                word = r.word.map(|w| (w, r.programmed_e_at));
            }
        }
        match word {
            Some((w, at)) => out.push_str(&with_e_word(line, w.encode(), at)),
            None => out.push_str(line),
        }
    }
    out
}

/// One line with its E word set to `e`: a programmed E word (at byte `at`) is replaced,
/// otherwise ` E…` is written after the last word, before a remark.
fn with_e_word(line: &str, e: f64, at: Option<usize>) -> String {
    let word = format!("E{e:.3}");
    if let Some(at) = at {
        let rest = &line[at + 1..];
        let len = rest
            .find(|c: char| !(c.is_ascii_digit() || matches!(c, '.' | '+' | '-' | ' ')))
            .unwrap_or(rest.len());
        let tail = &rest[len..];
        let gap = if tail.is_empty() || tail.starts_with(['\r', '\n']) {
            ""
        } else {
            " "
        };
        return format!("{}{word}{gap}{tail}", &line[..at]);
    }
    let end = words::remark_start(line);
    let code = line[..end].trim_end();
    let tail = &line[code.len()..];
    let gap = if tail.trim_start().is_empty() {
        ""
    } else {
        " "
    };
    format!("{code} {word}{gap}{}", tail.trim_start_matches([' ', '\t']))
}

/// Where a program's lines come from: a string in memory ([`StrLines`]) or a file the caller
/// reads (the kernel does no IO). Lines are given without their `\n`; the text after the last
/// `\n` (possibly empty) is the last line.
pub trait Lines {
    /// The next line, `None` after the last. `Err`: a line that cannot be read as text (not
    /// UTF-8 ...): reported as that line's error, and the stream goes on with the next line.
    fn next_line(&mut self, line_no: u32) -> Option<Result<&str, Diagnostic>>;

    /// Where the next line starts, for [`Lines::seek`]: the ISO dialect's loops and
    /// subroutines go back to a line already read. `None`: this source cannot go back.
    fn mark(&self) -> Option<LineMark> {
        None
    }

    /// Continues reading at `mark` (taken from this source). `false`: it cannot.
    fn seek(&mut self, _mark: LineMark) -> bool {
        false
    }
}

/// A place in a program's lines: the byte offset of a line's start in the source.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct LineMark(pub u64);

/// The lines of a text in memory.
pub struct StrLines<'a> {
    text: &'a str,
    pos: usize,
    done: bool,
}

impl<'a> StrLines<'a> {
    pub fn new(text: &'a str) -> Self {
        StrLines {
            text,
            pos: 0,
            done: false,
        }
    }
}

impl Lines for StrLines<'_> {
    fn next_line(&mut self, _line_no: u32) -> Option<Result<&str, Diagnostic>> {
        if self.done {
            return None;
        }
        let rest = &self.text[self.pos..];
        let line = match rest.find('\n') {
            Some(k) => {
                self.pos += k + 1;
                &rest[..k]
            }
            None => {
                self.done = true;
                self.pos = self.text.len();
                rest
            }
        };
        Some(Ok(line))
    }

    fn mark(&self) -> Option<LineMark> {
        Some(LineMark(if self.done {
            self.text.len() as u64 + 1
        } else {
            self.pos as u64
        }))
    }

    fn seek(&mut self, mark: LineMark) -> bool {
        let Ok(pos) = usize::try_from(mark.0) else {
            return false;
        };
        if pos > self.text.len() + 1 || (pos <= self.text.len() && !self.text.is_char_boundary(pos))
        {
            return false;
        }
        self.done = pos > self.text.len();
        self.pos = pos.min(self.text.len());
        true
    }
}

/// Streams the blocks of a program for execution: `Ok(block)` in order, `Err(error)` for a
/// block that is wrong (its state change is dropped and streaming continues, so a validating
/// caller sees every error; an executing caller stops at the first). Warnings and information
/// are not errors: collect them with [`Stream::take_notes`]. Memory stays constant.
pub fn stream<'a>(text: &'a str, setup: &Setup) -> Stream<StrLines<'a>> {
    stream_lines(StrLines::new(text), setup)
}

/// As [`stream`], from lines read by the caller (a program file of any size).
pub fn stream_lines<L: Lines>(lines: L, setup: &Setup) -> Stream<L> {
    let interp = Interpreter::new(setup);
    let iso = (setup.dialect == Dialect::Iso).then(|| Box::new(iso::Interpreter::new(setup)));
    Stream {
        pending_setup_error: interp.setup_error(),
        interp,
        iso,
        flow: cnc836::flow::Flow::default(),
        lines: lines_again::CountedLines::new(lines, setup.max_lines_again),
        line_no: 0,
        done: false,
        block_delete: setup.block_delete,
        tool_number_bits: setup.tool_number_bits,
    }
}

/// Iterator of a program's blocks, see [`stream`].
pub struct Stream<L> {
    /// The CNC836 interpreter (also the setup's checks for an ISO program).
    interp: Interpreter,
    /// The ISO front-end, when the program is ISO.
    iso: Option<Box<iso::Interpreter>>,
    /// Subprogram calls and repeats of a CNC836 program.
    flow: cnc836::flow::Flow,
    lines: lines_again::CountedLines<L>,
    line_no: u32,
    pending_setup_error: Option<Diagnostic>,
    done: bool,
    /// The block-delete switch of the setup.
    block_delete: bool,
    /// See [`Setup::tool_number_bits`].
    tool_number_bits: Option<u8>,
}

impl<L> Stream<L> {
    /// Warnings and information produced so far and not yet taken.
    pub fn take_notes(&mut self) -> Vec<Diagnostic> {
        match self.iso.as_mut() {
            Some(iso) => iso.take_notes(),
            None => self.interp.take_notes(),
        }
    }

    fn has_notes(&self) -> bool {
        match self.iso.as_ref() {
            Some(iso) => iso.has_notes(),
            None => self.interp.has_notes(),
        }
    }

    /// The CNC836 interpreter (its offset table, parameters) as of the last block returned;
    /// `None` for an ISO program.
    pub fn interpreter(&self) -> Option<&Interpreter> {
        self.iso.is_none().then_some(&self.interp)
    }

    /// The probing move of the last block returned ended as `r` reports: the interpreter
    /// sets its result parameters and goes on from where the axes came to rest.
    pub fn probe_result(&mut self, r: &crate::probe::ProbeResult) {
        match self.iso.as_mut() {
            Some(iso) => iso.probe_result(r),
            None => self.interp.probe_result(r),
        }
    }

    /// The modal state after the last block returned (what an MDI after it inherits).
    pub fn modal(&self) -> Modal {
        match self.iso.as_ref() {
            Some(iso) => iso.modal(),
            None => self.interp.modal(),
        }
    }
}

impl<L: Lines> Stream<L> {
    /// M2/M30 end the program: what follows is neither interpreted nor run; a note says so
    /// when there is something.
    fn end_program(&mut self, b: &Block) {
        self.done = true;
        if self.iso.is_some() {
            // ISO programs keep subroutines after M2 (LinuxCNC reads them): no note.
            return;
        }
        if self.flow.code_after_end(&mut self.lines, self.line_no) {
            self.interp.note(Diagnostic::info(
                DiagCode::LinesAfterEnd,
                b.n,
                b.line,
                0,
                format!(
                    "the program ends at line {} (M2/M30): the lines after it are not run",
                    b.line
                ),
            ));
        }
    }

    /// An M6 whose tool the changer's tool number outputs cannot carry (the daemon's RT core
    /// puts the number on them in binary, docs/setup.md "Automatic tool changer").
    fn tool_beyond_outputs(&self, b: &Block) -> Option<Diagnostic> {
        let bits = u32::from(self.tool_number_bits?);
        let crate::block::BlockKind::ToolChange { tool } = b.kind else {
            return None;
        };
        (bits < 8 && u32::from(tool) >> bits != 0).then(|| {
            Diagnostic::error(
                DiagCode::ToolNumberBeyondOutputs,
                b.n,
                b.line,
                0,
                format!(
                    "T{tool}: the tool changer's {bits} tool number outputs carry tools up to {}",
                    (1u32 << bits) - 1
                ),
            )
        })
    }

    /// The program read more lines again than its bound (`Setup::max_lines_again`): it ends
    /// with one error, whatever the dialect made of the source seeming to end.
    fn lines_spent(&mut self) -> Option<Result<Block, Diagnostic>> {
        self.done = true;
        Some(Err(Diagnostic::error(
            DiagCode::LoopLimit,
            None,
            self.line_no,
            0,
            format!(
                "the program reads more than {} lines again (loops, repeats, calls): \
                 checking stopped here",
                self.lines.bound()
            ),
        )))
    }

    fn next_cnc836(&mut self) -> Option<Result<Block, Diagnostic>> {
        let item = self.flow.next(
            &mut self.interp,
            &mut self.lines,
            &mut self.line_no,
            self.block_delete,
        );
        if item.is_none() {
            self.done = true;
        }
        item
    }
}

impl<L: Lines> Iterator for Stream<L> {
    type Item = Result<Block, Diagnostic>;

    fn next(&mut self) -> Option<Self::Item> {
        if let Some(e) = self.pending_setup_error.take() {
            self.done = true;
            return Some(Err(e));
        }
        if self.done {
            return None;
        }
        let item = match self.iso.as_mut() {
            Some(iso) => {
                let item = iso.next(&mut self.lines, &mut self.line_no, self.block_delete);
                if item.is_none() {
                    self.done = true;
                }
                item
            }
            None => self.next_cnc836(),
        };
        if self.lines.spent() {
            return self.lines_spent();
        }
        if let Some(Ok(b)) = &item
            && crate::block::ends_program(&b.m)
        {
            let b = *b;
            self.end_program(&b);
        }
        if let Some(Ok(b)) = &item
            && let Some(e) = self.tool_beyond_outputs(b)
        {
            self.done = true;
            return Some(Err(e));
        }
        item
    }
}

/// Where the block-delete `/` of `line` is: the first character that is not a space or tab.
fn block_delete_slash(line: &str) -> Option<usize> {
    let k = line.len() - line.trim_start_matches([' ', '\t']).len();
    (line.as_bytes().get(k) == Some(&b'/')).then_some(k)
}

/// Fuzzing entry: arbitrary bytes as a program, for a mill and a lathe, with refinement and
/// 7.R397 on and off, and as an ISO program. Must never panic; `compile` and `validate` must agree. Used by `fuzz/`
/// and by a proptest in kernel/tests.
pub fn fuzz_entry(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    let mut mill = Setup::new(&['X', 'Y', 'Z', 'U']);
    mill.offsets
        .set_entry(
            1,
            crate::offsets::OffsetEntry {
                radius_mm: 5.0,
                length_mm: [0.0, 0.0, 10.0, 0.0],
            },
        )
        .expect("valid entry");
    let mut lathe = Setup::new(&['X', 'Z']);
    lathe.constants.set(325, 20003.0);
    lathe.constants.set(397, 1000.0); // 7.R397 = 1
    lathe.ij = IjMode::Absolute;
    let iso = Setup {
        dialect: Dialect::Iso,
        ..mill.clone()
    };
    for setup in [&mill, &lathe, &iso] {
        let c = compile(&text, setup);
        let v = validate(&text, setup);
        assert_eq!(
            c.diagnostics, v,
            "compile and validate must report the same"
        );
        if !c.has_errors() {
            for (k, b) in c.blocks.iter().enumerate() {
                assert_eq!(b.seq as usize, k, "seq numbers are dense");
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::block::{Feed, Path};

    fn setup() -> Setup {
        Setup::new(&['X', 'Y', 'Z'])
    }

    #[test]
    fn lines_and_rapids() {
        let c = compile(
            "N10 G0 X10 Y5\nN20 G1 X20 F600 ; cut\nN30 G91 Y-5\n",
            &setup(),
        );
        assert!(!c.has_errors(), "{:?}", c.diagnostics);
        assert_eq!(c.blocks.len(), 3);
        let (_, end, path) = c.blocks[2].motion().unwrap();
        assert_eq!(path, Path::Line);
        assert_eq!(&end.0[..3], &[20.0, 0.0, 0.0]);
        assert_eq!(c.blocks[1].feed, Feed::MmPerMin(600.0));
    }

    #[test]
    fn feed_with_decimal_point_is_m_per_min() {
        let c = compile("G1 X1 F1.2", &setup());
        assert_eq!(c.blocks[0].feed, Feed::MmPerMin(1200.0));
    }

    #[test]
    fn unknown_word_and_missing_value_are_located() {
        let c = compile("N10 G1 X1 F100\nN20 Q5\nN30 X\n", &setup());
        assert!(c.blocks.is_empty());
        assert_eq!(c.diagnostics.len(), 2);
        assert_eq!(c.diagnostics[0].block, Some(20));
        assert_eq!((c.diagnostics[0].line, c.diagnostics[0].column), (2, 5));
        assert_eq!(c.diagnostics[0].code, DiagCode::UnknownAddress);
        assert_eq!(c.diagnostics[1].block, Some(30));
        assert_eq!(c.diagnostics[1].code, DiagCode::WordWithoutValue);
    }

    #[test]
    fn m30_ends_the_program_and_stops_the_spindle() {
        let c = compile(
            "N10 S1000 M3\nN20 G1 X1 F100\nN30 M30\nN40 G1 X99\nN50 Q5\n",
            &setup(),
        );
        assert!(!c.has_errors(), "{:?}", c.diagnostics);
        assert_eq!(c.blocks.len(), 3, "nothing after M30 is interpreted");
        assert_eq!(c.blocks[2].spindle.dir, crate::block::SpindleDir::Stopped);
        assert_eq!(c.diagnostics.len(), 1);
        assert_eq!(c.diagnostics[0].block, Some(30));
        assert!(!c.diagnostics[0].is_error());
        let c = compile("N10 G1 X1 F100\nN20 M2\n; done\n", &setup());
        assert_eq!((c.blocks.len(), c.diagnostics.len()), (2, 0));
    }

    #[test]
    fn m0_and_m1_are_program_stops() {
        use crate::block::ProgramStop;
        let c = compile("N10 G1 X1 F100 M1\nN20 M0\nN30 M5\n", &setup());
        let stops: Vec<_> = c.blocks.iter().map(|b| ProgramStop::of(&b.m)).collect();
        assert_eq!(
            stops,
            [
                ProgramStop::Optional,
                ProgramStop::Always,
                ProgramStop::None
            ]
        );
    }

    #[test]
    fn g1_without_feed_is_an_error() {
        let c = compile("N5 G1 X1", &setup());
        assert!(c.has_errors());
        assert_eq!(c.diagnostics[0].block, Some(5));
    }
}
