//! R383 (SPEC §7.2): a line shorter than R383 (G23, no M functions, same feed) is merged
//! into the next line: its start becomes the start of the next block, and it has no segment
//! of its own. When the next block cannot absorb it, it is emitted as a block of its own.

use super::{Planner, SegPath};
use crate::block::{Block, Continuity, Path};
use crate::units::AxesMm;

/// A short line held back for merging into the next block.
#[derive(Clone, Copy, Debug)]
pub(super) struct Carry {
    start: AxesMm,
    end: AxesMm,
    feed_mm_min: f64,
    block: Block,
    set: usize,
}

impl Planner {
    /// Start of the motion block now pushed: the held-back line's start when this block
    /// absorbs it (a G23 line at the same feed), else `start` (and the held-back line is
    /// emitted first).
    pub(super) fn merged_start(
        &mut self,
        block: &Block,
        path: Path,
        start: AxesMm,
        feed_mm_min: f64,
    ) -> AxesMm {
        let Some(c) = self.carry else { return start };
        if path == Path::Line && c.feed_mm_min == feed_mm_min && block.continuity == Continuity::G23
        {
            self.carry = None;
            c.start
        } else {
            self.flush_carry();
            start
        }
    }

    /// Holds a short G23 line without M functions back for merging (R383 ≥ 0); true when
    /// held.
    pub(super) fn hold_back_short_line(
        &mut self,
        block: &Block,
        path: Path,
        start: AxesMm,
        end: AxesMm,
        length_mm: f64,
        feed_mm_min: f64,
    ) -> bool {
        let Some(m) = self.cfg.envelope.merge_len_mm else {
            return false;
        };
        let short = path == Path::Line && length_mm < m;
        if !(short && block.continuity == Continuity::G23 && block.m.iter().all(Option::is_none)) {
            return false;
        }
        let set = self.dyn_set_of(block);
        self.carry = Some(Carry {
            start,
            end,
            feed_mm_min,
            block: *block,
            set,
        });
        true
    }

    /// Emits a held-back short line as a block of its own (the next block cannot absorb it).
    pub(super) fn flush_carry(&mut self) {
        let Some(c) = self.carry.take() else { return };
        let path = SegPath::Line {
            start: c.start,
            end: c.end,
        };
        let length_mm = path.length(self.cfg.axes);
        if length_mm > 1e-9 {
            self.append(&c.block, path, length_mm, false, c.feed_mm_min, c.set);
        }
    }
}
