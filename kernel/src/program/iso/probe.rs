//! G38.2..G38.5 as LinuxCNC 2.9 reads them: a straight move at the feed toward the axis
//! words' end that stops where the probe changes. The results go to #5061.. (where the
//! change was seen, program coordinates in the program's units) and #5070 (1: it changed),
//! once the machine reports them ([`super::Interpreter::probe_result`]); the next block
//! starts where the axes came to rest.

use super::Fail;
use super::exec::Exec;
use super::state::{CompSide, FeedMode, State};
use super::words::Words;
use crate::block::{BlockKind, Path};
use crate::diag::DiagCode;
use crate::probe::{ProbeMove, ProbeResult};

/// Shorter than this a move does not run (the planner's limit): a probing move that must
/// find its change cannot (LinuxCNC 2.9 would end it without contact on the machine).
const MIN_PROBE_MM: f64 = 1e-6;

/// The first of LinuxCNC's probe result parameters (#5061 X .. #5069 W) and the flag.
pub const FIRST_RESULT: usize = 5061;
pub const TRIPPED: usize = 5070;

impl Exec<'_> {
    /// A G38.x line: its move as a probing block.
    pub fn probe(&mut self, w: &Words, mv: ProbeMove) -> Result<(), Fail> {
        if self.st.comp != CompSide::Off {
            return Err(Fail::new(
                w.first,
                DiagCode::ProbeUnderComp,
                "G38: no probing under radius compensation (program G40 first)",
            ));
        }
        if self.st.feed_mode == FeedMode::InverseTime {
            return Err(Fail::new(
                w.first,
                DiagCode::ProbeMoveInvalid,
                "G38 cannot run in inverse time (G93)",
            ));
        }
        let start = self.st.machine;
        let end = self.end_point(w, false);
        let length = (end - start).norm(self.m.n_axes);
        if length < MIN_PROBE_MM && mv.must_trip {
            return Err(Fail::new(
                w.first,
                DiagCode::ProbeMoveInvalid,
                "G38.2/G38.4: the probing move ends where it starts, it cannot find a change",
            ));
        }
        let feed = self.feed_for(w.first, length)?;
        self.emit(
            BlockKind::Motion {
                start,
                end,
                path: Path::Probe(mv),
            },
            feed,
            [None; 4],
        );
        Ok(())
    }
}

/// LinuxCNC's axis order of #5061..#5069.
const RESULT_AXES: &[u8; 9] = b"XYZABCUVW";

/// The parameters and position after a probing move ended as `r` reports; `letters` are
/// the machine's axis letters.
pub fn apply_result(st: &mut State, letters: &[u8], r: &ProbeResult) -> Vec<(usize, f64)> {
    st.machine = r.stop_mm;
    let off = st.offset();
    let mut set: Vec<(usize, f64)> = letters
        .iter()
        .enumerate()
        .filter_map(|(k, l)| {
            let i = RESULT_AXES.iter().position(|a| a == l)?;
            Some((FIRST_RESULT + i, st.units(r.trip_mm[k] - off[k])))
        })
        .collect();
    set.push((TRIPPED, if r.tripped { 1.0 } else { 0.0 }));
    set
}
