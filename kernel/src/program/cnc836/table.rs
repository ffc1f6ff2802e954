//! The offset table from the program (SPEC §3): G92 writes, D selects the radius entry, &
//! the length entry.

use super::collect::Words;
use super::column;
use super::modal::State;
use super::{Fail, Interpreter, fail};
use crate::diag::{DiagCode, Diagnostic};
use crate::offsets::{self, TableEdit};
use crate::units::AxesMm;

impl Interpreter {
    /// G92 D<n> R0..R4: the table write the block makes (SPEC §3 (c)); without G92, D selects
    /// the offset entry.
    pub(super) fn table_write_or_d(
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

    /// Length offsets of entry `amp` for axes 1..4 (0 = none).
    pub(super) fn length_offset(&self, amp: u8, edit: Option<&TableEdit>) -> AxesMm {
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

    /// Radius of entry `d`, seeing a `G92` write of the same block.
    pub(super) fn radius_of(&self, d: u8, edit: Option<&TableEdit>) -> Option<f64> {
        let e = self.table.entry(d)?;
        Some(
            edit.filter(|ed| ed.entry == d)
                .and_then(|ed| ed.values[0])
                .unwrap_or(e.radius_mm),
        )
    }
}
