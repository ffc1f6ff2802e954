//! The ISO / RS274-NGC dialect as LinuxCNC 2.9 reads it (docs/language.md, "ISO programs"):
//! a front-end that produces the same canonical [`Block`]s as the CNC836 dialect, so
//! validation, compensation, planning, preview and restart serve both.
//!
//! Parts: [`ast`] (a parsed line), [`parse`] (text → line), [`expr`] and [`params`]
//! (expressions and `#` parameters), [`state`] (modal state), [`words`] (words into modal
//! groups), [`exec`] (a line in LinuxCNC's order), [`motion`], [`cycles`] and [`flow`]
//! (O-words).

pub mod ast;
mod cycles;
mod exec;
pub mod expr;
mod flow;
mod handover;
mod motion;
pub mod params;
pub mod parse;
mod probe;
mod state;
mod words;

use super::{Lines, Modal, Setup};
use crate::block::Block;
use crate::diag::{DiagCode, Diagnostic};
use crate::units::MAX_AXES;
use std::collections::VecDeque;

/// An error inside a line: byte offset, code and message.
#[derive(Clone, Debug, PartialEq)]
pub struct Fail {
    pub at: usize,
    pub code: DiagCode,
    pub message: String,
}

impl Fail {
    pub fn new(at: usize, code: DiagCode, message: impl ToString) -> Self {
        Fail {
            at,
            code,
            message: message.to_string(),
        }
    }
}

/// The ISO interpreter: modal state, parameters, control flow.
pub struct Interpreter {
    machine: exec::Machine,
    state: state::State,
    params: params::Params,
    flow: flow::Flow,
    /// Blocks of the last line not yet handed out (a cycle line makes several).
    queue: VecDeque<Block>,
    seq: u32,
    notes: Vec<Diagnostic>,
    modal: Modal,
    /// A `%` opened the program: the next `%` ends it.
    percent_open: bool,
    lines_seen: bool,
    ended: bool,
    /// Where the last line found by a skip started (for `continue`).
    last_skipped: Option<flow::Place>,
    /// A setup problem reported before any block.
    setup_error: Option<Diagnostic>,
    buf: String,
    /// The N of the line being run (for its errors).
    last_n: Option<u32>,
    /// The text of a skipped line an error is about (its column is counted there).
    fail_text: Option<String>,
}

impl Interpreter {
    pub fn new(setup: &Setup) -> Self {
        let cnc836 = super::Interpreter::new(setup);
        let mut axis_letters = [0u8; MAX_AXES];
        for (k, a) in setup.axis_names.iter().take(MAX_AXES).enumerate() {
            axis_letters[k] = a.to_ascii_uppercase() as u8;
        }
        let kr_axis = crate::kr::config::controlling_axis_letter(&setup.constants).and_then(|l| {
            setup
                .axis_names
                .iter()
                .take(MAX_AXES)
                .position(|a| a.to_ascii_uppercase() == l)
        });
        let machine = exec::Machine {
            n_axes: setup.axis_names.len().min(MAX_AXES),
            axis_letters,
            table: setup.offsets.clone(),
            m_outputs: setup.m_outputs.clone(),
            arc_tolerance_mm: setup.constants.arc_tolerance_mm(),
            kr_axis,
        };
        let mut interp = Interpreter {
            machine,
            state: state::State::power_on(setup.start, setup.work_offsets),
            params: params::Params::new(),
            flow: flow::Flow::default(),
            queue: VecDeque::new(),
            seq: 0,
            notes: Vec::new(),
            modal: cnc836.modal(),
            percent_open: false,
            lines_seen: false,
            ended: false,
            last_skipped: None,
            setup_error: cnc836.setup_error(),
            buf: String::new(),
            last_n: None,
            fail_text: None,
        };
        if let Some(m) = &setup.modal {
            handover::inherit(&mut interp.state, m);
        }
        interp.modal = handover::modal_of(&interp.state);
        interp.sync_params(true);
        interp
    }

    pub fn take_notes(&mut self) -> Vec<Diagnostic> {
        std::mem::take(&mut self.notes)
    }

    pub fn has_notes(&self) -> bool {
        !self.notes.is_empty()
    }

    /// The modal state after the last block (what an MDI after it inherits).
    pub fn modal(&self) -> Modal {
        self.modal
    }

    /// The next block of the program, reading (and for loops and calls, seeking) `lines`;
    /// `line_no` is the number of the last line read.
    pub fn next<L: Lines>(
        &mut self,
        lines: &mut L,
        line_no: &mut u32,
        block_delete: bool,
    ) -> Option<Result<Block, Diagnostic>> {
        if let Some(e) = self.setup_error.take() {
            self.ended = true;
            return Some(Err(e));
        }
        loop {
            if let Some(b) = self.queue.pop_front() {
                return Some(Ok(b));
            }
            if self.ended {
                return None;
            }
            let here = lines.mark().map(|mark| flow::Place {
                mark,
                line_no: *line_no,
            });
            let text = match lines.next_line(*line_no + 1) {
                None => return self.end_of_text(*line_no),
                Some(Err(d)) => {
                    *line_no += 1;
                    return Some(Err(d));
                }
                Some(Ok(t)) => t,
            };
            *line_no += 1;
            self.buf.clear();
            self.buf
                .push_str(text.strip_prefix('\u{FEFF}').unwrap_or(text));
            let text = std::mem::take(&mut self.buf);
            let r = self.line(&text, lines, line_no, here, block_delete);
            self.buf = text;
            if let Err(f) = r {
                let n = self.last_n;
                let text = self.fail_text.take();
                let col = column(text.as_deref().unwrap_or(&self.buf), f.at);
                return Some(Err(Diagnostic::error(f.code, n, *line_no, col, f.message)));
            }
        }
    }

    /// The text ended: open structures are an error.
    fn end_of_text(&mut self, line_no: u32) -> Option<Result<Block, Diagnostic>> {
        self.ended = true;
        let open = self.flow.frames.last()?;
        let label = match open {
            flow::Frame::Call { label, .. }
            | flow::Frame::While { label, .. }
            | flow::Frame::Do { label, .. }
            | flow::Frame::Repeat { label, .. }
            | flow::Frame::If { label } => flow::show(label),
        };
        Some(Err(Diagnostic::error(
            DiagCode::OWordMismatch,
            None,
            line_no,
            0,
            format!("{label} is not closed before the end of the program"),
        )))
    }

    /// One line: parse, flow control or words.
    fn line<L: Lines>(
        &mut self,
        text: &str,
        lines: &mut L,
        line_no: &mut u32,
        here: Option<flow::Place>,
        block_delete: bool,
    ) -> Result<(), Fail> {
        self.last_n = None;
        if block_delete && text.trim_start_matches([' ', '\t']).starts_with('/') {
            // LinuxCNC does not read a deleted line at all.
            return Ok(());
        }
        let l = parse::line(text)?;
        self.last_n = l.n;
        if l.block_delete && block_delete {
            return Ok(());
        }
        if l.percent {
            // `%` first: the program runs to the next `%` (LinuxCNC).
            if self.percent_open {
                self.ended = true;
            } else if !self.lines_seen {
                self.percent_open = true;
            }
            return Ok(());
        }
        let meaningful = l.oword.is_some() || !l.words.is_empty() || !l.assigns.is_empty();
        self.lines_seen |= meaningful || !l.comments.is_empty();
        self.comments(&l, *line_no);
        if let Some(o) = &l.oword {
            let here = here.ok_or_else(|| {
                Fail::new(
                    o.at,
                    DiagCode::SourceCannotSeek,
                    "loops and calls need a program source that can go back",
                )
            })?;
            return self.oword(o, lines, line_no, here);
        }
        if !meaningful {
            return Ok(());
        }
        self.words_line(&l, *line_no)
    }

    /// Messages and debug comments become notes.
    fn comments(&mut self, l: &ast::Line, line_no: u32) {
        for c in &l.comments {
            let text = match c {
                ast::Comment::Msg(t) => t.clone(),
                ast::Comment::Debug(t) | ast::Comment::Print(t) => {
                    expr::substitute(t, &self.params)
                }
            };
            self.notes.push(Diagnostic::info(
                DiagCode::ProgramMessage,
                l.n,
                line_no,
                0,
                text,
            ));
        }
    }

    /// A line of words: evaluated with the parameters before the line, executed on a copy of
    /// the state, then the assignments, state and blocks committed together.
    fn words_line(&mut self, l: &ast::Line, line_no: u32) -> Result<(), Fail> {
        let w = self.evaluate(l)?;
        let mut x = exec::Exec {
            m: &self.machine,
            st: self.state.clone(),
            out: Vec::new(),
            seq: self.seq,
            line: line_no,
            n: l.n,
            prev_motion: self.state.motion,
        };
        x.run(&w)?;
        let (st, out, seq) = (x.st, x.out, x.seq);
        // All of the line's assignments or none; they read the values from before the line.
        expr::assign(&l.assigns, &mut self.params)?;
        self.state = st;
        self.modal = handover::modal_of(&self.state);
        self.seq = seq;
        let ends = out.iter().any(|b| crate::block::ends_program(&b.m));
        let probe = out
            .iter()
            .rev()
            .find(|b| matches!(b.motion(), Some((_, _, crate::block::Path::Probe(_)))))
            .map(crate::probe::ProbeResult::without_machine_for);
        self.queue.extend(out);
        self.sync_params(w.non_modal.is_some());
        if let Some(r) = probe {
            // Until the machine reports (a pass without one keeps this): as LinuxCNC's rs274.
            self.probe_result(&r);
        }
        if ends {
            self.ended = true;
        }
        Ok(())
    }

    /// The words of a line, evaluated and sorted into their groups.
    fn evaluate(&self, l: &ast::Line) -> Result<words::Words, Fail> {
        let mut w = words::Words {
            first: l.words.first().map_or(0, |x| x.at),
            ..Default::default()
        };
        for word in &l.words {
            let v = expr::eval(&word.value, &self.params, word.at)?;
            match word.letter {
                b'G' => words::g_word(&mut w, words::g_tenths(v, word.at)?, word.at)?,
                b'M' => {
                    let m = words::whole(v, word.at, "M", 999.0)? as u16;
                    let bound = self.machine.m_outputs.get(m).is_some();
                    words::m_word(&mut w, m, word.at, bound)?
                }
                b'N' => {}
                letter => {
                    let axis = self.machine.axis_letters[..self.machine.n_axes]
                        .iter()
                        .position(|&a| a == letter);
                    words::letter(&mut w, letter, v, word.at, axis)?
                }
            }
        }
        Ok(w)
    }

    /// A probing move of the last line ended as `r` reports: #5061.., #5070 and the
    /// position the next line starts from.
    pub fn probe_result(&mut self, r: &crate::probe::ProbeResult) {
        let letters = &self.machine.axis_letters[..self.machine.n_axes];
        for (i, v) in probe::apply_result(&mut self.state, letters, r) {
            self.params.set_numbered(i, v);
        }
        self.modal = handover::modal_of(&self.state);
        self.sync_params(false);
    }

    /// LinuxCNC's system parameters a program may read: #5220 (system), #5221.. (work
    /// offsets), #5211.. (G92), #5400 (tool), #5420.. (position), in the program's units.
    fn sync_params(&mut self, offsets: bool) {
        let st = &self.state;
        let n = self.machine.n_axes;
        let pos = st.program_pos();
        let mut set = Vec::with_capacity(32);
        for k in 0..n.min(6) {
            set.push((5420 + k, st.units(pos[k])));
            set.push((5211 + k, st.units(st.g92_mm[k])));
        }
        set.push((5220, (st.system + 1) as f64));
        set.push((5400, f64::from(st.tool)));
        if offsets {
            for s in 0..crate::offsets::work::SYSTEMS {
                for k in 0..n.min(6) {
                    set.push((5221 + 20 * s + k, st.units(st.work.systems[s][k])));
                }
            }
        }
        for (i, v) in set {
            self.params.set_numbered(i, v);
        }
    }
}

/// Column (1-based, in characters) of byte offset `at` in `text`.
fn column(text: &str, at: usize) -> u32 {
    let at = at.min(text.len());
    let at = (0..=at)
        .rev()
        .find(|&k| text.is_char_boundary(k))
        .unwrap_or(0);
    text[..at].chars().count() as u32 + 1
}
