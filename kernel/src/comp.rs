//! Radius compensation G41/G42/G40 on equidistants (SPEC §4). Issue #4.
//!
//! The seam: a streaming stage between interpreter and planner. Programmed blocks go in with
//! [`Compensator::push`]; tool-centre blocks come out of [`Compensator::poll`] (lines and arcs,
//! including inserted corner arcs, each keeping the `seq` of its source block). The stage may
//! hold back up to 200 blocks (SPEC §4.1 bridging) before it can emit.
//!
//! Walking skeleton: compensation is not implemented yet; blocks pass through unchanged and a
//! block asking for G41/G42 is refused with an error rather than cut wrong.

use std::collections::VecDeque;

use crate::block::{Block, Comp};
use crate::diag::Diagnostic;

#[derive(Default)]
pub struct Compensator {
    out: VecDeque<Block>,
}

impl Compensator {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn push(&mut self, block: &Block) -> Result<(), Diagnostic> {
        if block.comp != Comp::Off {
            return Err(Diagnostic::error(
                block.n,
                block.line,
                0,
                "radius compensation G41/G42 is not available yet",
            ));
        }
        self.out.push_back(*block);
        Ok(())
    }

    /// No more blocks will come: everything held back becomes available.
    pub fn finish(&mut self) {}

    pub fn poll(&mut self) -> Option<Block> {
        self.out.pop_front()
    }
}
