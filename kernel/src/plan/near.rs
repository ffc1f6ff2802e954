//! The blocks near a junction, walked once: the curvature-window search of a junction
//! (`Planner::box_window_bound`) looks up the tangents at several distances before and after
//! it for every speed it tries; walking the look-ahead window for each lookup dominated the
//! planner's cost (issue #32). The lookups give exactly what `Planner::tangents_near` gives.

use std::cell::Cell;

use super::{Planner, SegPath};
use crate::units::{AxesMm, MAX_AXES};

/// One block on a side of the junction.
#[derive(Clone, Copy, Debug)]
struct Entry {
    /// Path length between the junction and this block, mm (summed in walking order).
    walked_mm: f64,
    length_mm: f64,
    /// Index in the planner's window.
    k: usize,
    /// An arc: its tangent depends on the distance. (A line's is read from the window when
    /// looked up: copying it here for every block walked cost more.)
    arc: bool,
}

/// Turns looked up near a junction (`JunctionTurns::normal_per_s` without the absolute
/// turns), the tangent's turn over the tick window, the absolute turns and the range of h
/// (h_lo, h_hi] over which all are the same (the absolute turns as a function of h). (The
/// turns alone, not the whole `JunctionTurns`: the search copies a lookup at every hit.)
pub(super) type Lookup = ([f64; MAX_AXES], AxesMm, AbsTurns, (f64, f64));

/// The absolute turns near a junction weighted as the setpoints' second differences weigh
/// them (issue #32): a tick point p with steps of at most S = v_ref·Ts = 2h on either side
/// weighs the turn Δu of a junction at distance d by S − d (the part of the step beyond it),
/// so per axis N_k·Ts ≤ v_ref·Σ|Δu_k|·(1 − d/S) over the junctions within S. Between two
/// junctions the sum is convex in p (each term falls or rises linearly, then stays 0), so
/// its largest value on a line is at one of its ends: the junction's own sum bounds every
/// tick whose step starts on the lines beside it. Turns of opposite sign do not cancel.
/// Kept as Σ|Δu_k| and Σ|Δu_k|·d over the junctions within S (the junction's own at d = 0):
/// the same junctions lie within S over a range of h.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct AbsTurns {
    sum: AxesMm,
    moment_mm: AxesMm,
    /// An arc lies within S: its turn is spread along it, where the sums (which count it at
    /// its far end) do not bound what the ticks see.
    arcs: bool,
}

impl AbsTurns {
    /// Whether the sums bound the turns every tick near the junction sees: only lines
    /// within S, so the setpoints' second differences are exactly the weighted turns.
    #[inline]
    pub(super) fn exact(&self) -> bool {
        !self.arcs
    }

    /// Σ|Δu_k|·(1 − d/S) for axis k at S = 2h.
    #[inline]
    pub(super) fn at(&self, k: usize, h: f64) -> f64 {
        self.sum[k] - self.moment_mm[k] / (2.0 * h)
    }

    /// Adds the junction's own turn, taken absolute per axis (at d = 0).
    #[inline]
    pub(super) fn add_own(&mut self, axes: usize, du_abs: &AxesMm) {
        self.add_abs(axes, du_abs, 0.0);
    }

    /// Adds the turn of a junction at distance `d_mm`, taken absolute per axis.
    #[inline]
    pub(super) fn add_abs(&mut self, axes: usize, du_abs: &AxesMm, d_mm: f64) {
        for k in 0..axes {
            let a = du_abs[k];
            self.sum[k] += a;
            self.moment_mm[k] += a * d_mm;
        }
    }
}

/// The blocks within a distance before and after junction `j` (the end of block `j`).
#[derive(Clone, Debug)]
pub(super) struct NearJunction {
    j: usize,
    ahead: Vec<Entry>,
    behind: Vec<Entry>,
    /// Distance covered on each side (∞ where the walk ended), mm.
    reach_ahead_mm: f64,
    reach_behind_mm: f64,
    /// Every block of the walk is longer than 1e-12 of its distance from the junction: then
    /// the lookup's test `x − walked ≤ length` (rounded) that holds at one entry holds at
    /// every later one (x − walked_{e+1} is at most a few ulp of walked_{e+1}, below
    /// length_{e+1}), so a lookup may start from the entry where the last one ended.
    sorted: bool,
    /// Where the first lookup of the last call ended, behind and ahead (index into the side's
    /// entries; see `tangents_from`).
    hint: [Cell<usize>; 2],
    /// The last turns the curvature search looked up, the tangent's turn over the tick
    /// window and the range of h (h_lo, h_hi] over which they are the same: the search's
    /// speeds close in on its result, so most of its evaluations fall in a range it has
    /// already seen, and the cap it settles on too (`junction_turns`). At most `PIECES`,
    /// the oldest replaced first.
    piece_h: [Cell<(f64, f64)>; PIECES],
    piece_turns: [Cell<([f64; MAX_AXES], AxesMm, AbsTurns)>; PIECES],
    /// Pieces kept, and where the next one goes once `PIECES` are.
    pieces: Cell<usize>,
    next_piece: Cell<usize>,
}

/// Ranges of h kept per junction (the search's evaluations see 2-4 of them).
const PIECES: usize = 8;

impl Default for NearJunction {
    fn default() -> Self {
        NearJunction {
            j: usize::MAX,
            ahead: Vec::new(),
            behind: Vec::new(),
            reach_ahead_mm: 0.0,
            reach_behind_mm: 0.0,
            sorted: false,
            hint: Default::default(),
            piece_h: Default::default(),
            piece_turns: Default::default(),
            pieces: Cell::new(0),
            next_piece: Cell::new(0),
        }
    }
}

impl NearJunction {
    /// Forgets the walk (the window changed), keeping the allocations.
    pub(super) fn invalidate(&mut self) {
        self.j = usize::MAX;
        self.forget();
    }

    /// Keeps the turns of a lookup at h in `h_piece` (h_lo, h_hi] (a lookup in a range
    /// already kept comes from it: not kept twice).
    pub(super) fn remember(&self, lookup: Lookup) {
        let (t, window, abs, h_piece) = lookup;
        let n = self.pieces.get();
        if self.piece_h[..n].iter().any(|p| p.get() == h_piece) {
            return;
        }
        let slot = if n < PIECES {
            self.pieces.set(n + 1);
            n
        } else {
            let slot = self.next_piece.get();
            self.next_piece.set((slot + 1) % PIECES);
            slot
        };
        self.piece_h[slot].set(h_piece);
        self.piece_turns[slot].set((t, window, abs));
    }

    fn forget(&self) {
        self.pieces.set(0);
        self.next_piece.set(0);
    }

    /// Turns looked up at junction `j` in a range that holds h well inside (the tangents at
    /// c·h are the same), with that range.
    #[inline]
    pub(super) fn same_piece(&self, j: usize, h: f64) -> Option<Lookup> {
        if self.j != j {
            return None;
        }
        // (The latest first: the search closes in on its result. The ranges apart from the
        // turns: a hit copies only its own.)
        let n = self.pieces.get();
        let slot = self.piece_h[..n].iter().rposition(|p| {
            let (lo, hi) = p.get();
            lo < hi && lo * (1.0 + 1e-9) < h && h <= hi * (1.0 - 1e-9)
        })?;
        let (t, window, abs) = self.piece_turns[slot].get();
        Some((t, window, abs, self.piece_h[slot].get()))
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
        let sorted = |side: &[Entry]| side.iter().all(|x| x.length_mm > 1e-12 * x.walked_mm);
        near.sorted = sorted(&near.ahead) && sorted(&near.behind);
        near.hint = Default::default();
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
                arc,
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

    /// The tangent at the far end of the walk's block `y` (seen from the junction): a line's
    /// tangent (its t_start and t_end are the same vector), and what the lookups beyond the
    /// last block of the walk give.
    #[inline(always)]
    fn far_tangent(&self, y: &Entry, ahead: bool) -> AxesMm {
        let p = &self.win[y.k];
        if ahead { p.t_end } else { p.t_start }
    }

    /// [`Planner::tangents_near`] at the distances `c·h` (`cs` ascending, > 0) from the walk
    /// `near` (which must cover them). `h_piece` is narrowed to the range of h over which
    /// every lookup stays on the same line (h_lo, h_hi]: the tangents, and so the turns, are
    /// the same for every h in it; a lookup on an arc narrows it to nothing.
    #[inline(always)]
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
        let far_end = |y: &Entry| self.far_tangent(y, ahead);
        // (The range's ends are finite: plain comparisons, not the NaN-aware max and min.)
        let raise = |lo: &mut f64, x: f64| {
            if x > *lo {
                *lo = x;
            }
        };
        // Each lookup takes the first entry from the previous lookup's on whose block its
        // distance ends (rest ≤ length, rounded as written here). Where that test, once
        // true, stays true (`sorted`), the first lookup starts from where the last call's
        // ended: the search's speeds are close, so that is mostly the entry itself.
        let hint = &near.hint[usize::from(ahead)];
        let mut e = if near.sorted { hint.get() } else { 0 };
        for (n, &c) in cs.iter().enumerate() {
            let x = c * h;
            let beyond = |y: &Entry| x - y.walked_mm > y.length_mm;
            if n == 0 && near.sorted {
                while e > 0 && !beyond(&entries[e - 1]) {
                    e -= 1;
                }
            }
            e += entries[e..]
                .iter()
                .position(|y| !beyond(y))
                .unwrap_or(entries.len() - e);
            if n == 0 {
                hint.set(e.min(entries.len().saturating_sub(1)));
            }
            let Some(y) = entries.get(e) else {
                // Beyond the last block of the walk (a stop or the window's end): its tangent.
                let Some(y) = entries.last() else { return };
                out[n..cs.len()].fill(far_end(y));
                raise(&mut h_piece.0, (y.walked_mm + y.length_mm) / c);
                return;
            };
            out[n] = if y.arc {
                let f = (x - y.walked_mm) / y.length_mm;
                let t = if ahead { f } else { 1.0 - f };
                *h_piece = (h, h);
                self.win[y.k].seg.path.tangent_at(t, axes)
            } else {
                // (`walked_mm` is the end of the block before, summed as it was walked.)
                let before_mm = if e == 0 { 0.0 } else { y.walked_mm };
                raise(&mut h_piece.0, before_mm / c);
                let end = (y.walked_mm + y.length_mm) / c;
                if end < h_piece.1 {
                    h_piece.1 = end;
                }
                far_end(y)
            };
        }
    }

    /// Adds the absolute turns of the junctions between blocks of the walk `near` on one side
    /// of its junction at distances d < 2h to `abs` (the junction itself not counted).
    /// Narrows `h_piece` to the range of h over which the same junctions lie within 2h.
    pub(super) fn abs_turns_from(
        &self,
        near: &NearJunction,
        ahead: bool,
        h: f64,
        abs: &mut AbsTurns,
        h_piece: &mut (f64, f64),
    ) {
        let entries = if ahead { &near.ahead } else { &near.behind };
        let s = 2.0 * h;
        abs.arcs |= entries.first().is_some_and(|y| y.arc);
        for pair in entries.windows(2) {
            let d = pair[1].walked_mm;
            // (Plain comparisons: the range's ends and d are finite.)
            if d >= s {
                if 0.5 * d < h_piece.1 {
                    h_piece.1 = 0.5 * d;
                }
                return;
            }
            if 0.5 * d > h_piece.0 {
                h_piece.0 = 0.5 * d;
            }
            // The turn of the tangent at each block's far end (seen from the junction), as
            // the lookups: |far(pair[1]) − far(pair[0])|.
            let p = &self.win[pair[1].k];
            let du = if ahead {
                &p.abs_du_end
            } else {
                &p.abs_du_start
            };
            abs.add_abs(self.cfg.axes, du, d);
            abs.arcs |= pair[1].arc;
        }
    }
}
