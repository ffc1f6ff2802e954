//! `G31`: probing in a CNC836 program (docs/language.md, "Probing"). **Decision** (the
//! manuals have no probing): `G31` is the skip function of ISO controls of the CNC836's
//! time (Fanuc's G31), as LinuxCNC's G38.2 behaves: `N40 G31 Z-30 F300` moves in a straight
//! line at F toward the axis words' end and stops where the probe touches; ending there
//! without contact ends the run (`probe_no_contact`). It stands in a block of its own (N,
//! G31, axis words, F) and is not modal. The result goes to program parameters: R90..R93 the
//! position of axes 1..4 where the probe touched (program coordinates as the program writes
//! them: length offset & taken off, a diameter axis in diameter) and R94 = 1 when it
//! touched; the next block starts where the axes came to rest.

use super::collect::Words;
use super::modal::{CompMode, Motion};
use super::words::Num;
use super::{Checked, Fail, Interpreter, fail};
use crate::block::{Block, BlockKind, Path};
use crate::diag::DiagCode;
use crate::probe::{ProbeMove, ProbeResult};

/// Shorter than this a move does not run (the planner's limit): a G31 cannot find a contact.
const MIN_PROBE_MM: f64 = 1e-6;

/// R90..R93: where the probe touched, axes 1..4; R94: it touched.
pub const FIRST_RESULT: usize = 90;
pub const TRIPPED: usize = 94;

impl Interpreter {
    /// The probing block of `w` (which has G31).
    pub(super) fn probe_block(
        &mut self,
        w: &Words,
        line_no: u32,
        text: &str,
    ) -> Result<Block, Fail> {
        let at = w.g31.unwrap_or(w.first);
        let axes = w.axes[..self.n_axes].iter().filter(|a| a.is_some()).count();
        let own = 1 + axes + usize::from(w.n.is_some()) + usize::from(w.f.is_some());
        if usize::from(w.words) > own || axes == 0 {
            return fail(
                at,
                DiagCode::ProbeMoveInvalid,
                "G31 (probing) stands in a block of its own: N, G31, the axis words of its end and F",
            );
        }
        let old = self.state;
        if old.comp != CompMode::Off {
            return fail(
                at,
                DiagCode::ProbeUnderComp,
                "G31: no probing under radius compensation (program G40 first)",
            );
        }
        let mut st = old;
        let per_rev = self.feed_and_speed(w, &old, &mut st)?;
        let offset = self.positions(w, &old, &mut st, None);
        let (start, end) = (old.machine, st.prog + offset);
        if (end - start).norm(self.n_axes) < MIN_PROBE_MM {
            return fail(
                at,
                DiagCode::ProbeMoveInvalid,
                "G31: the probing move ends where it starts, it cannot find a contact",
            );
        }
        // G31 moves as G1 and leaves the motion mode as it was.
        st.modal.motion = Motion::Line;
        let mut out = self.motion(w, &st, &old, (start, end, offset), false, per_rev)?;
        st.modal.motion = old.modal.motion;
        let mv = ProbeMove {
            toward: true,
            must_trip: true,
        };
        if let BlockKind::Motion { path, .. } = &mut out.kind {
            *path = Path::Probe(mv);
        }
        let comp = self.comp_in_force(&st, None, at)?;
        let checked = Checked {
            st,
            edit: None,
            comp,
            m_codes: [None; 4],
            out,
        };
        let b = self.commit(w, line_no, text, checked);
        // Until the machine reports (a pass without one keeps this): as LinuxCNC's rs274.
        self.probe_result(&ProbeResult::without_machine(start, end));
        Ok(b)
    }

    /// The probing move of the last block ended as `r` reports: R90..R94 and the position
    /// the next block starts from.
    pub fn probe_result(&mut self, r: &ProbeResult) {
        let offset = self.length_offset(self.state.amp, None);
        self.state.machine = r.stop_mm;
        for k in 0..self.n_axes {
            self.state.prog[k] = r.stop_mm[k] - offset[k];
        }
        for k in 0..self.n_axes.min(4) {
            let mut v = r.trip_mm[k] - offset[k];
            if self.diameter_axis == Some(k) {
                v *= 2.0;
            }
            self.params[FIRST_RESULT + k] = Some(Num {
                value: v,
                point: true,
            });
        }
        self.params[TRIPPED] = Some(Num {
            value: if r.tripped { 1.0 } else { 0.0 },
            point: true,
        });
    }
}
