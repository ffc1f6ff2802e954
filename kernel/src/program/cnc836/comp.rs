//! Radius compensation words G40/G41/G42 (SPEC §4.1, §4.2): what the interpreter can check
//! block by block; the geometry is the compensation stage's.

use super::collect::Words;
use super::modal::{CompMode, State};
use super::{Fail, Interpreter, fail};
use crate::block::Comp;
use crate::diag::DiagCode;
use crate::offsets::TableEdit;

impl Interpreter {
    /// Radius compensation G40/G41/G42 (SPEC §4.1, §4.2): the side and radius in force, and
    /// the checks on starting, switching and cancelling it.
    pub(super) fn compensation(
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
        let comp = self.comp_in_force(st, edit, comp_at)?;
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

    /// The side and radius of the compensation in force in `st` (`at`: where an error points).
    #[inline]
    pub(super) fn comp_in_force(
        &self,
        st: &State,
        edit: Option<&TableEdit>,
        at: usize,
    ) -> Result<Comp, Fail> {
        Ok(match st.comp {
            CompMode::Off => Comp::Off,
            side => {
                let Some(radius_mm) = self.radius_of(st.d, edit) else {
                    return fail(
                        at,
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
        })
    }
}
