//! The tool change (issue #47; the manuals have no T word, so this is a **decision**,
//! docs/language.md "Tool change"): `T<n>` names tool n, entry n of TAB0.KOR, for the next
//! `M6`; `M6` changes to it by hand: the program holds (as at M0, the spindle stopped) and
//! the blocks after it run with `D n` and `& n` selected.

use super::collect::Words;
use super::modal::{CompMode, State};
use super::{Fail, fail};
use crate::block::SpindleDir;
use crate::diag::DiagCode;

/// T and M6 of one block: the tool changed to, when the block has M6.
pub(super) fn tool_change(
    w: &Words,
    old: &State,
    st: &mut State,
    motion_words: bool,
) -> Result<Option<u8>, Fail> {
    if let Some((t, _)) = w.t {
        st.next_tool = t;
    }
    let Some(at) = w.m.iter().flatten().find(|(m, _)| *m == 6).map(|m| m.1) else {
        return Ok(None);
    };
    if motion_words || w.g92.is_some() {
        return fail(
            at,
            DiagCode::ToolChangeNotAlone,
            "M6 changes the tool at rest: write it in a block without axis words or G92 \
             (T<n> M6, then move)",
        );
    }
    let comp = w.comp.map_or(old.comp, |c| c.0);
    if comp != CompMode::Off {
        return fail(
            at,
            DiagCode::ToolChangeUnderComp,
            "M6 cannot change the tool while radius compensation is on: program G40 first",
        );
    }
    st.d = st.next_tool;
    st.amp = st.next_tool;
    st.modal.spindle.dir = SpindleDir::Stopped;
    Ok(Some(st.next_tool))
}
