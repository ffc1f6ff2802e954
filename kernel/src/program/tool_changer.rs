//! The automatic tool changer (issue #47, docs/setup.md "Automatic tool changer"): `M6`
//! does not hold for the operator; it becomes technology blocks, one per step of the
//! configured sequence of M functions on outputs and inputs (unclamp, confirm, clamp ...).
//! Dialect-independent: the stream expands the `ToolChange` block either front-end makes.

use crate::block::{Block, BlockKind};
use crate::diag::{DiagCode, Diagnostic};
use crate::outputs::{MFunction, MFunctions, ProgramOutputs};

/// The M code the tool-number step and the first step carry (the block was `M6`).
const M6: u16 = 6;

/// How M6 changes tools on a machine with a changer.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ToolChanger {
    /// M functions run in order at each M6 (each bound to outputs or inputs).
    pub sequence: Vec<u16>,
    /// Outputs (indices of the configuration's list) that carry the tool number in binary,
    /// bit 0 first, switched before the first step; empty: none.
    pub tool_number_outputs: Vec<u8>,
}

impl ToolChanger {
    /// The mask of the tool-number outputs.
    fn number_mask(&self) -> u64 {
        self.tool_number_outputs
            .iter()
            .fold(0, |m, &k| m | 1u64 << (k & 63))
    }

    /// The tool-number step as an M function: its bits on, the other number outputs off.
    /// `None` when `tool` does not fit in the outputs.
    fn number_function(&self, tool: u8) -> Option<MFunction> {
        let bits = self.tool_number_outputs.len().min(64);
        if bits < 8 && u32::from(tool) >> bits != 0 {
            return None;
        }
        let on = self
            .tool_number_outputs
            .iter()
            .enumerate()
            .filter(|(bit, _)| *bit < 8 && tool & (1 << bit) != 0)
            .fold(0, |m, (_, &k)| m | 1u64 << (k & 63));
        Some(MFunction {
            code: M6,
            on,
            off: self.number_mask() & !on,
            ..MFunction::default()
        })
    }

    /// The blocks an M6 block `tc` (kind `ToolChange`) becomes, in order, with consecutive
    /// `seq` from its own; the last one's outputs are the modal state after the change.
    pub fn expand(&self, tc: &Block, m_outputs: &MFunctions) -> Result<Vec<Block>, Diagnostic> {
        let BlockKind::ToolChange { tool } = tc.kind else {
            return Ok(vec![*tc]);
        };
        let mut steps = Vec::with_capacity(self.sequence.len() + 1);
        let step = |outputs: ProgramOutputs, m: [Option<u16>; 4], k: usize| Block {
            seq: tc.seq + k as u32,
            kind: BlockKind::Technology,
            m,
            spindle: crate::block::Spindle {
                outputs,
                ..tc.spindle
            },
            ..*tc
        };
        // The first step keeps the M6 block's own M functions and what they switched.
        let mut st = tc.spindle.outputs;
        let mut first_m = tc.m;
        if !self.tool_number_outputs.is_empty() {
            let f = self
                .number_function(tool)
                .ok_or_else(|| too_large(tc, tool, self))?;
            st.on = (st.on | f.on) & !f.off;
            st.touched = true;
            steps.push(step(st, first_m, steps.len()));
            st = st.carried();
            first_m = [None; 4];
        }
        for &code in &self.sequence {
            let m = if first_m.iter().any(Option::is_some) {
                with_code(first_m, code)
            } else {
                [Some(code), None, None, None]
            };
            m_outputs.apply(code, &mut st);
            st.touched = true;
            steps.push(step(st, m, steps.len()));
            st = st.carried();
            first_m = [None; 4];
        }
        if steps.is_empty() {
            // No step configured: the change is a technology block (the spindle stopped).
            steps.push(step(st, first_m, 0));
        }
        Ok(steps)
    }
}

/// `m` with `code` added in its first free place (the M6 block's own codes stay).
fn with_code(mut m: [Option<u16>; 4], code: u16) -> [Option<u16>; 4] {
    if let Some(slot) = m.iter_mut().find(|c| c.is_none() || **c == Some(M6)) {
        *slot = Some(code);
    }
    m
}

fn too_large(tc: &Block, tool: u8, tc_cfg: &ToolChanger) -> Diagnostic {
    let bits = tc_cfg.tool_number_outputs.len();
    Diagnostic::error(
        DiagCode::ToolNumberBeyondOutputs,
        tc.n,
        tc.line,
        0,
        format!(
            "T{tool}: the changer's {bits} tool number outputs carry tools 0 to {} \
             ([tool_change] tool_number_outputs)",
            (1u32 << bits.min(8)) - 1
        ),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn changer() -> (ToolChanger, MFunctions) {
        let mut m = MFunctions::default();
        m.add(MFunction {
            code: 61,
            on: 1 << 4,
            ..MFunction::default()
        });
        m.add(MFunction {
            code: 62,
            wait: 1 << 2,
            ..MFunction::default()
        });
        m.add(MFunction {
            code: 63,
            off: 1 << 4,
            wait: 1 << 3,
            ..MFunction::default()
        });
        let tc = ToolChanger {
            sequence: vec![61, 62, 63],
            tool_number_outputs: vec![1, 2],
        };
        (tc, m)
    }

    #[test]
    fn the_number_fits_or_is_refused() {
        let (tc, _) = changer();
        let f = tc.number_function(2).unwrap();
        assert_eq!((f.on, f.off), (0b100, 0b010));
        assert_eq!(tc.number_function(3).unwrap().on, 0b110);
        assert!(tc.number_function(4).is_none());
        let wide = ToolChanger {
            tool_number_outputs: (0..8).collect(),
            ..tc
        };
        assert_eq!(wide.number_function(255).unwrap().on, 0xFF);
    }

    #[test]
    fn with_code_replaces_m6_and_keeps_the_rest() {
        assert_eq!(
            with_code([Some(8), Some(6), None, None], 61),
            [Some(8), Some(61), None, None]
        );
    }
}
