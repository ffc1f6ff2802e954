//! The words of one block, collected and checked one by one before anything is interpreted:
//! the address table of the dialect and the table of its G functions.

use super::modal::{CompMode, Motion};
use super::words::{Lexer, Num, Token, Value};
use super::{Fail, Interpreter, fail};
use crate::block::{Continuity, Plane};
use crate::diag::DiagCode;
use crate::program::feed::FeedMode;
use crate::units::MAX_AXES;

/// Highest subprogram number (`%L1`..`%L9999`).
pub(super) const MAX_LABEL: u32 = 9999;
/// Most passes of one call (`L<n> P9999`).
pub(super) const MAX_COUNT: u32 = 9999;

/// The words of one block, collected before anything is interpreted.
#[derive(Default)]
pub(super) struct Words {
    pub(super) n: Option<u32>,
    pub(super) motion: Option<(Motion, usize)>,
    pub(super) plane: Option<(Plane, usize)>,
    pub(super) continuity: Option<(Continuity, usize)>,
    pub(super) comp: Option<(CompMode, usize)>,
    pub(super) absolute: Option<(bool, usize)>,
    pub(super) feed_mode: Option<(FeedMode, usize)>,
    pub(super) g76: Option<usize>,
    pub(super) g92: Option<usize>,
    pub(super) axes: [Option<(f64, usize)>; MAX_AXES],
    pub(super) i: Option<(Num, usize)>,
    pub(super) j: Option<(Num, usize)>,
    pub(super) e: Option<(Num, usize)>,
    pub(super) f: Option<(Num, usize)>,
    pub(super) s: Option<(Num, usize)>,
    pub(super) d: Option<(u8, usize)>,
    pub(super) amp: Option<(u8, usize)>,
    /// `T<n>`: the tool for the next M6 (docs/language.md, "Tool change").
    pub(super) t: Option<(u8, usize)>,
    pub(super) m: [Option<(u16, usize)>; 4],
    pub(super) assigns: [Option<(u8, Num)>; 16],
    /// G4: a dwell (its time is F).
    pub(super) g4: Option<usize>,
    /// G31: a probing move (`probe`).
    pub(super) g31: Option<usize>,
    /// `L<n>`: call of subprogram n; `P<count>`: how many times.
    pub(super) call: Option<(u16, usize)>,
    pub(super) count: Option<(u16, usize)>,
    /// M17 written as a number: the end of a subprogram.
    pub(super) ret: Option<usize>,
    /// Words and assignments in the block (saturating): what must stand alone checks it.
    pub(super) words: u8,
    pub(super) first: usize,
    pub(super) any: bool,
}

impl Interpreter {
    /// Lexes the line into `w`, checking each word on its own.
    pub(super) fn collect(&self, text: &str, w: &mut Words) -> Result<(), Fail> {
        for (k, lexed) in Lexer::new(text).enumerate() {
            let lexed = lexed?;
            let at = lexed.at;
            if k == 0 {
                w.first = at;
            }
            w.any = true;
            w.words = w.words.saturating_add(1);
            match lexed.token {
                Token::Assign { index, value } => {
                    let num = self.resolve(w, value, at)?;
                    let Some(slot) = w.assigns.iter_mut().find(|s| s.is_none()) else {
                        return fail(
                            at,
                            DiagCode::TooManyAssignments,
                            "more than 16 parameter assignments in one block",
                        );
                    };
                    *slot = Some((index, num));
                }
                Token::Word { letter, value } => {
                    let num = self.resolve(w, value, at)?;
                    self.word(w, (letter, value), num, at, k == 0)?;
                }
            }
        }
        Ok(())
    }

    /// Looks up a parameter: assignments earlier in this block first, then the committed table.
    pub(super) fn param_value(
        &self,
        w: &Words,
        index: u8,
        negate: bool,
        at: usize,
    ) -> Result<Num, Fail> {
        let pending = w
            .assigns
            .iter()
            .rev()
            .flatten()
            .find(|(i, _)| *i == index)
            .map(|(_, n)| *n);
        match pending.or(self.params[index as usize]) {
            Some(n) => Ok(Num {
                value: if negate { -n.value } else { n.value },
                point: n.point,
            }),
            None => fail(
                at,
                DiagCode::ParamUnassigned,
                format!("parameter R{index} is used before it was assigned"),
            ),
        }
    }

    pub(super) fn resolve(&self, w: &Words, value: Value, at: usize) -> Result<Num, Fail> {
        match value {
            Value::Num(n) => Ok(n),
            Value::Param { index, negate } => self.param_value(w, index, negate, at),
        }
    }

    pub(super) fn word(
        &self,
        w: &mut Words,
        (letter, value): (u8, Value),
        num: Num,
        at: usize,
        first: bool,
    ) -> Result<(), Fail> {
        if let Some(ax) = self.axis_letters[..self.n_axes]
            .iter()
            .position(|&a| a == letter)
        {
            // The name is formatted only for the error: every axis word of every block
            // passes here.
            return put_once(&mut w.axes[ax], num.value, at, || {
                let message = format!("axis {} is written twice in this block", letter as char);
                (DiagCode::WordTwice, message)
            });
        }
        match letter {
            b'N' => {
                if !first {
                    return fail(
                        at,
                        DiagCode::BlockNumberNotFirst,
                        "the block number N must be the first word of the block",
                    );
                }
                w.n = Some(int(num, "N", 0, 999_999).map_err(|e| Fail::new(at, e.code(), e))?);
            }
            b'G' => self.g_word(w, num, at)?,
            b'I' => once(&mut w.i, num, at, "I")?,
            b'J' => once(&mut w.j, num, at, "J")?,
            b'E' => once(&mut w.e, num, at, "E")?,
            b'F' => once(&mut w.f, num, at, "F")?,
            b'S' => once(&mut w.s, num, at, "S")?,
            b'D' => {
                let d = int(num, "D", 0, 99).map_err(|e| Fail::new(at, e.code(), e))?;
                once(&mut w.d, d as u8, at, "D")?
            }
            b'&' => {
                let d = int(num, "&", 0, 99).map_err(|e| Fail::new(at, e.code(), e))?;
                once(&mut w.amp, d as u8, at, "&")?
            }
            b'T' => {
                let t = int(num, "T", 0, 99).map_err(|e| Fail::new(at, e.code(), e))?;
                once(&mut w.t, t as u8, at, "T")?
            }
            b'M' if num.value == 17.0 && !num.point => subprogram_end(w, value, at)?,
            b'M' => m_word(w, num, at)?,
            b'L' => {
                let l = int(num, "L", 1, MAX_LABEL).map_err(|e| Fail::new(at, e.code(), e))?;
                once(&mut w.call, l as u16, at, "L")?
            }
            b'P' => {
                let p = int(num, "P", 1, MAX_COUNT).map_err(|e| Fail::new(at, e.code(), e))?;
                once(&mut w.count, p as u16, at, "P")?
            }
            _ => {
                return fail(
                    at,
                    DiagCode::UnknownAddress,
                    format!("unknown address {}", letter as char),
                );
            }
        }
        Ok(())
    }

    // A match over the dialect's G words: it reads better whole than split.
    pub(super) fn g_word(&self, w: &mut Words, num: Num, at: usize) -> Result<(), Fail> {
        const MOTION: &str = "motion (G0..G3)";
        const PLANE: &str = "plane (G17..G19)";
        const CONTINUITY: &str = "continuity (G23/G24/G98)";
        const COMP: &str = "radius compensation (G40..G42)";
        const DISTANCE: &str = "G90/G91";
        const FEED: &str = "feed (G94..G97)";
        let g = int(num, "G", 0, 999).map_err(|e| Fail::new(at, e.code(), e))?;
        match g {
            0 => group(&mut w.motion, Motion::Rapid, at, MOTION),
            1 => group(&mut w.motion, Motion::Line, at, MOTION),
            2 => group(&mut w.motion, Motion::Cw, at, MOTION),
            3 => group(&mut w.motion, Motion::Ccw, at, MOTION),
            17..=19 => {
                let p = [Plane::G17, Plane::G18, Plane::G19][g as usize - 17];
                let (a, b) = p.axes();
                if a >= self.n_axes || b >= self.n_axes {
                    return fail(
                        at,
                        DiagCode::PlaneNeedsAxis,
                        format!("G{g} needs a third axis; this machine has {}", self.n_axes),
                    );
                }
                group(&mut w.plane, p, at, PLANE)
            }
            23 => group(&mut w.continuity, Continuity::G23, at, CONTINUITY),
            24 => group(&mut w.continuity, Continuity::G24, at, CONTINUITY),
            98 => group(&mut w.continuity, Continuity::G98, at, CONTINUITY),
            40 => group(&mut w.comp, CompMode::Off, at, COMP),
            41 => group(&mut w.comp, CompMode::Left, at, COMP),
            42 => group(&mut w.comp, CompMode::Right, at, COMP),
            90 => group(&mut w.absolute, true, at, DISTANCE),
            91 => group(&mut w.absolute, false, at, DISTANCE),
            94 => group(&mut w.feed_mode, FeedMode::G94, at, FEED),
            95 => group(&mut w.feed_mode, FeedMode::G95, at, FEED),
            96 => group(&mut w.feed_mode, FeedMode::G96, at, FEED),
            97 => group(&mut w.feed_mode, FeedMode::G97, at, FEED),
            76 => {
                if w.g76.is_some() {
                    return fail(
                        at,
                        DiagCode::WordTwice,
                        "G76 is written twice in this block",
                    );
                }
                w.g76 = Some(at);
                Ok(())
            }
            92 => {
                if w.g92.is_some() {
                    return fail(
                        at,
                        DiagCode::WordTwice,
                        "G92 is written twice in this block",
                    );
                }
                w.g92 = Some(at);
                Ok(())
            }
            31 => {
                if w.g31.is_some() {
                    return fail(
                        at,
                        DiagCode::WordTwice,
                        "G31 is written twice in this block",
                    );
                }
                w.g31 = Some(at);
                Ok(())
            }
            4 => {
                if w.g4.is_some() {
                    return fail(at, DiagCode::WordTwice, "G4 is written twice in this block");
                }
                w.g4 = Some(at);
                Ok(())
            }
            _ => fail(
                at,
                DiagCode::UnknownGFunction,
                format!("G{g} is not a function of this controller"),
            ),
        }
    }
}

/// An M function (M17 aside, see [`subprogram_end`]): up to four per block.
fn m_word(w: &mut Words, num: Num, at: usize) -> Result<(), Fail> {
    let m = int(num, "M", 0, 999).map_err(|e| Fail::new(at, e.code(), e))? as u16;
    let Some(slot) = w.m.iter_mut().find(|s| s.is_none()) else {
        return fail(
            at,
            DiagCode::TooManyMFunctions,
            "more than 4 M functions in one block",
        );
    };
    *slot = Some((m, at));
    Ok(())
}

/// M17 ends a subprogram. The end of a subprogram is found in the text before it runs (a
/// definition passed over, the end of a program), so it must be written as a number.
fn subprogram_end(w: &mut Words, value: Value, at: usize) -> Result<(), Fail> {
    if matches!(value, Value::Param { .. }) {
        return fail(
            at,
            DiagCode::SubprogramSyntax,
            "M17 ends a subprogram: write it as M17, not with a parameter",
        );
    }
    if w.ret.is_some() {
        return fail(
            at,
            DiagCode::WordTwice,
            "M17 is written twice in this block",
        );
    }
    w.ret = Some(at);
    Ok(())
}

/// Puts word `v` (written at `at`) in its slot: once per block.
fn once<T>(slot: &mut Option<(T, usize)>, v: T, at: usize, what: &str) -> Result<(), Fail> {
    put_once(slot, v, at, || {
        let message = format!("{what} is written twice in this block");
        (DiagCode::WordTwice, message)
    })
}

/// Puts G function `v` of modal group `what` (written at `at`) in its slot: one per block.
fn group<T>(slot: &mut Option<(T, usize)>, v: T, at: usize, what: &str) -> Result<(), Fail> {
    put_once(slot, v, at, || {
        let message = format!("two G functions of the {what} group in one block");
        (DiagCode::GGroupConflict, message)
    })
}

/// Puts `v` (written at `at`) in its slot of the block's words; if the slot is taken, the
/// error `twice` makes (built only then: words are read a million times a second).
#[inline]
fn put_once<T>(
    slot: &mut Option<(T, usize)>,
    v: T,
    at: usize,
    twice: impl FnOnce() -> (DiagCode, String),
) -> Result<(), Fail> {
    if slot.is_some() {
        let (code, message) = twice();
        return fail(at, code, message);
    }
    *slot = Some((v, at));
    Ok(())
}

/// Why a word that takes a whole number in a range is refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub(super) enum WordError {
    #[error("{what} takes a whole number, not {value}")]
    NotWhole { what: &'static str, value: f64 },
    #[error("{what}{value} is outside {lo}..{hi}")]
    OutOfRange {
        what: &'static str,
        value: f64,
        lo: u32,
        hi: u32,
    },
}

impl WordError {
    /// Stable code (tests and HMIs match it; the message may improve).
    pub(super) fn code(&self) -> DiagCode {
        match self {
            WordError::NotWhole { .. } => DiagCode::WordNotWhole,
            WordError::OutOfRange { .. } => DiagCode::WordOutOfRange,
        }
    }
}

/// An integer word without a decimal point in `lo..=hi`.
pub(super) fn int(n: Num, what: &'static str, lo: u32, hi: u32) -> Result<u32, WordError> {
    let value = n.value;
    if n.point || value.fract() != 0.0 {
        return Err(WordError::NotWhole { what, value });
    }
    if value < lo as f64 || value > hi as f64 {
        return Err(WordError::OutOfRange {
            what,
            value,
            lo,
            hi,
        });
    }
    Ok(value as u32)
}
