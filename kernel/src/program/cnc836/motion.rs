//! Positions and the motion of a block: programmed and machine coordinates, diameter axis,
//! rotary axes, and the path a block takes (rapid, line or arc).

use super::collect::Words;
use super::modal::{Motion, State};
use super::spindle::check_feed;
use super::{Fail, Interpreter, fail};
use crate::block::{BlockKind, Path};
use crate::diag::DiagCode;
use crate::offsets::TableEdit;
use crate::program::arc::ERefinement;
use crate::units::AxesMm;

impl Interpreter {
    /// The programmed position after the block and the length offset in force (which KŘR
    /// version 2 also uses, from this block on, SPEC §6).
    pub(super) fn positions(
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
    pub(super) fn motion(
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

    /// The first rotary axis that moves between `start` and `end`.
    pub(super) fn moving_rotary_axis(&self, start: AxesMm, end: AxesMm) -> Option<usize> {
        (0..self.n_axes).find(|&k| self.rotary_kppr[k] > 0.0 && (end[k] - start[k]).abs() > 1e-12)
    }

    /// A value of axis `k` in program units → internal (radius) units.
    pub(super) fn to_radius(&self, k: usize, v: f64) -> f64 {
        if self.diameter_axis == Some(k) {
            v / 2.0
        } else {
            v
        }
    }
}

/// What a checked block makes, before the commit: its kind, a warning to give (an arc
/// replaced by a line, 7.R397) and the R325 refinement applied to its arc.
pub(super) struct Outcome {
    pub(super) kind: BlockKind,
    pub(super) warn: Option<(usize, String)>,
    pub(super) refined: Option<ERefinement>,
}
