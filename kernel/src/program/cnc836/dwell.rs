//! Dwell `G4 F<seconds>` (docs/language.md, "Dwell"): F in a G4 block is the time, not a
//! feed, and the modal feed stays as it was (as Sinumerik reads `G4 F`).

use super::collect::Words;
use super::motion::Outcome;
use super::words::{Lexer, Token, Value};
use super::{Checked, Fail, Interpreter, fail};
use crate::block::{Block, BlockKind};
use crate::diag::DiagCode;

/// Longest dwell, seconds.
pub const MAX_DWELL_S: f64 = 99_999.999;

impl Interpreter {
    /// The dwell block of `w` (which has G4): the modal state is unchanged, the block waits
    /// `seconds` at rest.
    pub(super) fn dwell(&mut self, w: &Words, line_no: u32, text: &str) -> Result<Block, Fail> {
        let g4_at = w.g4.unwrap_or(w.first);
        let own = 1 + usize::from(w.n.is_some()) + usize::from(w.f.is_some());
        if usize::from(w.words) > own {
            return fail(
                other_word(text).unwrap_or(g4_at),
                DiagCode::DwellNotAlone,
                "a dwell stands in a block of its own: N, G4 and its time F<seconds>",
            );
        }
        let Some((f, f_at)) = w.f else {
            return fail(
                g4_at,
                DiagCode::DwellWithoutTime,
                "G4 (dwell) needs its time in seconds: G4 F2.5",
            );
        };
        if !(0.0..=MAX_DWELL_S).contains(&f.value) {
            return fail(
                f_at,
                DiagCode::WordOutOfRange,
                format!(
                    "the dwell time F{} is outside 0..{MAX_DWELL_S} seconds",
                    f.value
                ),
            );
        }
        let st = self.state;
        let comp = self.comp_in_force(&st, None, g4_at)?;
        let out = Outcome {
            kind: BlockKind::Dwell { seconds: f.value },
            warn: None,
            refined: None,
        };
        let checked = Checked {
            st,
            edit: None,
            comp,
            m_codes: [None; 4],
            out,
        };
        Ok(self.commit(w, line_no, text, checked))
    }
}

/// Where the first word of a dwell block that is not N, G4 or F starts.
fn other_word(text: &str) -> Option<usize> {
    Lexer::new(text)
        .map_while(Result::ok)
        .find(|t| match t.token {
            Token::Word {
                letter: b'N' | b'F',
                ..
            } => false,
            Token::Word {
                letter: b'G',
                value: Value::Num(n),
            } => n.value != 4.0,
            _ => true,
        })
        .map(|t| t.at)
}
