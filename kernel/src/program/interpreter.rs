//! The interpreter: words of one block + modal state → one canonical block (SPEC §2, §3, §5).
//!
//! Each block is handled in two steps: the words are collected and checked, then the new modal
//! state is computed into a copy. Only when nothing is wrong is the copy committed, so a bad
//! block never changes state half-way.

use super::arc::{self, Corrected, ERefinement, Refined};
use super::feed::{self, FeedMode};
use super::words::{LexError, Lexer, MAX_PARAM, Num, Token, Value};
use super::{IjMode, Setup};
use crate::block::{
    ArcDir, Block, BlockKind, Comp, Continuity, Feed, MCodes, Path, Plane, Spindle, SpindleDir,
};
use crate::constants::Refinement;
use crate::diag::{DiagCode, Diagnostic};
use crate::offsets::{self, OffsetTable, TableEdit};
use crate::units::{AxesMm, MAX_AXES};

/// Letters the language uses for other things; an axis may not be named by one of them.
pub const RESERVED_LETTERS: &str = "NGIJEFSMDR";

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Motion {
    Rapid,
    Line,
    Cw,
    Ccw,
}

impl Motion {
    fn is_arc(self) -> bool {
        matches!(self, Motion::Cw | Motion::Ccw)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum CompMode {
    Off,
    Left,
    Right,
}

/// Rules taken from the machine constants once, when the interpreter is made.
#[derive(Clone, Copy, Debug)]
struct Rules {
    arc_tolerance_mm: f64,
    bad_arc_becomes_line: bool,
    side_switch_allowed: bool,
    g40_without_motion: bool,
    refinement: Refinement,
    css_swapped: bool,
    ij: IjMode,
}

/// Modal state: small and `Copy`, so a block works on a copy and commits it whole.
#[derive(Clone, Copy, Debug)]
struct State {
    /// Programmed position (program coordinates, without length offset).
    prog: AxesMm,
    /// Where the last motion ended, in machine coordinates (programmed + length offset).
    machine: AxesMm,
    /// What the next MDI inherits.
    modal: Modal,
    comp: CompMode,
    /// Offset entry selected by D (0 = none).
    d: u8,
    /// Length offset entry selected by & (0 = none).
    amp: u8,
}

/// The modal state a program or MDI leaves for the next MDI (docs/language.md, "What MDI
/// inherits"): motion, plane, G90/G91, G94/G95, feed, M37, continuity, dynamic set and the
/// spindle (direction, S, gear, KŘR). Compensation, D and & offsets and the R parameters are
/// not inherited: they end with the program.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Modal {
    motion: Motion,
    plane: Plane,
    absolute: bool,
    feed_mode: FeedMode,
    /// Programmed feed (before M37 scaling); `None` until F is written, or after the feed
    /// changed between per minute and per revolution.
    feed: Option<Feed>,
    /// M37: actual feed = programmed / 100 (SPEC §5).
    m37: bool,
    continuity: Continuity,
    dyn_set: u8,
    spindle: Spindle,
    /// The spindle speed is known at run time although S is 0: after constant cutting speed
    /// ends, the last reached speed becomes S (SPEC §6).
    speed_from_css: bool,
}

impl Modal {
    /// The spindle state in force.
    pub fn spindle(&self) -> Spindle {
        self.spindle
    }

    /// G91 (incremental) is in force.
    pub fn incremental(&self) -> bool {
        !self.absolute
    }

    /// The programmed feed in force, if any.
    pub fn feed(&self) -> Option<Feed> {
        self.feed
    }
}

impl Rules {
    fn of(setup: &Setup) -> Self {
        let c = &setup.constants;
        Rules {
            arc_tolerance_mm: c.arc_tolerance_mm(),
            bad_arc_becomes_line: c.bad_arc_becomes_line(),
            side_switch_allowed: c.comp_side_switch_allowed(),
            g40_without_motion: c.g40_without_motion_allowed(),
            refinement: if setup.preprocessor {
                c.refinement()
            } else {
                Refinement::Off
            },
            css_swapped: c.css_g96_g97_swapped(),
            ij: setup.ij,
        }
    }
}

impl State {
    /// The power-on modal state at position `start`.
    fn power_on(start: AxesMm) -> Self {
        State {
            prog: start,
            machine: start,
            modal: Modal {
                motion: Motion::Rapid,
                plane: Plane::G17,
                absolute: true,
                feed_mode: FeedMode::G94,
                feed: None,
                m37: false,
                continuity: Continuity::G98,
                dyn_set: 1,
                spindle: Spindle::default(),
                speed_from_css: false,
            },
            comp: CompMode::Off,
            d: 0,
            amp: 0,
        }
    }

    fn inherit(&mut self, m: &Modal) {
        self.modal = *m;
        // Offsets are not inherited: the spindle's length offset for KŘR goes with them.
        self.modal.spindle.length_offset_mm = 0.0;
    }
}

/// The words of one block, collected before anything is interpreted.
#[derive(Default)]
struct Words {
    n: Option<u32>,
    motion: Option<(Motion, usize)>,
    plane: Option<(Plane, usize)>,
    continuity: Option<(Continuity, usize)>,
    comp: Option<(CompMode, usize)>,
    absolute: Option<(bool, usize)>,
    feed_mode: Option<(FeedMode, usize)>,
    g76: Option<usize>,
    g92: Option<usize>,
    axes: [Option<(f64, usize)>; MAX_AXES],
    i: Option<(Num, usize)>,
    j: Option<(Num, usize)>,
    e: Option<(Num, usize)>,
    f: Option<(Num, usize)>,
    s: Option<(Num, usize)>,
    d: Option<(u8, usize)>,
    amp: Option<(u8, usize)>,
    m: [Option<(u16, usize)>; 4],
    assigns: [Option<(u8, Num)>; 16],
    first: usize,
    any: bool,
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
    /// remark-only lines make none). On error the modal state is unchanged.
    pub fn line(&mut self, line_no: u32, text: &str) -> Result<Option<Block>, Diagnostic> {
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
        match self.interpret(&w, line_no, text) {
            Ok(b) => Ok(Some(b)),
            Err(f) => Err(located(w.n, f)),
        }
    }

    /// Looks up a parameter: assignments earlier in this block first, then the committed table.
    fn param_value(&self, w: &Words, index: u8, negate: bool, at: usize) -> Result<Num, Fail> {
        let pending = w
            .assigns
            .iter()
            .rev()
            .flatten()
            .find(|(i, _)| *i == index)
            .map(|(_, n)| *n);
        match pending.or(self.params[index as usize]) {
            Some(n) => Ok(Num {
                value: if negate { -n.value } else { n.value },
                point: n.point,
            }),
            None => fail(
                at,
                DiagCode::ParamUnassigned,
                format!("parameter R{index} is used before it was assigned"),
            ),
        }
    }

    /// Lexes the line into `w`, checking each word on its own.
    fn collect(&self, text: &str, w: &mut Words) -> Result<(), Fail> {
        for (k, lexed) in Lexer::new(text).enumerate() {
            let lexed = lexed?;
            let at = lexed.at;
            if k == 0 {
                w.first = at;
            }
            w.any = true;
            match lexed.token {
                Token::Assign { index, value } => {
                    let num = self.resolve(w, value, at)?;
                    let Some(slot) = w.assigns.iter_mut().find(|s| s.is_none()) else {
                        return fail(
                            at,
                            DiagCode::TooManyAssignments,
                            "more than 16 parameter assignments in one block",
                        );
                    };
                    *slot = Some((index, num));
                }
                Token::Word { letter, value } => {
                    let num = self.resolve(w, value, at)?;
                    self.word(w, letter, num, at, k == 0)?;
                }
            }
        }
        Ok(())
    }

    fn resolve(&self, w: &Words, value: Value, at: usize) -> Result<Num, Fail> {
        match value {
            Value::Num(n) => Ok(n),
            Value::Param { index, negate } => self.param_value(w, index, negate, at),
        }
    }

    fn word(
        &self,
        w: &mut Words,
        letter: u8,
        num: Num,
        at: usize,
        first: bool,
    ) -> Result<(), Fail> {
        fn once<T>(slot: &mut Option<(T, usize)>, v: T, at: usize, what: &str) -> Result<(), Fail> {
            put_once(slot, v, at, || {
                let message = format!("{what} is written twice in this block");
                (DiagCode::WordTwice, message)
            })
        }
        if let Some(ax) = self.axis_letters[..self.n_axes]
            .iter()
            .position(|&a| a == letter)
        {
            return once(
                &mut w.axes[ax],
                num.value,
                at,
                &format!("axis {}", letter as char),
            );
        }
        match letter {
            b'N' => {
                if !first {
                    return fail(
                        at,
                        DiagCode::BlockNumberNotFirst,
                        "the block number N must be the first word of the block",
                    );
                }
                w.n = Some(int(num, "N", 0, 999_999).map_err(|e| Fail::new(at, e.code(), e))?);
            }
            b'G' => self.g_word(w, num, at)?,
            b'I' => once(&mut w.i, num, at, "I")?,
            b'J' => once(&mut w.j, num, at, "J")?,
            b'E' => once(&mut w.e, num, at, "E")?,
            b'F' => once(&mut w.f, num, at, "F")?,
            b'S' => once(&mut w.s, num, at, "S")?,
            b'D' => {
                let d = int(num, "D", 0, 99).map_err(|e| Fail::new(at, e.code(), e))?;
                once(&mut w.d, d as u8, at, "D")?
            }
            b'&' => {
                let d = int(num, "&", 0, 99).map_err(|e| Fail::new(at, e.code(), e))?;
                once(&mut w.amp, d as u8, at, "&")?
            }
            b'M' => {
                let m = int(num, "M", 0, 999).map_err(|e| Fail::new(at, e.code(), e))? as u16;
                let Some(slot) = w.m.iter_mut().find(|s| s.is_none()) else {
                    return fail(
                        at,
                        DiagCode::TooManyMFunctions,
                        "more than 4 M functions in one block",
                    );
                };
                *slot = Some((m, at));
            }
            _ => {
                return fail(
                    at,
                    DiagCode::UnknownAddress,
                    format!("unknown address {}", letter as char),
                );
            }
        }
        Ok(())
    }

    // A match over the dialect's G words: it reads better whole than split.
    fn g_word(&self, w: &mut Words, num: Num, at: usize) -> Result<(), Fail> {
        const MOTION: &str = "motion (G0..G3)";
        const PLANE: &str = "plane (G17..G19)";
        const CONTINUITY: &str = "continuity (G23/G24/G98)";
        const COMP: &str = "radius compensation (G40..G42)";
        const DISTANCE: &str = "G90/G91";
        const FEED: &str = "feed (G94..G97)";
        let g = int(num, "G", 0, 999).map_err(|e| Fail::new(at, e.code(), e))?;
        match g {
            0 => group(&mut w.motion, Motion::Rapid, at, MOTION),
            1 => group(&mut w.motion, Motion::Line, at, MOTION),
            2 => group(&mut w.motion, Motion::Cw, at, MOTION),
            3 => group(&mut w.motion, Motion::Ccw, at, MOTION),
            17..=19 => {
                let p = [Plane::G17, Plane::G18, Plane::G19][g as usize - 17];
                let (a, b) = p.axes();
                if a >= self.n_axes || b >= self.n_axes {
                    return fail(
                        at,
                        DiagCode::PlaneNeedsAxis,
                        format!("G{g} needs a third axis; this machine has {}", self.n_axes),
                    );
                }
                group(&mut w.plane, p, at, PLANE)
            }
            23 => group(&mut w.continuity, Continuity::G23, at, CONTINUITY),
            24 => group(&mut w.continuity, Continuity::G24, at, CONTINUITY),
            98 => group(&mut w.continuity, Continuity::G98, at, CONTINUITY),
            40 => group(&mut w.comp, CompMode::Off, at, COMP),
            41 => group(&mut w.comp, CompMode::Left, at, COMP),
            42 => group(&mut w.comp, CompMode::Right, at, COMP),
            90 => group(&mut w.absolute, true, at, DISTANCE),
            91 => group(&mut w.absolute, false, at, DISTANCE),
            94 => group(&mut w.feed_mode, FeedMode::G94, at, FEED),
            95 => group(&mut w.feed_mode, FeedMode::G95, at, FEED),
            96 => group(&mut w.feed_mode, FeedMode::G96, at, FEED),
            97 => group(&mut w.feed_mode, FeedMode::G97, at, FEED),
            76 => {
                if w.g76.is_some() {
                    return fail(
                        at,
                        DiagCode::WordTwice,
                        "G76 is written twice in this block",
                    );
                }
                w.g76 = Some(at);
                Ok(())
            }
            92 => {
                if w.g92.is_some() {
                    return fail(
                        at,
                        DiagCode::WordTwice,
                        "G92 is written twice in this block",
                    );
                }
                w.g92 = Some(at);
                Ok(())
            }
            4 => fail(
                at,
                DiagCode::DwellNotSupported,
                "G4 (dwell) is not a function of this controller's dialect",
            ),
            _ => fail(
                at,
                DiagCode::UnknownGFunction,
                format!("G{g} is not a function of this controller"),
            ),
        }
    }

    /// Length offsets of entry `amp` for axes 1..4 (0 = none).
    fn length_offset(&self, amp: u8, edit: Option<&TableEdit>) -> AxesMm {
        let mut off = AxesMm::ZERO;
        if let Some(e) = self.table.entry(amp) {
            for k in 0..4.min(self.n_axes) {
                off[k] = e.length_mm[k];
            }
            if let Some(ed) = edit.filter(|ed| ed.entry == amp) {
                for k in 0..4.min(self.n_axes) {
                    if let Some(v) = ed.values[k + 1] {
                        off[k] = v;
                    }
                }
            }
        }
        // TAB0.KOR holds the diameter axis's length as a diameter (measured the way the
        // machinist reads the part); the tool tip moves by half of it.
        if let Some(k) = self.diameter_axis {
            off[k] = self.to_radius(k, off[k]);
        }
        off
    }

    /// A value of axis `k` in program units → internal (radius) units.
    fn to_radius(&self, k: usize, v: f64) -> f64 {
        if self.diameter_axis == Some(k) {
            v / 2.0
        } else {
            v
        }
    }

    /// Radius of entry `d`, seeing a `G92` write of the same block.
    fn radius_of(&self, d: u8, edit: Option<&TableEdit>) -> Option<f64> {
        let e = self.table.entry(d)?;
        Some(
            edit.filter(|ed| ed.entry == d)
                .and_then(|ed| ed.values[0])
                .unwrap_or(e.radius_mm),
        )
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

    /// M functions: spindle direction, feed scale, gear range (one of each per block).
    fn m_functions(&self, w: &Words, st: &mut State) -> Result<MCodes, Fail> {
        let mut m_codes: MCodes = [None; 4];
        let (mut dir_at, mut scale_at, mut gear_at) = (None, None, None);
        st.modal.spindle.outputs = st.modal.spindle.outputs.carried();
        for (k, (m, at)) in w.m.iter().flatten().enumerate() {
            m_codes[k] = Some(*m);
            if self.m_outputs.apply(*m, &mut st.modal.spindle.outputs) {
                continue;
            }
            let gear = crate::kr::config::gear_for_m_code(&self.gears, *m);
            let (slot, what) = match m {
                3..=5 => (&mut dir_at, "spindle direction (M3/M4/M5)"),
                36 | 37 => (&mut scale_at, "feed scale (M36/M37)"),
                _ if gear.is_some() => (&mut gear_at, "gear range"),
                41..=44 => {
                    return fail(
                        *at,
                        DiagCode::GearNotConfigured,
                        format!(
                            "M{m} selects no gear range: the machine's [kr.gears] table has no \
                             range with m_code = {m}"
                        ),
                    );
                }
                _ => continue,
            };
            if slot.is_some() {
                return fail(
                    *at,
                    DiagCode::MGroupConflict,
                    format!("two M functions for the {what} in one block"),
                );
            }
            *slot = Some(*m);
            match m {
                3 => st.modal.spindle.dir = SpindleDir::Cw,
                4 => st.modal.spindle.dir = SpindleDir::Ccw,
                5 => st.modal.spindle.dir = SpindleDir::Stopped,
                36 => st.modal.m37 = false,
                37 => st.modal.m37 = true,
                _ => st.modal.spindle.gear = gear.unwrap_or(0),
            }
        }
        if crate::block::ends_program(&m_codes) {
            // M2/M30 end the program: the spindle stops with it (the next run starts from the
            // power-on modal state anyway, docs/language.md).
            st.modal.spindle.dir = SpindleDir::Stopped;
            // … and so do the outputs it switched on (LinuxCNC: M2/M30 switch coolant off).
            st.modal.spindle.outputs.on = 0;
        }
        // P of the range in force (gear 0, none selected yet, is range 1), for feed per rev.
        st.modal.spindle.gear_max_rpm = self
            .gears
            .get(usize::from(st.modal.spindle.gear.max(1)) - 1)
            .map_or(0.0, |g| g.max_rpm);
        Ok(m_codes)
    }

    /// Feed group, F, and S / G76 S / constant cutting speed (SPEC §5, §6). Returns whether
    /// the feed is per revolution.
    fn feed_and_speed(&self, w: &Words, old: &State, st: &mut State) -> Result<bool, Fail> {
        let css_swapped = self.rules.css_swapped;
        if let Some((fm, _)) = w.feed_mode {
            st.modal.feed_mode = fm;
        }
        let per_rev = st.modal.feed_mode.per_rev(css_swapped);
        if per_rev != old.modal.feed_mode.per_rev(css_swapped) {
            // F is not carried over between per minute and per revolution (seed 002 §6.1).
            st.modal.feed = None;
        }
        if let Some((f, at)) = w.f {
            st.modal.feed =
                Some(feed::convert(f, per_rev).map_err(|e| Fail::new(at, e.code(), e))?);
        }
        st.modal.spindle.css = st.modal.feed_mode.css();
        if let Some(at) = w.g76 {
            let Some((s, s_at)) = w.s else {
                return fail(
                    at,
                    DiagCode::G76NeedsS,
                    "G76 needs S: the spindle speed limit in rpm (G76 S2000)",
                );
            };
            if s.value < 0.0 {
                return fail(
                    s_at,
                    DiagCode::NegativeSpeed,
                    "the spindle speed limit cannot be negative",
                );
            }
            st.modal.spindle.limit_rpm = s.value;
        } else if let Some((s, at)) = w.s {
            if s.value < 0.0 {
                return fail(at, DiagCode::NegativeSpeed, "S cannot be negative");
            }
            st.modal.spindle.s = s.value;
            st.modal.speed_from_css = false;
        } else if old.modal.spindle.css && !st.modal.spindle.css {
            // KŘR ends without S: the last reached speed becomes S, known only at run time.
            st.modal.spindle.s = 0.0;
            st.modal.speed_from_css = true;
        }
        Ok(per_rev)
    }

    /// G92 D<n> R0..R4: the table write the block makes (SPEC §3 (c)); without G92, D selects
    /// the offset entry.
    fn table_write_or_d(
        &mut self,
        w: &Words,
        st: &mut State,
        line_no: u32,
        text: &str,
    ) -> Result<Option<TableEdit>, Fail> {
        let Some(at) = w.g92 else {
            if let Some((d, _)) = w.d {
                st.d = d;
            }
            return Ok(None);
        };
        if let Some(ax) = w.axes.iter().flatten().next() {
            return fail(
                ax.1,
                DiagCode::G92WithMotion,
                "G92 fills the offset table; it cannot be in a block with axis motion",
            );
        }
        let Some((entry, d_at)) = w.d else {
            return fail(
                at,
                DiagCode::G92NeedsEntry,
                "G92 needs D<entry> (01..99): the offset entry to fill",
            );
        };
        if entry == 0 {
            return fail(
                d_at,
                DiagCode::G92NeedsEntry,
                "G92 D0: offset entries are 01..99",
            );
        }
        let mut values = [None; 5];
        for (index, num) in w.assigns.iter().flatten() {
            if (*index as usize) < 5 {
                if !num.value.is_finite() || num.value.abs() > offsets::MAX_VALUE_MM {
                    return fail(
                        at,
                        DiagCode::OffsetValueOutOfRange,
                        format!(
                            "R{index}={} is outside ±{} mm",
                            num.value,
                            offsets::MAX_VALUE_MM
                        ),
                    );
                }
                values[*index as usize] = Some(num.value);
            }
        }
        if values.iter().all(Option::is_none) {
            self.notes.push(Diagnostic::warning(
                DiagCode::G92WritesNothing,
                w.n,
                line_no,
                column(text, at),
                format!(
                    "G92 D{entry} writes nothing: program R0 (radius) .. R4 (lengths) in the block"
                ),
            ));
        }
        Ok(Some(TableEdit { entry, values }))
    }

    /// Radius compensation G40/G41/G42 (SPEC §4.1, §4.2): the side and radius in force, and
    /// the checks on starting, switching and cancelling it.
    fn compensation(
        &self,
        w: &Words,
        old: &State,
        st: &mut State,
        edit: Option<&TableEdit>,
        arc_block: bool,
        motion_words: bool,
    ) -> Result<Comp, Fail> {
        let rules = self.rules;
        if let Some((c, _)) = w.comp {
            st.comp = c;
        }
        let comp_at = w.comp.map(|c| c.1).unwrap_or(w.first);
        let comp = match st.comp {
            CompMode::Off => Comp::Off,
            side => {
                let Some(radius_mm) = self.radius_of(st.d, edit) else {
                    return fail(
                        comp_at,
                        DiagCode::CompWithoutTool,
                        "radius compensation needs a tool: select an offset entry with D before G41/G42",
                    );
                };
                if side == CompMode::Left {
                    Comp::Left { d: st.d, radius_mm }
                } else {
                    Comp::Right { d: st.d, radius_mm }
                }
            }
        };
        if st.comp == old.comp {
            return Ok(comp);
        }
        if arc_block && motion_words {
            return fail(
                comp_at,
                DiagCode::CompChangeOnArc,
                "radius compensation can be started or cancelled only in a linear block, not on an arc",
            );
        }
        if old.comp != CompMode::Off && st.comp != CompMode::Off && !rules.side_switch_allowed {
            return fail(
                comp_at,
                DiagCode::CompSideSwitch,
                "G41 and G42 cannot follow each other directly: program G40 between them (or set 6.R397 = 1)",
            );
        }
        let (a, b) = st.modal.plane.axes();
        if st.comp == CompMode::Off
            && !rules.g40_without_motion
            && w.axes[a].is_none()
            && w.axes[b].is_none()
        {
            return fail(
                comp_at,
                DiagCode::G40WithoutMotion,
                "G40 must be in a block that moves in the compensation plane (or set 7.R339 = 1)",
            );
        }
        Ok(comp)
    }

    /// The programmed position after the block and the length offset in force (which KŘR
    /// version 2 also uses, from this block on, SPEC §6).
    fn positions(
        &self,
        w: &Words,
        old: &State,
        st: &mut State,
        edit: Option<&TableEdit>,
    ) -> AxesMm {
        let offset = self.length_offset(st.amp, edit);
        st.modal.spindle.length_offset_mm = self.kr_axis.map_or(0.0, |k| offset[k]);
        for (k, v) in w.axes[..self.n_axes].iter().enumerate() {
            if let Some((v, _)) = v {
                let v = self.to_radius(k, *v);
                st.prog[k] = if st.modal.absolute {
                    v
                } else {
                    old.prog[k] + v
                };
            }
        }
        offset
    }

    /// A block that moves: its path (rapid, line or a checked arc) and the feed it needs.
    /// `ends` is (start, end, length offset) in machine coordinates.
    #[inline(always)]
    fn motion(
        &self,
        w: &Words,
        st: &State,
        old: &State,
        ends: (AxesMm, AxesMm, AxesMm),
        arc_block: bool,
        per_rev: bool,
    ) -> Result<Outcome, Fail> {
        let (start, end, offset) = ends;
        let (mut warn, mut refined) = (None, None);
        if arc_block && let Some(k) = self.moving_rotary_axis(start, end) {
            return fail(
                w.axes[k].map_or(w.first, |a| a.1),
                DiagCode::RotaryAxisInArc,
                format!(
                    "{} is a rotary axis: it moves in linear blocks (G0, G1), not in an arc",
                    self.axis_letters[k] as char
                ),
            );
        }
        let path = if arc_block {
            match self.arc(w, st, old, start, end, offset)? {
                Ok((p, r)) => {
                    refined = r;
                    p
                }
                Err(off) => {
                    warn = Some((w.first, format!("{off}; replaced by a line (7.R397 = 1)")));
                    Path::Line
                }
            }
        } else if st.modal.motion == Motion::Rapid {
            Path::Rapid
        } else {
            Path::Line
        };
        if path != Path::Rapid {
            check_feed(w, st, old, per_rev)?;
        }
        Ok(Outcome {
            kind: BlockKind::Motion { start, end, path },
            warn,
            refined,
        })
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

    /// The first rotary axis that moves between `start` and `end`.
    fn moving_rotary_axis(&self, start: AxesMm, end: AxesMm) -> Option<usize> {
        (0..self.n_axes).find(|&k| self.rotary_kppr[k] > 0.0 && (end[k] - start[k]).abs() > 1e-12)
    }

    /// The programmed feed as the feed along the block's whole axis vector (rotary axes in
    /// degrees), by the rule of [`super::feed::rotary_feed_factor`] (docs/lathe.md).
    fn rotary_feed(&self, f: Feed, start: AxesMm, end: AxesMm) -> Feed {
        if self.moving_rotary_axis(start, end).is_none() {
            return f;
        }
        let n = self.n_axes;
        let k = super::feed::rotary_feed_factor(&start.0[..n], &end.0[..n], &self.rotary_kppr[..n]);
        match f {
            Feed::MmPerMin(v) => Feed::MmPerMin(v * k),
            Feed::MmPerRev(v) => Feed::MmPerRev(v * k),
        }
    }

    /// SPEC §5: βmax = Vmax/S. A feed per revolution above it cannot be followed at the
    /// nominal spindle speed of the block (the axes cap the feed): a warning.
    fn beta_max_warning(&self, beta_mm_rev: f64, spindle: &Spindle) -> Option<String> {
        let n = spindle.per_rev_nominal_rpm()?;
        let beta_max = crate::kr::max_feed_mm_rev(self.max_feed_mm_min, n)?;
        (self.max_feed_mm_min > 0.0 && beta_mm_rev > beta_max + 1e-9).then(|| {
            format!(
                "feed {beta_mm_rev} mm/rev is above βmax = {beta_max:.3} mm/rev (Vmax {} mm/min \
                 / {n} rpm; at this feed Smax = Vmax/β = {:.0} rpm): the axes limit the feed, \
                 it will not follow the spindle",
                self.max_feed_mm_min,
                self.max_feed_mm_min / beta_mm_rev
            )
        })
    }

    /// SPEC §4.6: the preprocessor records a refinement as address E in the block; here it
    /// is an information message with the E word (and, when recording, a [`Refined`]).
    fn note_refinement(&mut self, w: &Words, line_no: u32, r: ERefinement) {
        // A programmed E on the same coordinate adds up; on the other one the block would
        // need two E words, which the language does not have: only the message tells.
        let programmed =
            w.e.and_then(|(e, at)| Some((ERefinement::decode(e.value).ok()?, at)));
        let word = match programmed {
            Some((p, _)) if p.which == r.which => Some(ERefinement {
                which: r.which,
                delta_mm: p.delta_mm + r.delta_mm,
            }),
            Some(_) => None,
            None => Some(r),
        };
        let coord = if r.which == Corrected::I { 'I' } else { 'J' };
        let shown = word.unwrap_or(r);
        self.notes.push(Diagnostic::info(
            DiagCode::ArcRefined,
            w.n,
            line_no,
            0,
            format!(
                "circle refinement (R325): E{:.3}, {coord} corrected by {:+.6} mm",
                shown.encode(),
                r.delta_mm
            ),
        ));
        if let Some(list) = self.refinements.as_mut() {
            list.push(Refined {
                seq: self.seq,
                n: w.n,
                line: line_no,
                refinement: r,
                word,
                programmed_e_at: programmed.map(|(_, at)| at),
            });
        }
    }

    /// The arc centre words I, J as the machine reads them (radius units), with a programmed
    /// E refinement applied (SPEC §4.6).
    fn centre_words(
        &self,
        (i, j): (Num, Num),
        w: &Words,
        plane: Plane,
    ) -> Result<(f64, f64), Fail> {
        let (a, b) = plane.axes();
        let mut ij = (i.value, j.value);
        if self.rules.ij == IjMode::Absolute {
            // An absolute centre is a coordinate: a diameter on the diameter axis. A relative
            // one is a distance from the start: always a radius (docs/lathe.md).
            ij = (self.to_radius(a, ij.0), self.to_radius(b, ij.1));
        }
        if let Some((e, at)) = w.e {
            let r = ERefinement::decode(e.value).map_err(|e| Fail::new(at, e.code(), e))?;
            ij = r.apply(ij);
        }
        Ok(ij)
    }

    /// Builds and checks an arc. `Ok(Err(off))`: the end point misses the circle and 7.R397
    /// turns the arc into a line (a warning). `Ok(Ok((path, E)))`: E is
    /// the R325 refinement the preprocessor applied, if any.
    fn arc(
        &self,
        w: &Words,
        st: &State,
        old: &State,
        start: AxesMm,
        end: AxesMm,
        offset: AxesMm,
    ) -> Result<Result<(Path, Option<ERefinement>), OffCircle>, Fail> {
        let rules = self.rules;
        let (a, b) = st.modal.plane.axes();
        let (Some((i, _)), Some((j, _))) = (w.i, w.j) else {
            return fail(
                w.i.or(w.j).map_or(w.first, |x| x.1),
                DiagCode::ArcNeedsCentre,
                "an arc needs both centre words I and J",
            );
        };
        let old_offset = old.machine - old.prog;
        if (0..MAX_AXES).any(|k| (offset[k] - old_offset[k]).abs() > 1e-12) {
            return fail(
                w.amp.map_or(w.first, |x| x.1),
                DiagCode::ArcAfterOffsetChange,
                "the length offset changed (& or G92) since the last motion: move in a line first, an arc cannot take it up",
            );
        }
        let mut ij = self.centre_words((i, j), w, st.modal.plane)?;
        let (s2, e2) = ((start[a], start[b]), (end[a], end[b]));
        let centre_of = |ij: (f64, f64)| match rules.ij {
            IjMode::RelativeToStart => (start[a] + ij.0, start[b] + ij.1),
            IjMode::Absolute => (ij.0 + offset[a], ij.1 + offset[b]),
        };
        let mut c2 = centre_of(ij);
        let refined = arc::refine(s2, e2, c2, rules.refinement);
        if let Some(r) = refined {
            ij = r.apply(ij);
            c2 = centre_of(ij);
        }
        let (rs, re) = arc::radii(s2, e2, c2);
        if rs < 1e-9 {
            return fail(
                w.first,
                DiagCode::ArcRadiusZero,
                "the arc radius is zero: the centre I J is at the start point",
            );
        }
        let miss = (rs - re).abs();
        if miss > rules.arc_tolerance_mm {
            let off = OffCircle {
                start_mm: rs,
                end_mm: re,
                miss_mm: miss,
                tolerance_mm: rules.arc_tolerance_mm,
            };
            if rules.bad_arc_becomes_line {
                return Ok(Err(off));
            }
            return fail(w.first, DiagCode::ArcEndOffCircle, off);
        }
        let mut center = start;
        center[a] = c2.0;
        center[b] = c2.1;
        Ok(Ok((
            Path::Arc {
                dir: if st.modal.motion == Motion::Cw {
                    ArcDir::Cw
                } else {
                    ArcDir::Ccw
                },
                center,
                plane: st.modal.plane,
            },
            refined,
        )))
    }
}

/// The arc end point is not on the circle (SPEC §4.6: the radii at start and end differ by
/// more than R55).
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error(
    "the arc end point is not on the circle: start radius {start_mm:.4} mm, end radius \
     {end_mm:.4} mm, difference {miss_mm:.4} mm is more than the tolerance R55 = \
     {tolerance_mm:.3} mm"
)]
struct OffCircle {
    start_mm: f64,
    end_mm: f64,
    miss_mm: f64,
    tolerance_mm: f64,
}

/// What a checked block makes, before the commit: its kind, a warning to give (an arc
/// replaced by a line, 7.R397) and the R325 refinement applied to its arc.
struct Outcome {
    kind: BlockKind,
    warn: Option<(usize, String)>,
    refined: Option<ERefinement>,
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

/// Motion (G0..G3), G90/G91 and continuity (G23/G24/G98): modal words without checks.
fn apply_simple_modals(w: &Words, st: &mut State) {
    if let Some((m, _)) = w.motion {
        st.modal.motion = m;
    }
    if let Some((a, _)) = w.absolute {
        st.modal.absolute = a;
    }
    if let Some((c, _)) = w.continuity {
        st.modal.continuity = c;
    }
}

/// G23/G24/G98 I1..I4: I selects the dynamic set (SPEC §7.4) unless the block is an arc that
/// moves (G2/G3 mode with an axis word or J), where I is the centre. Returns whether I is the
/// arc centre.
fn dynamic_set(
    w: &Words,
    st: &mut State,
    arc_block: bool,
    motion_words: bool,
) -> Result<bool, Fail> {
    if let (Some(_), Some((i, at))) = (w.continuity, w.i)
        && (!arc_block || (w.j.is_none() && !motion_words))
    {
        let set = int(i, "I (dynamic set)", 1, 4).map_err(|e| Fail::new(at, e.code(), e))?;
        st.modal.dyn_set = set as u8;
        return Ok(false);
    }
    Ok(true)
}

/// Plane G17..G19 (SPEC §4.1: no change under compensation).
fn plane(w: &Words, old: &State, st: &mut State) -> Result<(), Fail> {
    if let Some((p, at)) = w.plane {
        if old.comp != CompMode::Off && p != old.modal.plane {
            return fail(
                at,
                DiagCode::PlaneChangeUnderComp,
                "the plane cannot change while radius compensation G41/G42 is active: program G40 first",
            );
        }
        st.modal.plane = p;
    }
    Ok(())
}

/// I, J, E belong to arcs.
fn check_arc_words(w: &Words, arc_block: bool, i_is_centre: bool) -> Result<(), Fail> {
    if arc_block {
        return Ok(());
    }
    if let Some((_, at)) = w.i.filter(|_| i_is_centre).or(w.j) {
        return fail(
            at,
            DiagCode::ArcWordWithoutArc,
            "I and J are arc centre words: they need G2 or G3",
        );
    }
    if let Some((_, at)) = w.e {
        return fail(
            at,
            DiagCode::ArcWordWithoutArc,
            "E refines an arc centre: it needs G2 or G3",
        );
    }
    Ok(())
}

/// A feed move needs F > 0 in the feed mode in force, and feed per revolution a turning
/// spindle (SPEC §5).
fn check_feed(w: &Words, st: &State, old: &State, per_rev: bool) -> Result<(), Fail> {
    match st.modal.feed {
        Some(f) if feed_value(f) > 0.0 => {}
        Some(_) => {
            return fail(
                w.f.map_or(w.first, |f| f.1),
                DiagCode::FeedZero,
                "feed F is zero: a feed move needs F > 0",
            );
        }
        None if old.modal.feed.is_some() => {
            return fail(
                w.first,
                DiagCode::FeedModeChanged,
                "the feed changed between per minute and per revolution: program F again",
            );
        }
        None => {
            return fail(
                w.first,
                DiagCode::NoFeed,
                "no feed: program F before the first feed move (G1/G2/G3)",
            );
        }
    }
    if per_rev
        && (st.modal.spindle.dir == SpindleDir::Stopped
            || (st.modal.spindle.s <= 0.0 && !st.modal.speed_from_css))
    {
        return fail(
            w.first,
            DiagCode::FeedPerRevWithoutSpindle,
            "feed per revolution needs a turning spindle: program S and M3 or M4 first",
        );
    }
    Ok(())
}

fn feed_value(f: Feed) -> f64 {
    match f {
        Feed::MmPerMin(v) | Feed::MmPerRev(v) => v,
    }
}

/// Puts G function `v` of modal group `what` (written at `at`) in its slot: one per block.
fn group<T>(slot: &mut Option<(T, usize)>, v: T, at: usize, what: &str) -> Result<(), Fail> {
    put_once(slot, v, at, || {
        let message = format!("two G functions of the {what} group in one block");
        (DiagCode::GGroupConflict, message)
    })
}

/// Puts `v` (written at `at`) in its slot of the block's words; if the slot is taken, the
/// error `twice` makes (built only then: words are read a million times a second).
#[inline]
fn put_once<T>(
    slot: &mut Option<(T, usize)>,
    v: T,
    at: usize,
    twice: impl FnOnce() -> (DiagCode, String),
) -> Result<(), Fail> {
    if slot.is_some() {
        let (code, message) = twice();
        return fail(at, code, message);
    }
    *slot = Some((v, at));
    Ok(())
}

/// Why a word that takes a whole number in a range is refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
enum WordError {
    #[error("{what} takes a whole number, not {value}")]
    NotWhole { what: &'static str, value: f64 },
    #[error("{what}{value} is outside {lo}..{hi}")]
    OutOfRange {
        what: &'static str,
        value: f64,
        lo: u32,
        hi: u32,
    },
}

impl WordError {
    /// Stable code (tests and HMIs match it; the message may improve).
    fn code(&self) -> DiagCode {
        match self {
            WordError::NotWhole { .. } => DiagCode::WordNotWhole,
            WordError::OutOfRange { .. } => DiagCode::WordOutOfRange,
        }
    }
}

/// An integer word without a decimal point in `lo..=hi`.
fn int(n: Num, what: &'static str, lo: u32, hi: u32) -> Result<u32, WordError> {
    let value = n.value;
    if n.point || value.fract() != 0.0 {
        return Err(WordError::NotWhole { what, value });
    }
    if value < lo as f64 || value > hi as f64 {
        return Err(WordError::OutOfRange {
            what,
            value,
            lo,
            hi,
        });
    }
    Ok(value as u32)
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
