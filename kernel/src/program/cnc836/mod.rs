//! The CNC836 / CNC8x9 dialect (SPEC §2, §3, §5; docs/language.md): words of one block + modal
//! state → one canonical block.
//!
//! Each block is handled in two steps: the words are collected and checked, then the new modal
//! state is computed into a copy. Only when nothing is wrong is the copy committed, so a bad
//! block never changes state half-way.
//!
//! Parts, one concept each: [`words`] (the lexer), `collect` (the words of a block, the G
//! word table), `modal` (modal state, the rules read from the constants), `spindle` (M
//! functions, feed and speed), `table` (G92 table writes, D, &), `comp` (compensation checks),
//! `motion` (positions and the motion of a block), `circle` (arcs: centre, R55, R325),
//! `dwell` (G4), `subprogram` (the forms `%L<n>`, `L<n> P<count>`, M17) and [`flow`] (running
//! them: calls, repeats and returns over the program's lines).

mod circle;
mod collect;
mod comp;
mod dwell;
pub(crate) mod flow;
mod modal;
mod motion;
mod spindle;
mod subprogram;
mod table;
mod tool;
pub mod words;

pub use modal::{Modal, ModalParts, Motion};

use self::circle::check_arc_words;
use self::collect::Words;
use self::modal::{Rules, State, apply_simple_modals, dynamic_set, plane};
use self::motion::Outcome;
use self::words::{LexError, MAX_PARAM, Num};
use super::Setup;
use super::arc::Refined;
use crate::block::{Block, BlockKind, Comp, Feed, MCodes, Path};
use crate::diag::{DiagCode, Diagnostic};
use crate::offsets::{OffsetTable, TableEdit};
use crate::units::MAX_AXES;

/// Letters the language uses for other things; an axis may not be named by one of them.
pub const RESERVED_LETTERS: &str = "NGIJEFSMDRLP";

/// A subprogram form of a line, for [`flow`] to act on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Control {
    /// `%L<n>`: subprogram n starts on the next line.
    Label(u16),
    /// `L<label> P<count>` in block N `n`: run subprogram `label` `count` times, then go on
    /// after this line.
    Call {
        label: u16,
        count: u16,
        n: Option<u32>,
    },
    /// M17: the end of a subprogram.
    Return,
}

/// An error inside a block: byte offset in the line, code and message.
struct Fail {
    at: usize,
    code: DiagCode,
    message: String,
}

impl Fail {
    fn new(at: usize, code: DiagCode, message: impl ToString) -> Self {
        Fail {
            at,
            code,
            message: message.to_string(),
        }
    }
}

fn fail<T>(at: usize, code: DiagCode, message: impl ToString) -> Result<T, Fail> {
    Err(Fail::new(at, code, message))
}

impl From<LexError> for Fail {
    fn from(e: LexError) -> Self {
        Fail {
            at: e.at,
            code: e.code,
            message: e.message,
        }
    }
}

/// Modal state and position, advanced block by block.
pub struct Interpreter {
    axis_letters: [u8; MAX_AXES],
    n_axes: usize,
    rules: Rules,
    table: OffsetTable,
    state: State,
    params: [Option<Num>; MAX_PARAM as usize + 1],
    seq: u32,
    notes: Vec<Diagnostic>,
    /// R325 refinements of committed blocks, kept only when asked for (see
    /// [`Interpreter::record_refinements`]): a streaming run never grows.
    refinements: Option<Vec<Refined>>,
    setup_error: Option<String>,
    /// Index of the controlling axis R67 among the program's axes, for the length offset that
    /// rides with the spindle state (KŘR at the tool tip, SPEC §6); `None`: R67 names no axis
    /// of this machine (the daemon refuses such constants when KŘR is configured).
    kr_axis: Option<usize>,
    /// The spindle gear table (empty: M41..M44 select ranges 1..4), SPEC §6.
    gears: Vec<crate::kr::Gear>,
    /// M functions bound to the machine's outputs and inputs (docs/io.md).
    m_outputs: crate::outputs::MFunctions,
    /// The axis programmed as a diameter ([`Setup::diameter_axis`]): its words are halved.
    diameter_axis: Option<usize>,
    /// Thousands of encoder pulses per revolution of rotary axes, 0 for linear ones.
    rotary_kppr: [f64; MAX_AXES],
    /// Fastest path feed of the machine, mm/min (0 = unknown), for the βmax warning (SPEC §5).
    max_feed_mm_min: f64,
    /// The subprogram form of the last line read ([`Self::take_control`]).
    control: Option<Control>,
}

impl Interpreter {
    /// What the interpreter decoded from the constants (the check that every constant read is
    /// in `kernel::machine::CONSTANTS_READ`).
    #[cfg(test)]
    pub(crate) fn decoded_rules(&self) -> String {
        format!("{:?} {:?}", self.rules, self.kr_axis)
    }

    pub fn new(setup: &Setup) -> Self {
        let c = &setup.constants;
        let (axis_letters, setup_error) = axis_letters(&setup.axis_names);
        let kr_axis = crate::kr::config::controlling_axis_letter(c).and_then(|l| {
            setup
                .axis_names
                .iter()
                .take(MAX_AXES)
                .position(|a| a.to_ascii_uppercase() == l)
        });
        let mut interp = Interpreter {
            kr_axis,
            gears: setup.gears.clone(),
            m_outputs: setup.m_outputs.clone(),
            diameter_axis: setup.diameter_axis.filter(|&k| k < setup.axis_names.len()),
            rotary_kppr: setup.rotary_kpulses_per_rev,
            max_feed_mm_min: setup.max_feed_mm_min,
            axis_letters,
            n_axes: setup.axis_names.len().min(MAX_AXES),
            rules: Rules::of(setup),
            table: setup.offsets.clone(),
            state: State::power_on(setup.start),
            params: [None; MAX_PARAM as usize + 1],
            seq: 0,
            notes: Vec::new(),
            refinements: None,
            setup_error,
            control: None,
        };
        if let Some(m) = &setup.modal {
            interp.state.inherit(m);
        }
        interp
    }

    /// A problem with the setup itself (axis names); reported once, before any block.
    pub fn setup_error(&self) -> Option<Diagnostic> {
        self.setup_error
            .as_ref()
            .map(|m| Diagnostic::error(DiagCode::AxisNamesInvalid, None, 0, 0, m.clone()))
    }

    /// Warnings and information produced since the last call (arc replaced by a line, ...).
    /// Keep every R325 refinement for [`Interpreter::take_refinements`] (listings).
    pub fn record_refinements(&mut self) {
        self.refinements.get_or_insert_with(Vec::new);
    }

    /// R325 refinements recorded so far (empty unless recording).
    pub fn take_refinements(&mut self) -> Vec<Refined> {
        self.refinements
            .as_mut()
            .map(std::mem::take)
            .unwrap_or_default()
    }

    pub(crate) fn note(&mut self, d: Diagnostic) {
        self.notes.push(d);
    }

    pub fn take_notes(&mut self) -> Vec<Diagnostic> {
        std::mem::take(&mut self.notes)
    }

    /// Whether notes are waiting (cheap check for the streaming loop).
    pub fn has_notes(&self) -> bool {
        !self.notes.is_empty()
    }

    /// The modal state after the last block (what an MDI after it inherits).
    pub fn modal(&self) -> Modal {
        self.state.modal
    }

    /// The interpreter's copy of the offset table (including `G92` writes so far).
    pub fn table(&self) -> &OffsetTable {
        &self.table
    }

    /// Value of program parameter `R<index>` as assigned so far.
    pub fn param(&self, index: u8) -> Option<f64> {
        self.params
            .get(index as usize)
            .copied()
            .flatten()
            .map(|n| n.value)
    }

    /// Interprets one source line. Returns the canonical block it makes, if any (empty and
    /// remark-only lines make none). On error the modal state is unchanged. The subprogram
    /// forms (`%L<n>`, `L<n>`, M17) need the program's lines: they are run by [`super::stream`]
    /// and refused here.
    pub fn line(&mut self, line_no: u32, text: &str) -> Result<Option<Block>, Diagnostic> {
        let block = self.read_line(line_no, text)?;
        if self.control.take().is_some() {
            return Err(Diagnostic::error(
                DiagCode::SourceCannotSeek,
                None,
                line_no,
                1,
                "subprograms (%L, L, M17) run only in a whole program, not line by line",
            ));
        }
        Ok(block)
    }

    /// As [`Self::line`]; a subprogram form makes no block and is left for
    /// [`Self::take_control`]. (A block is returned as before, not wrapped with the forms:
    /// this is the path of every block.)
    pub(crate) fn read_line(
        &mut self,
        line_no: u32,
        text: &str,
    ) -> Result<Option<Block>, Diagnostic> {
        if let Some(label) = subprogram::label_line(text) {
            let label = label.map_err(|f| {
                Diagnostic::error(f.code, None, line_no, column(text, f.at), f.message)
            })?;
            self.control = Some(Control::Label(label));
            return Ok(None);
        }
        let mut w = Words::default();
        let located = |n: Option<u32>, f: Fail| {
            Diagnostic::error(f.code, n, line_no, column(text, f.at), f.message)
        };
        if let Err(f) = self.collect(text, &mut w) {
            return Err(located(w.n, f));
        }
        if !w.any {
            return Ok(None);
        }
        match subprogram::form(&w, text) {
            Ok(None) => {}
            Ok(Some(c)) => {
                self.control = Some(c);
                return Ok(None);
            }
            Err(f) => return Err(located(w.n, f)),
        }
        if w.g4.is_some() {
            return self
                .dwell(&w, line_no, text)
                .map(Some)
                .map_err(|f| located(w.n, f));
        }
        match self.interpret(&w, line_no, text) {
            Ok(b) => Ok(Some(b)),
            Err(f) => Err(located(w.n, f)),
        }
    }

    /// The subprogram form of the last line read, if it was one.
    pub(crate) fn take_control(&mut self) -> Option<Control> {
        self.control.take()
    }

    /// One block, in the order the modal groups depend on each other: the simple modal words,
    /// dynamic set, plane, M functions, feed and S, G92/D/&, compensation, positions, then the
    /// block's kind (motion checks). Every step works on the copy `st`; [`Self::commit`] is the
    /// only one that changes the interpreter.
    fn interpret(&mut self, w: &Words, line_no: u32, text: &str) -> Result<Block, Fail> {
        let old = self.state;
        let mut st = old;
        apply_simple_modals(w, &mut st);
        let motion_words = w.axes[..self.n_axes].iter().any(Option::is_some);
        let arc_block = st.modal.motion.is_arc() && w.g92.is_none();
        let i_is_centre = dynamic_set(w, &mut st, arc_block, motion_words)?;
        plane(w, &old, &mut st)?;
        let m_codes = self.m_functions(w, &mut st)?;
        let per_rev = self.feed_and_speed(w, &old, &mut st)?;
        let edit = self.table_write_or_d(w, &mut st, line_no, text)?;
        if let Some((a, _)) = w.amp {
            st.amp = a;
        }
        let tool_change = tool::tool_change(w, &old, &mut st, motion_words)?;
        let comp = self.compensation(w, &old, &mut st, edit.as_ref(), arc_block, motion_words)?;
        let offset = self.positions(w, &old, &mut st, edit.as_ref());
        let start = old.machine;
        let end = st.prog + offset;
        check_arc_words(w, arc_block, i_is_centre)?;
        let moves =
            motion_words || (arc_block && ((w.i.is_some() && i_is_centre) || w.j.is_some()));
        let mut out = Outcome {
            kind: BlockKind::Technology,
            warn: None,
            refined: None,
        };
        if let Some(ed) = edit {
            out.kind = BlockKind::TableWrite {
                entry: ed.entry,
                values: ed.values,
            };
        } else if let Some(tool) = tool_change {
            out.kind = BlockKind::ToolChange { tool };
        } else if moves {
            out = self.motion(w, &st, &old, (start, end, offset), arc_block, per_rev)?;
        }
        let checked = Checked {
            st,
            edit,
            comp,
            m_codes,
            out,
        };
        Ok(self.commit(w, line_no, text, checked))
    }

    /// Everything checked: the block's feed, the table write, the parameters, the notes and
    /// the new modal state take effect together.
    // Inlined into `interpret` (its only caller): the block is then built in place, not
    // copied out (the parse bench lost ~10 % without it).
    #[inline(always)]
    fn commit(&mut self, w: &Words, line_no: u32, text: &str, checked: Checked) -> Block {
        let Checked {
            mut st,
            edit,
            comp,
            m_codes,
            out,
        } = checked;
        let kind = out.kind;
        let mut feed_out = st.modal.feed.unwrap_or_default();
        if st.modal.m37 {
            feed_out = match feed_out {
                Feed::MmPerMin(f) => Feed::MmPerMin(f / 100.0),
                Feed::MmPerRev(f) => Feed::MmPerRev(f / 100.0),
            };
        }
        if let BlockKind::Motion { start, end, .. } = kind {
            feed_out = self.rotary_feed(feed_out, start, end);
        }
        if let Some(ed) = &edit {
            self.table
                .apply(ed)
                .expect("G92 values were checked before the commit");
        }
        for (index, num) in w.assigns.iter().flatten() {
            self.params[*index as usize] = Some(*num);
        }
        if let Some((at, msg)) = out.warn {
            self.notes.push(Diagnostic::warning(
                DiagCode::ArcReplacedByLine,
                w.n,
                line_no,
                column(text, at),
                msg,
            ));
        }
        if let (BlockKind::Motion { path, .. }, Feed::MmPerRev(beta)) = (kind, feed_out)
            && path != Path::Rapid
            && let Some(msg) = self.beta_max_warning(beta, &st.modal.spindle)
        {
            self.notes.push(Diagnostic::warning(
                DiagCode::FeedAboveBetaMax,
                w.n,
                line_no,
                column(text, w.first),
                msg,
            ));
        }
        if let Some(r) = out.refined {
            self.note_refinement(w, line_no, r);
        }
        if let BlockKind::Motion { end, .. } = kind {
            st.machine = end;
        }
        self.state = st;
        let block = Block {
            seq: self.seq,
            n: w.n,
            line: line_no,
            kind,
            feed: feed_out,
            plane: st.modal.plane,
            comp,
            continuity: st.modal.continuity,
            dyn_set: st.modal.dyn_set,
            spindle: st.modal.spindle,
            m: m_codes,
        };
        self.seq += 1;
        block
    }
}

/// A block that passed every check: the new modal state and what the commit applies.
struct Checked {
    st: State,
    edit: Option<TableEdit>,
    comp: Comp,
    m_codes: MCodes,
    out: Outcome,
}

/// The machine's axis letters (upper case) and, if they cannot be used, why.
fn axis_letters(names: &[char]) -> ([u8; MAX_AXES], Option<String>) {
    let mut letters = [0u8; MAX_AXES];
    let mut error = None;
    if names.is_empty() || names.len() > MAX_AXES {
        error = Some(format!(
            "the machine must have 1..{MAX_AXES} axes, not {}",
            names.len()
        ));
    }
    for (k, &a) in names.iter().take(MAX_AXES).enumerate() {
        let up = a.to_ascii_uppercase();
        if !up.is_ascii_alphabetic() || RESERVED_LETTERS.contains(up) {
            error = Some(format!(
                "axis name '{a}' cannot be used: axes are letters other than {RESERVED_LETTERS}"
            ));
        } else if names[..k].iter().any(|b| b.to_ascii_uppercase() == up) {
            error = Some(format!("axis name '{a}' is configured twice"));
        }
        letters[k] = up as u8;
    }
    (letters, error)
}

/// 1-based character column of byte offset `at` in `text`.
pub(crate) fn column(text: &str, at: usize) -> u32 {
    let at = at.min(text.len());
    let at = (0..=at)
        .rev()
        .find(|&i| text.is_char_boundary(i))
        .unwrap_or(0);
    text[..at].chars().count() as u32 + 1
}
