//! Restart in the middle of a program (issue #31; LinuxCNC's run-from-line, the block scan of
//! commercial controls): the blocks before block `N` are interpreted and compensated without
//! motion, so the modal state (G90/G91, feed, spindle and gear, plane, compensation and its
//! D, KŘR, continuity, dynamic set, G92 writes) is the state an uninterrupted run has at `N`;
//! then an approach moves from where the axes are to where the tool centre is at the start of
//! `N` (on the equidistant when `N` is compensated), and the run goes on from `N`.
//!
//! The approach (docs/operator.md "Restart from a block"), each leg ending at rest:
//! 1. rapid the axis perpendicular to the plane (Z for G17) up to the higher of where it is
//!    and where it must be (a retract, never a plunge);
//! 2. rapid the other axes to the start of `N`;
//! 3. the perpendicular axis down to the start of `N` at the feed in force at `N` (a rapid
//!    when no feed per minute is in force).
//!
//! On a machine without the perpendicular axis (a lathe in G18 with X and Z) the approach is
//! one rapid straight to the start of `N`.

use crate::block::{Block, BlockKind, Comp, Continuity, Feed, Path};
use crate::diag::{DiagCode, Diagnostic};
use crate::units::AxesMm;

/// Where a restart stands while the program streams.
#[derive(Clone, Debug)]
pub struct Restart {
    /// The `N` number of the block to restart from.
    n: u32,
    /// The interpreter's sequence number of that block, once it came.
    from_seq: Option<u32>,
    /// Where the axes are (the approach starts there).
    machine_mm: AxesMm,
    /// Where an uninterrupted run's tool centre is: the end of the last skipped move.
    tool_mm: AxesMm,
    axes: usize,
    /// The approach was made: everything passes from here on.
    approached: bool,
}

impl Restart {
    /// A restart from block `n` with the axes at `machine_mm`, the blocks before `n`
    /// interpreted from `origin_mm` (where the program's run started).
    pub fn new(n: u32, machine_mm: AxesMm, origin_mm: AxesMm, axes: usize) -> Self {
        Restart {
            n,
            from_seq: None,
            machine_mm,
            tool_mm: origin_mm,
            axes,
            approached: false,
        }
    }

    /// A programmed block: notes the sequence number of block `N` (its first occurrence).
    pub fn programmed(&mut self, b: &Block) {
        if self.from_seq.is_none() && b.n == Some(self.n) {
            self.from_seq = Some(b.seq);
        }
    }

    /// A tool-centre block: `None` while it comes before `N` (interpreted, not run);
    /// otherwise the approach legs to put before it (empty after the first).
    pub fn compensated(&mut self, b: &Block) -> Option<Vec<Block>> {
        if self.approached {
            return Some(Vec::new());
        }
        match self.from_seq {
            Some(seq) if b.seq >= seq => {
                self.approached = true;
                Some(approach(self.machine_mm, self.tool_mm, b, self.axes))
            }
            _ => {
                if let Some((_, end, _)) = b.motion() {
                    self.tool_mm = end;
                }
                None
            }
        }
    }

    /// The restart block has come: blocks run from here on.
    pub fn reached(&self) -> bool {
        self.approached
    }

    /// At the end of the program: an error when block `N` never came.
    pub fn finish(&self) -> Option<Diagnostic> {
        (!self.approached).then(|| {
            Diagnostic::error(
                DiagCode::RestartBlockNotFound,
                Some(self.n),
                0,
                0,
                format!(
                    "cannot restart from block N{}: the program has no such block with motion \
                     or function after it",
                    self.n
                ),
            )
        })
    }
}

/// The approach legs from `from` to the tool-centre position at the start of `target`
/// (`tool` when `target` does not move).
fn approach(from: AxesMm, tool: AxesMm, target: &Block, axes: usize) -> Vec<Block> {
    let to = match target.motion() {
        Some((start, _, _)) => start,
        None => tool,
    };
    let (a, b) = target.plane.axes();
    let perp = 3 - a - b; // the axis not in the plane: Z for G17, Y for G18, X for G19
    let mut legs = Vec::new();
    let mut at = from;
    let mut leg = |at: &mut AxesMm, end: AxesMm, path: Path| {
        if (0..axes).any(|i| (end[i] - at[i]).abs() > 1e-9) {
            legs.push(leg_block(target, *at, end, path));
            *at = end;
        }
    };
    if perp < axes {
        let safe = at[perp].max(to[perp]);
        let mut up = at;
        up[perp] = safe;
        leg(&mut at, up, Path::Rapid);
        let mut over = to;
        over[perp] = safe;
        leg(&mut at, over, Path::Rapid);
        let down = match target.feed {
            Feed::MmPerMin(f) if f > 0.0 => Path::Line,
            _ => Path::Rapid,
        };
        leg(&mut at, to, down);
    } else {
        leg(&mut at, to, Path::Rapid);
    }
    legs
}

/// One approach leg with block `N`'s technology (spindle, feed, dynamic set) and sequence
/// number, not compensated, ending at rest. It carries no `N` number and line 0: status and
/// the trajectory show it as the approach, not as a programmed block.
fn leg_block(n: &Block, start: AxesMm, end: AxesMm, path: Path) -> Block {
    Block {
        n: None,
        line: 0,
        kind: BlockKind::Motion { start, end, path },
        comp: Comp::Off,
        continuity: Continuity::G98,
        m: [None; 4],
        ..*n
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::block::{Plane, Spindle};

    fn block(seq: u32, n: u32, start: AxesMm, end: AxesMm) -> Block {
        Block {
            seq,
            n: Some(n),
            line: seq,
            kind: BlockKind::Motion {
                start,
                end,
                path: Path::Line,
            },
            feed: Feed::MmPerMin(500.0),
            plane: Plane::G17,
            comp: Comp::Off,
            continuity: Continuity::G23,
            dyn_set: 0,
            spindle: Spindle::default(),
            m: [None; 4],
        }
    }

    fn mm(x: f64, y: f64, z: f64) -> AxesMm {
        let mut a = AxesMm::default();
        a[0] = x;
        a[1] = y;
        a[2] = z;
        a
    }

    #[test]
    fn skips_the_blocks_before_n_then_retracts_moves_over_and_feeds_down() {
        let mut r = Restart::new(30, mm(0.0, 0.0, 50.0), mm(0.0, 0.0, 50.0), 3);
        let b10 = block(1, 10, mm(0.0, 0.0, 50.0), mm(10.0, 0.0, -5.0));
        let b20 = block(2, 20, mm(10.0, 0.0, -5.0), mm(10.0, 10.0, -5.0));
        let b30 = block(3, 30, mm(10.0, 10.0, -5.0), mm(0.0, 10.0, -5.0));
        for b in [&b10, &b20, &b30] {
            r.programmed(b);
        }
        assert_eq!(r.compensated(&b10), None);
        assert_eq!(r.compensated(&b20), None);
        let legs = r.compensated(&b30).unwrap();
        let ends: Vec<(AxesMm, Path)> = legs
            .iter()
            .map(|l| {
                let (_, e, p) = l.motion().unwrap();
                (e, p)
            })
            .collect();
        assert_eq!(
            ends,
            vec![
                (mm(10.0, 10.0, 50.0), Path::Rapid),
                (mm(10.0, 10.0, -5.0), Path::Line)
            ],
            "Z is already up: over, then down at feed"
        );
        assert!(legs.iter().all(|l| l.continuity == Continuity::G98));
        assert_eq!(r.compensated(&b30), Some(Vec::new()));
        assert_eq!(r.finish(), None);
    }

    #[test]
    fn a_missing_block_is_an_error_with_a_code() {
        let mut r = Restart::new(99, AxesMm::default(), AxesMm::default(), 3);
        let b = block(1, 10, AxesMm::default(), mm(1.0, 0.0, 0.0));
        r.programmed(&b);
        assert_eq!(r.compensated(&b), None);
        assert_eq!(r.finish().unwrap().code, DiagCode::RestartBlockNotFound);
    }
}
