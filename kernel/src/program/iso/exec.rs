//! One line's words executed in LinuxCNC's order (RS274-NGC "order of execution"): feed
//! mode, F, S, T, M6, spindle, coolant, dwell, plane, units, compensation, tool length, work
//! offset, path control, distance modes, retract mode, G10/G92, motion, stops. The line works
//! on a copy of the state and collects its blocks; the caller commits both only when the
//! whole line is right.

use super::Fail;
use super::state::{CompSide, FeedMode, MotionMode, State};
use super::words::{NonModal, PathMode, Words};
use crate::block::{Block, BlockKind, Comp, Continuity, Feed, MCodes, SpindleDir};
use crate::diag::DiagCode;
use crate::offsets::OffsetTable;
use crate::outputs::MFunctions;
use crate::units::{AxesMm, MAX_AXES};

/// What the ISO interpreter knows of the machine.
pub struct Machine {
    pub n_axes: usize,
    pub axis_letters: [u8; MAX_AXES],
    pub table: OffsetTable,
    pub m_outputs: MFunctions,
    /// R55: how far an arc's end may miss its circle, mm.
    pub arc_tolerance_mm: f64,
    /// The controlling axis of constant cutting speed (its length offset rides with the
    /// spindle state, SPEC §6).
    pub kr_axis: Option<usize>,
}

/// A line being executed: the state copy and the blocks made so far.
pub struct Exec<'a> {
    pub m: &'a Machine,
    pub st: State,
    pub out: Vec<Block>,
    pub seq: u32,
    pub line: u32,
    pub n: Option<u32>,
    /// The motion mode before this line (a cycle's R and Z may be left out only while the
    /// same cycle stays in force).
    pub prev_motion: MotionMode,
}

fn fail<T>(at: usize, code: DiagCode, message: impl ToString) -> Result<T, Fail> {
    Err(Fail::new(at, code, message))
}

impl Exec<'_> {
    /// The whole line.
    pub fn run(&mut self, w: &Words) -> Result<(), Fail> {
        self.st.spindle.outputs = self.st.spindle.outputs.carried();
        self.feed_words(w)?;
        self.tool_select(w)?;
        if let Some(at) = w.m6 {
            self.tool_change(at)?;
        }
        self.spindle_and_coolant(w)?;
        if let Some((NonModal::Dwell, at)) = w.non_modal {
            self.dwell(w, at)?;
        }
        self.modal_groups(w)?;
        self.compensation(w)?;
        self.tool_length(w)?;
        self.non_modal(w)?;
        let moved = self.motion(w)?;
        let mut m: MCodes = [None; 4];
        for (k, code) in self.m_codes(w).into_iter().take(4).enumerate() {
            m[k] = Some(code);
        }
        let has_m = m.iter().any(Option::is_some);
        if moved {
            if has_m && let Some(b) = self.out.last_mut() {
                b.m = m;
            }
        } else if has_m || (self.out.is_empty() && w.first_word_is_code()) {
            self.emit(BlockKind::Technology, Feed::default(), m);
        }
        Ok(())
    }

    /// The M codes the line's last block carries (stops last, as they act after the motion).
    fn m_codes(&self, w: &Words) -> Vec<u16> {
        let mut m: Vec<u16> = Vec::new();
        m.extend(w.spindle.map(|s| s.0));
        m.extend(w.coolant.iter().map(|c| c.0));
        m.extend(w.bound.iter().map(|c| c.0));
        m.extend(w.stop.map(|s| s.0));
        m
    }

    /// G93/G94/G95, F and S.
    fn feed_words(&mut self, w: &Words) -> Result<(), Fail> {
        if let Some((fm, _)) = w.feed_mode {
            if fm != self.st.feed_mode {
                // LinuxCNC: inverse time needs F on every feed line; switching to or from
                // it leaves no feed in force.
                if fm == FeedMode::InverseTime || self.st.feed_mode == FeedMode::InverseTime {
                    self.st.feed = None;
                }
            }
            self.st.feed_mode = fm;
        }
        if self.st.feed_mode == FeedMode::InverseTime {
            self.st.feed = None;
        }
        if let Some((f, at)) = w.f {
            if !f.is_finite() || f < 0.0 {
                return fail(
                    at,
                    DiagCode::FeedOutOfRange,
                    format!("F{f} cannot be negative"),
                );
            }
            self.st.feed = Some(match self.st.feed_mode {
                FeedMode::InverseTime => f,
                _ => self.st.mm(f),
            });
        }
        if let Some((s, at)) = w.s {
            if !s.is_finite() || s < 0.0 {
                return fail(at, DiagCode::NegativeSpeed, "S cannot be negative");
            }
            self.st.spindle.s = s;
        }
        Ok(())
    }

    /// T: the tool for the next M6 (its entry of the offset table).
    fn tool_select(&mut self, w: &Words) -> Result<(), Fail> {
        if let Some((t, at)) = w.t {
            self.st.next_tool = entry_of(t, at, "T")?;
        }
        Ok(())
    }

    /// M6: the selected tool goes into the spindle. The program stops for the change (as at
    /// M0, the spindle stopped as LinuxCNC's M6 stops it) in a block of its own, before the
    /// line's motion (docs/language.md, "Tool change").
    fn tool_change(&mut self, _at: usize) -> Result<(), Fail> {
        self.st.tool = self.st.next_tool;
        self.st.spindle.dir = SpindleDir::Stopped;
        self.emit(
            BlockKind::ToolChange { tool: self.st.tool },
            Feed::default(),
            [Some(6), None, None, None],
        );
        Ok(())
    }

    fn spindle_and_coolant(&mut self, w: &Words) -> Result<(), Fail> {
        if let Some((m, _)) = w.spindle {
            self.st.spindle.dir = match m {
                3 => SpindleDir::Cw,
                4 => SpindleDir::Ccw,
                _ => SpindleDir::Stopped,
            };
        }
        for (m, _) in w.coolant.iter().chain(w.bound.iter()) {
            self.m.m_outputs.apply(*m, &mut self.st.spindle.outputs);
        }
        if matches!(w.stop, Some((2 | 30, _))) {
            // M2/M30 end the program: spindle and outputs off (LinuxCNC's program end).
            self.st.spindle.dir = SpindleDir::Stopped;
            self.st.spindle.outputs.on = 0;
        }
        Ok(())
    }

    /// G4 P<seconds>.
    fn dwell(&mut self, w: &Words, at: usize) -> Result<(), Fail> {
        let Some((p, _)) = w.p else {
            return fail(at, DiagCode::CycleWord, "G4 needs P: the dwell in seconds");
        };
        if !p.is_finite() || !(0.0..=99_999.0).contains(&p) {
            return fail(at, DiagCode::CycleWord, format!("G4 P{p}: 0..99999 s"));
        }
        self.emit(BlockKind::Dwell { seconds: p }, Feed::default(), [None; 4]);
        Ok(())
    }

    /// Plane, units, work offset, path control, distance modes, retract mode.
    fn modal_groups(&mut self, w: &Words) -> Result<(), Fail> {
        if let Some((p, at)) = w.plane {
            let (a, b) = p.axes();
            if a >= self.m.n_axes || b >= self.m.n_axes {
                return fail(
                    at,
                    DiagCode::PlaneNeedsAxis,
                    "this plane needs an axis the machine does not have",
                );
            }
            self.st.plane = p;
        }
        if let Some((inches, _)) = w.inches {
            self.st.inches = inches;
        }
        if let Some((k, _)) = w.system {
            self.st.system = k;
        }
        if let Some((p, _)) = w.path {
            self.st.continuity = match p {
                PathMode::Blend => Continuity::G23,
                PathMode::ExactPath | PathMode::ExactStop => Continuity::G98,
            };
        }
        if let Some((a, _)) = w.absolute {
            self.st.absolute = a;
        }
        if let Some((a, _)) = w.arc_absolute {
            self.st.arc_absolute = a;
        }
        if let Some((r, _)) = w.retract_to_r {
            self.st.retract_to_r = r;
        }
        Ok(())
    }

    /// G40/G41/G42 with D (the entry whose radius is used; without D the tool's own).
    fn compensation(&mut self, w: &Words) -> Result<(), Fail> {
        let Some((side, at)) = w.comp else {
            return Ok(());
        };
        self.st.comp = side;
        if side == CompSide::Off {
            return Ok(());
        }
        let entry = match w.d {
            Some((d, d_at)) => entry_of(d, d_at, "D")?,
            None => self.st.tool,
        };
        let Some(e) = self.m.table.entry(entry) else {
            return fail(
                at,
                DiagCode::CompWithoutTool,
                "radius compensation needs a tool: D<entry> or a tool in the spindle (M6)",
            );
        };
        self.st.comp_entry = entry;
        self.st.comp_radius_mm = e.radius_mm;
        Ok(())
    }

    /// G43 [H] / G49: the entry's lengths (axes 1..4) in force.
    fn tool_length(&mut self, w: &Words) -> Result<(), Fail> {
        let Some((on, _)) = w.length else {
            return Ok(());
        };
        self.st.length_mm = AxesMm::ZERO;
        self.st.length_entry = 0;
        if !on {
            return Ok(());
        }
        let entry = match w.h {
            Some((h, at)) => entry_of(h, at, "H")?,
            None => self.st.tool,
        };
        if let Some(e) = self.m.table.entry(entry) {
            for k in 0..4.min(self.m.n_axes) {
                self.st.length_mm[k] = e.length_mm[k];
            }
            self.st.length_entry = entry;
        }
        Ok(())
    }

    /// G10 L2/L20, G92, G92.1 (G53 and G4 act elsewhere).
    fn non_modal(&mut self, w: &Words) -> Result<(), Fail> {
        match w.non_modal {
            Some((NonModal::SetWorkOffset, at)) => self.g10(w, at),
            Some((NonModal::G92Set, at)) => {
                if !w.any_axis() {
                    return fail(at, DiagCode::CycleWord, "G92 needs at least one axis word");
                }
                let prog = self.st.program_pos();
                for k in 0..self.m.n_axes {
                    if let Some((v, _)) = w.axes[k] {
                        // The G92 offset makes the current point read v.
                        self.st.g92_mm[k] += prog[k] - self.st.mm(v);
                    }
                }
                Ok(())
            }
            Some((NonModal::G92Cancel, _)) => {
                self.st.g92_mm = AxesMm::ZERO;
                Ok(())
            }
            _ => Ok(()),
        }
    }

    /// G10 L2 P<n> (set system n's offset) and L20 (so that the current point reads the
    /// words). Acts on the run's copy of the work offsets only.
    fn g10(&mut self, w: &Words, at: usize) -> Result<(), Fail> {
        let l = w.l.map(|l| l.0.round() as i64);
        if l != Some(2) && l != Some(20) {
            return fail(
                at,
                DiagCode::IsoUnsupported,
                "G10 is run only as G10 L2 or G10 L20 (work offsets) in cncd's ISO dialect",
            );
        }
        let p = w.p.map_or(-1.0, |p| p.0).round();
        if !(0.0..=9.0).contains(&p) {
            return fail(
                at,
                DiagCode::CycleWord,
                "G10 L2/L20 needs P0..P9 (0: the system in force, 1: G54 … 9: G59.3)",
            );
        }
        let k = if p == 0.0 {
            self.st.system
        } else {
            p as usize - 1
        };
        let machine = self.st.machine;
        for ax in 0..self.m.n_axes {
            if let Some((v, _)) = w.axes[ax] {
                let v = self.st.mm(v);
                self.st.work.systems[k][ax] = if l == Some(2) {
                    v
                } else {
                    machine[ax] - self.st.g92_mm[ax] - self.st.length_mm[ax] - v
                };
            }
        }
        Ok(())
    }

    /// The feed of a feed move of `length_mm` (mm/min, or mm/rev under G95).
    pub fn feed_for(&self, at: usize, length_mm: f64) -> Result<Feed, Fail> {
        let Some(f) = self.st.feed else {
            let msg = match self.st.feed_mode {
                FeedMode::InverseTime => "G93 needs F on every feed line",
                _ => "a feed move needs F",
            };
            return fail(at, DiagCode::NoFeed, msg);
        };
        if f <= 0.0 {
            return fail(at, DiagCode::FeedZero, "cannot feed with F0");
        }
        match self.st.feed_mode {
            FeedMode::PerMinute => Ok(Feed::MmPerMin(f)),
            FeedMode::PerRev => {
                if self.st.spindle.dir == SpindleDir::Stopped || self.st.spindle.s <= 0.0 {
                    return fail(
                        at,
                        DiagCode::FeedPerRevWithoutSpindle,
                        "G95 feed needs a turning spindle with S",
                    );
                }
                Ok(Feed::MmPerRev(f))
            }
            // F is 1/minutes for the move: the path feed is its length times F.
            FeedMode::InverseTime => Ok(Feed::MmPerMin(length_mm * f)),
        }
    }

    /// Appends a block with the line's state.
    pub fn emit(&mut self, kind: BlockKind, feed: Feed, m: MCodes) {
        if let BlockKind::Motion { end, .. } = kind {
            self.st.machine = end;
        }
        let mut spindle = self.st.spindle;
        spindle.length_offset_mm = self.m.kr_axis.map_or(0.0, |k| self.st.length_mm[k]);
        let comp = match self.st.comp {
            CompSide::Off => Comp::Off,
            CompSide::Left => Comp::Left {
                d: self.st.comp_entry,
                radius_mm: self.st.comp_radius_mm,
            },
            CompSide::Right => Comp::Right {
                d: self.st.comp_entry,
                radius_mm: self.st.comp_radius_mm,
            },
        };
        self.out.push(Block {
            seq: self.seq,
            n: self.n,
            line: self.line,
            kind,
            feed,
            plane: self.st.plane,
            comp,
            continuity: self.st.continuity,
            dyn_set: 1,
            spindle,
            m,
        });
        self.seq += 1;
    }

    /// The motion of the line, if any. Returns whether a motion block was made.
    fn motion(&mut self, w: &Words) -> Result<bool, Fail> {
        let uses_axes = matches!(
            w.non_modal,
            Some((NonModal::SetWorkOffset | NonModal::G92Set, _))
        );
        self.prev_motion = self.st.motion;
        if let Some((m, _)) = w.motion {
            self.st.motion = m;
        }
        if uses_axes {
            return Ok(false);
        }
        let mode = self.st.motion;
        if !mode_is_cycle(mode) {
            self.st.cycle.initial_mm = None;
        }
        if !w.any_axis()
            && !(mode.is_arc()
                && w.motion.is_some()
                && (w.i.is_some() || w.j.is_some() || w.k.is_some()))
        {
            return Ok(false);
        }
        match mode {
            MotionMode::Off => fail(
                w.first,
                DiagCode::IsoModalConflict,
                "axis words with G80 in force: no motion mode (G0, G1 …) is selected",
            ),
            MotionMode::Cycle(g) => {
                self.cycle(w, g)?;
                Ok(true)
            }
            MotionMode::Probe(mv) => {
                self.probe(w, mv)?;
                Ok(true)
            }
            _ => {
                self.straight_or_arc(w, mode)?;
                Ok(true)
            }
        }
    }
}

fn mode_is_cycle(m: MotionMode) -> bool {
    matches!(m, MotionMode::Cycle(_))
}

impl MotionMode {
    pub fn is_arc(self) -> bool {
        matches!(self, MotionMode::Cw | MotionMode::Ccw)
    }
}

impl Words {
    /// The line has a word that makes a technology block (a G, M, F, S, T … word).
    pub fn first_word_is_code(&self) -> bool {
        self.motion.is_some()
            || self.non_modal.is_some()
            || self.plane.is_some()
            || self.inches.is_some()
            || self.absolute.is_some()
            || self.arc_absolute.is_some()
            || self.feed_mode.is_some()
            || self.comp.is_some()
            || self.length.is_some()
            || self.system.is_some()
            || self.path.is_some()
            || self.retract_to_r.is_some()
            || self.f.is_some()
            || self.s.is_some()
            || self.t.is_some()
            || self.d.is_some()
            || self.h.is_some()
    }
}

/// A T, H or D word as an entry of the offset table (0 = none).
pub fn entry_of(v: f64, at: usize, what: &str) -> Result<u8, Fail> {
    let r = v.round();
    if !v.is_finite()
        || (v - r).abs() > 1e-6
        || !(0.0..=f64::from(crate::offsets::ENTRIES)).contains(&r)
    {
        return fail(
            at,
            DiagCode::ToolNotInTable,
            format!(
                "{what}{v}: tools are the entries 0..{} of the offset table TAB0.KOR",
                crate::offsets::ENTRIES
            ),
        );
    }
    Ok(r as u8)
}
