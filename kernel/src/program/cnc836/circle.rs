//! Arcs (SPEC §2, §4.6): the centre words I, J with the E refinement, the R55 end-point check,
//! the preprocessor's R325 refinement and its message.

use super::collect::Words;
use super::modal::{Motion, State};
use super::words::Num;
use super::{Fail, Interpreter, fail};
use crate::block::{ArcDir, Path, Plane};
use crate::diag::{DiagCode, Diagnostic};
use crate::program::IjMode;
use crate::program::arc::{self, Corrected, ERefinement, Refined};
use crate::units::{AxesMm, MAX_AXES};

impl Interpreter {
    /// Builds and checks an arc. `Ok(Err(off))`: the end point misses the circle and 7.R397
    /// turns the arc into a line (a warning). `Ok(Ok((path, E)))`: E is
    /// the R325 refinement the preprocessor applied, if any.
    pub(super) fn arc(
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

    /// The arc centre words I, J as the machine reads them (radius units), with a programmed
    /// E refinement applied (SPEC §4.6).
    pub(super) fn centre_words(
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

    /// SPEC §4.6: the preprocessor records a refinement as address E in the block; here it
    /// is an information message with the E word (and, when recording, a [`Refined`]).
    pub(super) fn note_refinement(&mut self, w: &Words, line_no: u32, r: ERefinement) {
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
}

/// The arc end point is not on the circle (SPEC §4.6: the radii at start and end differ by
/// more than R55).
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error(
    "the arc end point is not on the circle: start radius {start_mm:.4} mm, end radius \
     {end_mm:.4} mm, difference {miss_mm:.4} mm is more than the tolerance R55 = \
     {tolerance_mm:.3} mm"
)]
pub(super) struct OffCircle {
    start_mm: f64,
    end_mm: f64,
    miss_mm: f64,
    tolerance_mm: f64,
}

/// I, J, E belong to arcs.
pub(super) fn check_arc_words(w: &Words, arc_block: bool, i_is_centre: bool) -> Result<(), Fail> {
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
