//! The blocks near a junction, walked once: the curvature-window search of a junction
//! (`Planner::box_window_bound`) looks up the tangents at several distances before and after
//! it for every speed it tries; walking the look-ahead window for each lookup dominated the
//! planner's cost (issue #32). The lookups give exactly what `Planner::tangents_near` gives.

use std::cell::Cell;

use super::budget::JunctionTurns;
use super::{Planner, SegPath};
use crate::units::AxesMm;

/// One block on a side of the junction.
#[derive(Clone, Copy, Debug)]
struct Entry {
    /// Path length between the junction and this block, mm (summed in walking order).
    walked_mm: f64,
    length_mm: f64,
    /// Index in the planner's window.
    k: usize,
    /// The walk ends with this block (a stop, or the end of the window).
    last: bool,
    /// An arc: its tangent depends on the distance.
    arc: bool,
    /// The tangent at the far end (seen from the junction): a line's tangent, and what
    /// the lookups beyond the last block of the walk give.
    tangent: AxesMm,
}

/// Turns looked up near a junction (without `dir`), the tangent's turn over the tick window
/// and the range of h (h_lo, h_hi] over which they are the same.
pub(super) type Lookup = (JunctionTurns, AxesMm, (f64, f64));

/// The blocks within a distance before and after junction `j` (the end of block `j`).
#[derive(Clone, Debug)]
pub(super) struct NearJunction {
    j: usize,
    ahead: Vec<Entry>,
    behind: Vec<Entry>,
    /// Distance covered on each side (∞ where the walk ended), mm.
    reach_ahead_mm: f64,
    reach_behind_mm: f64,
    /// The last turns the curvature search found within its bound, the tangent's turn over
    /// the tick window and the range of h (h_lo, h_hi] over which they are the same (the
    /// search's result lies in that range, mostly).
    last: Cell<Option<Lookup>>,
}

impl Default for NearJunction {
    fn default() -> Self {
        NearJunction {
            j: usize::MAX,
            ahead: Vec::new(),
            behind: Vec::new(),
            reach_ahead_mm: 0.0,
            reach_behind_mm: 0.0,
            last: Cell::new(None),
        }
    }
}

impl NearJunction {
    /// Forgets the walk (the window changed), keeping the allocations.
    pub(super) fn invalidate(&mut self) {
        self.j = usize::MAX;
        self.forget();
    }

    /// Keeps the turns of a lookup at h in `h_piece` (h_lo, h_hi].
    pub(super) fn remember(&self, t: JunctionTurns, window: AxesMm, h_piece: (f64, f64)) {
        self.last.set(Some((t, window, h_piece)));
    }

    fn forget(&self) {
        self.last.set(None);
    }

    /// The last turns looked up at junction `j` when h is well inside their range (the
    /// tangents at c·h are the same), with that range.
    pub(super) fn same_piece(&self, j: usize, h: f64) -> Option<Lookup> {
        if self.j != j {
            return None;
        }
        let (t, w, (lo, hi)) = self.last.get()?;
        let inside = lo < hi && lo * (1.0 + 1e-9) < h && h <= hi * (1.0 - 1e-9);
        inside.then_some((t, w, (lo, hi)))
    }

    /// Whether the walk was made for junction `j` and covers `d_mm` on both sides.
    pub(super) fn covers(&self, j: usize, d_mm: f64) -> bool {
        self.j == j && self.reach_ahead_mm >= d_mm && self.reach_behind_mm >= d_mm
    }
}

impl Planner {
    /// Walks the blocks within `d_mm` before and after junction `j` into `near` (its
    /// allocations are reused).
    pub(super) fn walk_near(&self, j: usize, d_mm: f64, near: &mut NearJunction) {
        near.j = j;
        near.forget();
        near.reach_ahead_mm = self.walk_side(j, true, d_mm, &mut near.ahead);
        near.reach_behind_mm = self.walk_side(j, false, d_mm, &mut near.behind);
    }

    fn walk_side(&self, j: usize, ahead: bool, d_mm: f64, out: &mut Vec<Entry>) -> f64 {
        out.clear();
        let mut walked = 0.0;
        // (Iterators over the ring: indexing it costs a wrap per block.)
        let mut push = |k: usize, p: &super::Pending, last: bool| {
            let arc = !matches!(p.seg.path, SegPath::Line { .. });
            out.push(Entry {
                walked_mm: walked,
                length_mm: p.seg.length_mm,
                k,
                last,
                arc,
                // (A line's t_start and t_end are the same vector.)
                tangent: if ahead { p.t_end } else { p.t_start },
            });
            if last {
                return Some(f64::INFINITY);
            }
            walked += p.seg.length_mm;
            (walked > d_mm).then_some(walked)
        };
        if ahead {
            let n = self.win.len();
            for (k, p) in self
                .win
                .range(j + 1..)
                .enumerate()
                .map(|(o, p)| (j + 1 + o, p))
            {
                if let Some(reach) = push(k, p, k + 1 >= n || !p.smooth) {
                    return reach;
                }
            }
        } else {
            let mut it = self.win.range(..=j).rev().peekable();
            let mut k = j;
            while let Some(p) = it.next() {
                let last = it.peek().is_none_or(|q| !q.smooth);
                if let Some(reach) = push(k, p, last) {
                    return reach;
                }
                k = k.wrapping_sub(1);
            }
        }
        f64::INFINITY
    }

    /// [`Planner::tangents_near`] at the distances `c·h` (`cs` ascending, > 0) from the walk
    /// `near` (which must cover them). `h_piece` is narrowed to the range of h over which
    /// every lookup stays on the same line (h_lo, h_hi]: the tangents, and so the turns, are
    /// the same for every h in it; a lookup on an arc narrows it to nothing.
    pub(super) fn tangents_from(
        &self,
        near: &NearJunction,
        ahead: bool,
        h: f64,
        cs: &[f64],
        out: &mut [AxesMm],
        h_piece: &mut (f64, f64),
    ) {
        let axes = self.cfg.axes;
        let entries = if ahead { &near.ahead } else { &near.behind };
        let mut e = 0;
        let mut n = 0;
        let mut before_mm = 0.0;
        while n < cs.len() {
            let x = &entries[e];
            let rest = cs[n] * h - x.walked_mm;
            if rest <= x.length_mm {
                out[n] = if x.arc {
                    let f = rest / x.length_mm;
                    let t = if ahead { f } else { 1.0 - f };
                    *h_piece = (h, h);
                    self.win[x.k].seg.path.tangent_at(t, axes)
                } else {
                    h_piece.0 = h_piece.0.max(before_mm / cs[n]);
                    h_piece.1 = h_piece.1.min((x.walked_mm + x.length_mm) / cs[n]);
                    x.tangent
                };
                n += 1;
                continue;
            }
            if x.last {
                out[n..cs.len()].fill(x.tangent);
                let end_mm = x.walked_mm + x.length_mm;
                h_piece.0 = h_piece.0.max(end_mm / cs[n]);
                return;
            }
            before_mm = x.walked_mm + x.length_mm;
            e += 1;
        }
    }

    /// Per axis the sum of the absolute turns |Δu_k| of the junctions between blocks of the
    /// walk `near` on one side of its junction, within each distance of `ds` (ascending;
    /// cumulative in `out`), the junction itself not counted. Unlike the turn of the
    /// tangent between two distances, turns of opposite sign do not cancel: the second
    /// difference of a tick weighs each turn by a different part of its step.
    pub(super) fn abs_turns_from(
        &self,
        near: &NearJunction,
        ahead: bool,
        ds: &[f64],
        out: &mut [AxesMm],
    ) {
        let axes = self.cfg.axes;
        let entries = if ahead { &near.ahead } else { &near.behind };
        let mut sum = AxesMm::ZERO;
        let mut n = 0;
        for pair in entries.windows(2) {
            let at = pair[1].walked_mm;
            while n < ds.len() && at > ds[n] {
                out[n] = sum;
                n += 1;
            }
            if n == ds.len() {
                return;
            }
            for k in 0..axes {
                sum[k] += (pair[1].tangent[k] - pair[0].tangent[k]).abs();
            }
        }
        out[n..ds.len()].fill(sum);
    }
}
