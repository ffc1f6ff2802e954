//! Modal state: what stays from block to block (motion, plane, G90/G91, feed, continuity,
//! spindle), the rules read from the constants once, and the block steps that only set modal
//! words.

use super::collect::{Words, int};
use super::{Fail, fail};
use crate::block::{Continuity, Feed, Plane, Spindle};
use crate::constants::Refinement;
use crate::diag::DiagCode;
use crate::program::feed::FeedMode;
use crate::program::{IjMode, Setup};
use crate::units::AxesMm;

/// The motion group: G0 rapid, G1 line, G2 arc clockwise, G3 arc counter-clockwise.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Motion {
    Rapid,
    Line,
    Cw,
    Ccw,
}

impl Motion {
    pub(super) fn is_arc(self) -> bool {
        matches!(self, Motion::Cw | Motion::Ccw)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum CompMode {
    Off,
    Left,
    Right,
}

/// Rules taken from the machine constants once, when the interpreter is made.
#[derive(Clone, Copy, Debug)]
pub(super) struct Rules {
    pub(super) arc_tolerance_mm: f64,
    pub(super) bad_arc_becomes_line: bool,
    pub(super) side_switch_allowed: bool,
    pub(super) g40_without_motion: bool,
    pub(super) refinement: Refinement,
    pub(super) css_swapped: bool,
    pub(super) ij: IjMode,
}

/// Modal state: small and `Copy`, so a block works on a copy and commits it whole.
#[derive(Clone, Copy, Debug)]
pub(super) struct State {
    /// Programmed position (program coordinates, without length offset).
    pub(super) prog: AxesMm,
    /// Where the last motion ended, in machine coordinates (programmed + length offset).
    pub(super) machine: AxesMm,
    /// What the next MDI inherits.
    pub(super) modal: Modal,
    pub(super) comp: CompMode,
    /// Offset entry selected by D (0 = none).
    pub(super) d: u8,
    /// Length offset entry selected by & (0 = none).
    pub(super) amp: u8,
    /// The tool `T` named for the next M6 (0 = none).
    pub(super) next_tool: u8,
}

/// The modal state a program or MDI leaves for the next MDI (docs/language.md, "What MDI
/// inherits"): motion, plane, G90/G91, G94/G95, feed, M37, continuity, dynamic set and the
/// spindle (direction, S, gear, KŘR). Compensation, D and & offsets and the R parameters are
/// not inherited: they end with the program.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Modal {
    pub(super) motion: Motion,
    pub(super) plane: Plane,
    pub(super) absolute: bool,
    pub(super) feed_mode: FeedMode,
    /// Programmed feed (before M37 scaling); `None` until F is written, or after the feed
    /// changed between per minute and per revolution.
    pub(super) feed: Option<Feed>,
    /// M37: actual feed = programmed / 100 (SPEC §5).
    pub(super) m37: bool,
    pub(super) continuity: Continuity,
    pub(super) dyn_set: u8,
    pub(super) spindle: Spindle,
    /// The spindle speed is known at run time although S is 0: after constant cutting speed
    /// ends, the last reached speed becomes S (SPEC §6).
    pub(super) speed_from_css: bool,
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

    /// A modal state made of its parts (another front-end's state handed on as a `Modal`).
    pub fn from_parts(p: ModalParts) -> Self {
        Modal {
            motion: p.motion,
            plane: p.plane,
            absolute: p.absolute,
            feed_mode: p.feed_mode,
            feed: p.feed,
            m37: p.m37,
            continuity: p.continuity,
            dyn_set: p.dyn_set.clamp(1, 4),
            spindle: p.spindle,
            speed_from_css: p.speed_from_css,
        }
    }

    /// The parts of this state ([`Modal::from_parts`] of them gives it back).
    pub fn parts(&self) -> ModalParts {
        ModalParts {
            motion: self.motion,
            plane: self.plane,
            absolute: self.absolute,
            feed_mode: self.feed_mode,
            feed: self.feed,
            m37: self.m37,
            continuity: self.continuity,
            dyn_set: self.dyn_set,
            spindle: self.spindle,
            speed_from_css: self.speed_from_css,
        }
    }
}

/// The parts of a [`Modal`]; `Default` is the power-on state (G0, G17, G90, G94, no F, M36,
/// G98, dynamic set 1, spindle stopped). The caller keeps them consistent: a feed per
/// revolution under a per-revolution mode, S as the mode reads it (docs/language.md).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModalParts {
    /// G0..G3.
    pub motion: Motion,
    /// G17..G19.
    pub plane: Plane,
    /// G90 (`true`) or G91.
    pub absolute: bool,
    /// G94..G97.
    pub feed_mode: FeedMode,
    /// The programmed F before M37 scaling; `None`: no feed in force (a feed move needs one).
    pub feed: Option<Feed>,
    /// M37 (actual feed = programmed / 100) rather than M36.
    pub m37: bool,
    /// G98, G24 or G23.
    pub continuity: Continuity,
    /// Dynamic parameter set 1..4 (others are clamped into it).
    pub dyn_set: u8,
    /// Direction, S, gear, KŘR, G76 limit, outputs switched by M functions.
    pub spindle: Spindle,
    /// S is 0 but the spindle keeps the speed KŘR last reached (feed per revolution allowed).
    pub speed_from_css: bool,
}

impl Default for ModalParts {
    fn default() -> Self {
        ModalParts {
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
        }
    }
}

impl Rules {
    pub(super) fn of(setup: &Setup) -> Self {
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
    pub(super) fn power_on(start: AxesMm) -> Self {
        State {
            prog: start,
            machine: start,
            modal: Modal::from_parts(ModalParts::default()),
            comp: CompMode::Off,
            d: 0,
            amp: 0,
            next_tool: 0,
        }
    }

    pub(super) fn inherit(&mut self, m: &Modal) {
        self.modal = *m;
        // Offsets are not inherited: the spindle's length offset for KŘR goes with them.
        self.modal.spindle.length_offset_mm = 0.0;
    }
}

/// Motion (G0..G3), G90/G91 and continuity (G23/G24/G98): modal words without checks.
pub(super) fn apply_simple_modals(w: &Words, st: &mut State) {
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
pub(super) fn dynamic_set(
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
pub(super) fn plane(w: &Words, old: &State, st: &mut State) -> Result<(), Fail> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::block::SpindleDir;
    use crate::program::{Interpreter, compile};

    #[test]
    fn parts_give_back_the_modal_state() {
        let power_on = Interpreter::new(&Setup::new(&['X', 'Y', 'Z'])).modal();
        assert_eq!(Modal::from_parts(ModalParts::default()), power_on);
        let mut stream = crate::program::stream(
            "G1 X1 F100 M3 S500\nG91 G18 G95 F0.1 G24",
            &Setup::new(&['X', 'Y', 'Z']),
        );
        while stream.next().is_some() {}
        let m = stream.modal();
        assert_eq!(Modal::from_parts(m.parts()), m);
        let p = m.parts();
        assert_eq!(
            (p.motion, p.plane, p.absolute, p.feed_mode),
            (Motion::Line, Plane::G18, false, FeedMode::G95)
        );
        assert_eq!(
            (p.spindle.dir, p.spindle.s, p.continuity),
            (SpindleDir::Cw, 500.0, Continuity::G24)
        );
    }

    #[test]
    fn a_modal_made_of_parts_is_inherited() {
        let mut setup = Setup::new(&['X', 'Y', 'Z']);
        setup.modal = Some(Modal::from_parts(ModalParts {
            motion: Motion::Line,
            absolute: false,
            feed: Some(Feed::MmPerMin(300.0)),
            ..ModalParts::default()
        }));
        let c = compile("X5\nX5", &setup);
        assert!(!c.has_errors(), "{:?}", c.diagnostics);
        let ends: Vec<f64> = c.blocks.iter().map(|b| b.motion().unwrap().1[0]).collect();
        assert_eq!(ends, [5.0, 10.0]);
        assert_eq!(c.blocks[0].feed, Feed::MmPerMin(300.0));
    }
}
