//! Geometry kept at the picture's resolution, not per block (bounded memory for programs of
//! millions of blocks, issue #10).
//!
//! Points snap to a square grid. A point in the same cell as the vertex before it replaces that
//! vertex instead of adding one, and a step between two cells already joined by a drawn edge
//! is not drawn again (a pocket passes the same places many times), so the drawing never
//! strays more than one cell from the true path and its size grows with the area covered,
//! not with the path length. The grid starts far below any useful resolution (0.1 µm) and
//! doubles whenever the budget is exceeded, so memory stays bounded whatever the program; when
//! the picture is laid out, [`Track::runs_at`] decimates once more to the final pixel size.

use std::collections::hash_map::Entry;

use rustc_hash::{FxHashMap, FxHashSet as HashSet};

/// Cell size the grids start with, mm: far below what any picture shows.
pub const START_CELL: f64 = 1e-4;

/// A grid cell of an `N`-dimensional grid (2: a picture's plane; 3: the server's outline of a
/// program, projected later onto any plane).
type Cell<const N: usize> = [i32; N];

fn cell_of<const N: usize>(p: [f64; N], cell: f64) -> Cell<N> {
    p.map(|v| floor_i32(v / cell))
}

/// `q.floor() as i32` without a call to `floor` (the baseline x86-64 has no instruction for
/// it; every point and dot of a picture comes here): `as` rounds towards zero, so one less
/// where that rounded a negative number up. `as` saturates (coordinates beyond the grid's
/// range share the border cells) and takes NaN to 0, as `floor` then `as` do.
fn floor_i32(q: f64) -> i32 {
    let t = q as i32;
    if f64::from(t) > q {
        t.saturating_sub(1)
    } else {
        t
    }
}

fn edge_key<const N: usize>(a: Cell<N>, b: Cell<N>) -> (Cell<N>, Cell<N>) {
    if a <= b { (a, b) } else { (b, a) }
}

/// Where the drawing stands.
#[derive(Clone, Copy, Debug)]
struct Pen<const N: usize> {
    at: [f64; N],
    cell: Cell<N>,
    /// `at` is the last vertex of the last polyline (drawing continues it).
    drawn: bool,
}

/// Open polylines with grid decimation.
#[derive(Clone, Debug)]
pub struct Track<const N: usize = 2> {
    pts: Vec<[f64; N]>,
    /// Index in `pts` where each polyline starts.
    starts: Vec<usize>,
    /// Edges between cells already drawn.
    edges: HashSet<(Cell<N>, Cell<N>)>,
    cell: f64,
    budget: usize,
    pen: Option<Pen<N>>,
}

impl<const N: usize> Track<N> {
    pub fn new(budget_points: usize) -> Self {
        Self::with_cell(START_CELL, budget_points.max(16))
    }

    /// A track whose grid starts at `cell` mm (coarser than [`START_CELL`]: a view that
    /// cannot show finer anyway).
    pub fn with_start(cell: f64, budget_points: usize) -> Self {
        Self::with_cell(cell.max(START_CELL), budget_points.max(16))
    }

    fn with_cell(cell: f64, budget: usize) -> Self {
        Track {
            pts: Vec::new(),
            starts: Vec::new(),
            edges: HashSet::default(),
            cell,
            budget,
            pen: None,
        }
    }

    /// Current grid cell, mm: curves should be flattened to about this accuracy.
    pub fn cell(&self) -> f64 {
        self.cell
    }

    pub fn points(&self) -> usize {
        self.pts.len()
    }

    pub fn is_empty(&self) -> bool {
        self.pts.is_empty()
    }

    /// A piece of path from `from` through `to`: continues the drawing when `from` is where
    /// the last piece ended, else starts a new polyline.
    pub fn segment(&mut self, from: [f64; N], to: &[[f64; N]]) {
        if self.pen.is_none_or(|p| p.at != from) {
            self.pen = Some(Pen {
                at: from,
                cell: cell_of(from, self.cell),
                drawn: false,
            });
        }
        for &p in to {
            self.push(p);
        }
        if self.pts.len() > self.budget {
            self.coarsen();
        }
    }

    /// Frees what only drawing more needs (the set of drawn edges), for a track kept to be
    /// read: segments added later are no longer checked against what is drawn.
    pub fn freeze(&mut self) {
        self.edges = HashSet::default();
        self.pts.shrink_to_fit();
        self.pen = None;
    }

    /// Ends the drawing here (the next segment starts a new polyline even if it joins).
    pub fn pen_up(&mut self) {
        self.pen = None;
    }

    fn push(&mut self, p: [f64; N]) {
        let c = cell_of(p, self.cell);
        let Some(pen) = self.pen.as_mut() else {
            self.pen = Some(Pen {
                at: p,
                cell: c,
                drawn: false,
            });
            return;
        };
        if c == pen.cell {
            let run_len = self.pts.len() - self.starts.last().copied().unwrap_or(0);
            // The first vertex of a polyline stays where it is (its start is exact).
            if pen.drawn && run_len > 1 {
                *self.pts.last_mut().expect("open polyline") = p;
                pen.at = p;
            } else if pen.drawn {
                self.pts.push(p);
                pen.at = p;
            }
            return;
        }
        if self.edges.insert(edge_key(pen.cell, c)) {
            if !pen.drawn {
                self.starts.push(self.pts.len());
                self.pts.push(pen.at);
            }
            self.pts.push(p);
            *pen = Pen {
                at: p,
                cell: c,
                drawn: true,
            };
        } else {
            // Already drawn: move without drawing.
            *pen = Pen {
                at: p,
                cell: c,
                drawn: false,
            };
        }
    }

    /// The polylines redrawn on a grid of `cell`.
    fn redrawn(&self, cell: f64, budget: usize) -> Track<N> {
        let mut t = Track::with_cell(cell, budget);
        t.edges.reserve(self.pts.len());
        t.pts.reserve(self.pts.len());
        for (k, &s) in self.starts.iter().enumerate() {
            let e = self.starts.get(k + 1).copied().unwrap_or(self.pts.len());
            t.pen = None;
            t.segment(self.pts[s], &self.pts[s + 1..e]);
        }
        t
    }

    /// Doubles the cell until the points fit half the budget (amortised constant per point:
    /// the points added since the last coarsening are already minimal on the current grid).
    fn coarsen(&mut self) {
        let pen = self.pen;
        let last = self.pts.last().copied();
        let target = self.budget / 2;
        let first = self.redrawn(self.cell * 2.0, usize::MAX);
        let mut t = if first.pts.len() <= target {
            first
        } else {
            // (Dropped first: the search's redraws are the peak of a large pass.)
            drop(first);
            self.redrawn_to_fit(target)
        };
        while t.pts.len() > target {
            t = t.redrawn(t.cell * 2.0, usize::MAX);
        }
        self.pts = t.pts;
        self.starts = t.starts;
        self.edges = t.edges;
        self.cell = t.cell;
        self.pen = pen.map(|p| Pen {
            at: p.at,
            cell: cell_of(p.at, self.cell),
            drawn: p.drawn && self.pts.last().copied() == last && last == Some(p.at),
        });
    }

    /// The track redrawn at the first doubling of the cell (from two on: one did not fit)
    /// that keeps at most `target` points, found without a redraw at every doubling on the
    /// way (a dozen from the start grid to what a large program needs): the grids nest (cell
    /// index `i` at one doubling is `i >> 1`), so an upper bound of the points at every
    /// doubling comes from one pass without hashing (a redraw keeps at most two points per
    /// step into another cell), and redraws halve the range between the doubling known not
    /// to fit and the one the bound says fits.
    fn redrawn_to_fit(&self, target: usize) -> Track<N> {
        let at = |k: usize| (0..k).fold(self.cell, |c, _| c * 2.0);
        // apart[k]: steps between consecutive points whose cells differ up to k - 1
        // doublings and coincide from k on.
        let mut apart = [0usize; 34];
        for (n, &s) in self.starts.iter().enumerate() {
            let e = self.starts.get(n + 1).copied().unwrap_or(self.pts.len());
            let mut prev: Option<Cell<N>> = None;
            for &p in &self.pts[s..e] {
                let c = cell_of(p, self.cell);
                if let Some(q) = prev {
                    let level = (0..N)
                        .map(|i| 32 - (c[i] ^ q[i]).leading_zeros() as usize)
                        .max()
                        .unwrap_or(0);
                    apart[level] += 1;
                }
                prev = Some(c);
            }
        }
        let bound = |k: usize| 2 * apart[k + 1..].iter().sum::<usize>();
        // (Beyond 30 doublings the cell is kilometres: the caller doubles on.)
        let mut hi = (2..=30).find(|&k| bound(k) <= target).unwrap_or(30);
        let mut lo = 1;
        let mut fit = None;
        while hi - lo > 1 {
            let mid = (lo + hi) / 2;
            let t = self.redrawn(at(mid), usize::MAX);
            if t.pts.len() <= target {
                hi = mid;
                fit = Some(t);
            } else {
                lo = mid;
            }
        }
        fit.unwrap_or_else(|| self.redrawn(at(hi), usize::MAX))
    }

    /// The polylines decimated to `cell` (at least the track's own cell).
    pub fn runs_at(&self, cell: f64) -> Vec<Vec<[f64; N]>> {
        let redrawn;
        let t = if cell > self.cell {
            redrawn = self.redrawn(cell, usize::MAX);
            &redrawn
        } else {
            self
        };
        let mut out = Vec::with_capacity(t.starts.len());
        for (k, &s) in t.starts.iter().enumerate() {
            let e = t.starts.get(k + 1).copied().unwrap_or(t.pts.len());
            out.push(t.pts[s..e].to_vec());
        }
        out
    }
}

/// A junction dot before drawing.
#[derive(Clone, Debug, PartialEq)]
pub struct JunctionDot<const N: usize = 2> {
    pub at: [f64; N],
    pub red: bool,
    /// Junctions merged into this dot.
    pub count: u64,
    /// Label of the first red junction merged here.
    pub label: Option<String>,
}

/// Junction dots, merged per grid cell and colour when there are more than the budget.
#[derive(Clone, Debug)]
pub struct DotSet<const N: usize = 2> {
    dots: Vec<JunctionDot<N>>,
    cell: f64,
    budget: usize,
    /// The cell of the last dot of `dots` when it is the one added last (`None` after a
    /// merge).
    last_cell: Option<Cell<N>>,
}

impl<const N: usize> DotSet<N> {
    pub fn new(budget: usize) -> Self {
        DotSet {
            dots: Vec::new(),
            cell: START_CELL,
            budget: budget.max(16),
            last_cell: None,
        }
    }

    pub fn len(&self) -> usize {
        self.dots.len()
    }

    pub fn is_empty(&self) -> bool {
        self.dots.is_empty()
    }

    pub fn add(&mut self, dot: JunctionDot<N>) {
        // In the cell and colour of the dot added before: merged into it at once, as the
        // next merge would (the first one's position and label, the counts summed).
        // Consecutive junctions of a dense path mostly are, and a merge costs more.
        let cell = cell_of(dot.at, self.cell);
        if let Some(last) = self.dots.last_mut()
            && self.last_cell == Some(cell)
            && last.red == dot.red
        {
            last.count += dot.count;
            return;
        }
        self.dots.push(dot);
        self.last_cell = Some(cell);
        if self.dots.len() > self.budget {
            self.last_cell = None;
            // Dots added since the last merge may share cells with earlier ones: merge at
            // the current cell first, coarsen only if that is not enough.
            self.dots = merge(std::mem::take(&mut self.dots), self.cell);
            if self.dots.len() > self.budget / 2 {
                self.coarsen();
            }
        }
    }

    /// Doubles the cell until the dots fit half the budget, merging them at the first
    /// doubling that fits. The grids nest (cell index `i` at one doubling is `i >> 1`), so a
    /// merge at a coarser cell is the same as merges at every doubling on the way; and the
    /// number of dots only falls as the cell grows. So the doubling is searched for: an upper
    /// bound (a dot per change of cell or colour between consecutive dots, no hashing) gives
    /// one that fits, then counting halves the range, and one merge is made, instead of a
    /// merge at every doubling (a dozen from the start grid to what a large program needs).
    fn coarsen(&mut self) {
        let target = self.budget / 2;
        let base: Vec<(Cell<N>, bool)> = self
            .dots
            .iter()
            .map(|d| (cell_of(d.at, self.cell), d.red))
            .collect();
        // apart[k]: consecutive dots whose cells (or colours) differ up to k - 1 doublings
        // and coincide from k on (33: never).
        let mut apart = [0usize; 34];
        for w in base.windows(2) {
            let ((a, ra), (b, rb)) = (w[0], w[1]);
            let level = if ra != rb {
                33
            } else {
                (0..N)
                    .map(|i| 32 - (a[i] ^ b[i]).leading_zeros() as usize)
                    .max()
                    .unwrap_or(0)
            };
            apart[level] += 1;
        }
        // Dots apart after k doublings: pairs whose level is above k.
        let bound = |k: usize| 1 + apart[k + 1..].iter().sum::<usize>();
        // (Beyond 30 doublings the cell is kilometres: the loop below takes over.)
        let mut hi = (1..=30).find(|&k| bound(k) <= target).unwrap_or(30);
        let mut lo = 0;
        while hi - lo > 1 {
            let mid = (lo + hi) / 2;
            let mut seen = HashSet::default();
            seen.reserve(base.len());
            let n = base
                .iter()
                .filter(|(c, red)| seen.insert((c.map(|i| i >> mid), *red)))
                .count();
            if n <= target {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        for _ in 0..hi {
            self.cell *= 2.0;
        }
        self.dots = merge(std::mem::take(&mut self.dots), self.cell);
        // The indices saturate at the edge of the grid's range: should the bound be wrong
        // there, the doubling goes on as before.
        while self.dots.len() > target {
            self.cell *= 2.0;
            self.dots = merge(std::mem::take(&mut self.dots), self.cell);
        }
    }

    /// Frees the spare capacity (a set kept to be read).
    pub fn shrink_to_fit(&mut self) {
        self.dots.shrink_to_fit();
    }

    /// The dots merged at `cell` (at least the set's own cell), smooth ones first so red ones
    /// are drawn on top.
    pub fn at(&self, cell: f64) -> Vec<JunctionDot<N>> {
        let mut d = merge(self.dots.clone(), cell.max(self.cell));
        d.sort_by_key(|d| d.red);
        d
    }
}

/// Merges dots of the same colour in the same cell (keeps the first one's position and label,
/// and program order).
fn merge<const N: usize>(dots: Vec<JunctionDot<N>>, cell: f64) -> Vec<JunctionDot<N>> {
    let mut index: FxHashMap<(Cell<N>, bool), usize> =
        FxHashMap::with_capacity_and_hasher(dots.len(), Default::default());
    let mut out: Vec<JunctionDot<N>> = Vec::with_capacity(dots.len() / 2 + 1);
    for d in dots {
        match index.entry((cell_of(d.at, cell), d.red)) {
            Entry::Occupied(e) => out[*e.get()].count += d.count,
            Entry::Vacant(e) => {
                e.insert(out.len());
                out.push(d);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_below_the_cell_and_bounded_above_the_budget() {
        let mut t = Track::new(1000);
        t.segment([0.0, 0.0], &[[1.0, 0.0], [1.0, 1.0]]);
        t.segment([1.0, 1.0], &[[2.0, 1.0]]);
        t.segment([5.0, 5.0], &[[6.0, 5.0]]);
        let runs = t.runs_at(0.0);
        assert_eq!(
            runs,
            vec![
                vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [2.0, 1.0]],
                vec![[5.0, 5.0], [6.0, 5.0]]
            ]
        );
        // A zig-zag of 100,000 points over 10 mm stays within the budget, and every kept
        // vertex is a point of the path.
        let mut z = Track::new(1000);
        let mut prev = [0.0, 0.0];
        for i in 1..100_000 {
            let p = [i as f64 * 1e-4, (i % 2) as f64];
            z.segment(prev, &[p]);
            prev = p;
        }
        assert!(z.points() <= 1000, "{}", z.points());
        assert!(z.cell() > START_CELL);
        let runs = z.runs_at(0.0);
        assert_eq!(runs[0][0], [0.0, 0.0]);
        // Every point of the path is within one cell (diagonal) of a kept vertex or edge
        // end: checked for the end point and a point in the middle.
        let near = |q: [f64; 2]| {
            runs.iter()
                .flatten()
                .any(|v| (v[0] - q[0]).hypot(v[1] - q[1]) <= 2.0 * z.cell() * 1.5)
        };
        assert!(near(prev) && near([5.0, 1.0]));
        // A path that retraces itself is drawn once.
        let mut r = Track::new(1000);
        for _ in 0..100 {
            r.segment([0.0, 0.0], &[[10.0, 0.0], [10.0, 10.0]]);
            r.pen_up();
        }
        assert_eq!(r.points(), 3);
    }

    /// A small deterministic generator (no dependency).
    fn next(state: &mut u64) -> f64 {
        *state ^= *state << 13;
        *state ^= *state >> 7;
        *state ^= *state << 17;
        (*state >> 11) as f64 / (1u64 << 53) as f64
    }

    #[test]
    fn coarsening_finds_the_doubling_a_merge_at_every_doubling_finds() {
        let mut state = 0x2545_f491_4f6c_dd1d;
        for round in 0..40 {
            // Dots on a random walk of a random step (some of them red), some far apart.
            let step = [1e-4, 1e-3, 0.05, 3.0][round % 4];
            let mut at = [0.0, 0.0, 0.0];
            let dots: Vec<JunctionDot<3>> = (0..300)
                .map(|i| {
                    for v in &mut at {
                        *v += (next(&mut state) - 0.5) * step * if i % 97 == 0 { 1e4 } else { 1.0 };
                    }
                    JunctionDot {
                        at,
                        red: next(&mut state) < 0.2,
                        count: 1,
                        label: None,
                    }
                })
                .collect();
            let mut fast = DotSet::new(64);
            fast.dots = merge(dots.clone(), fast.cell);
            let mut slow = fast.clone();
            if fast.dots.len() <= 32 {
                continue;
            }
            fast.coarsen();
            while slow.dots.len() > 32 {
                slow.cell *= 2.0;
                slow.dots = merge(std::mem::take(&mut slow.dots), slow.cell);
            }
            assert_eq!(fast.cell, slow.cell, "round {round}");
            assert_eq!(fast.dots, slow.dots, "round {round}");
        }
    }

    #[test]
    fn a_track_coarsens_to_the_first_doubling_a_redraw_of_it_fits() {
        let mut state = 0x9e37_79b9_7f4a_7c15;
        for round in 0..40 {
            let step = [1e-4, 1e-3, 0.05, 3.0][round % 4];
            let mut t = Track::<2>::new(usize::MAX);
            let mut at = [0.0, 0.0];
            for i in 0..400 {
                let from = at;
                for v in &mut at {
                    *v += (next(&mut state) - 0.5) * step;
                }
                if i % 50 == 0 {
                    t.pen_up();
                }
                t.segment(from, &[at]);
            }
            let target = t.points() / 8;
            let slow = (1..)
                .map(|k| t.redrawn(t.cell * f64::from(1u32 << k), usize::MAX))
                .find(|r| r.points() <= target)
                .unwrap();
            let fast = t.redrawn_to_fit(target);
            assert!(fast.points() <= target, "round {round}");
            assert_eq!(fast.cell, slow.cell, "round {round}");
            assert_eq!(fast.pts, slow.pts, "round {round}");
        }
    }

    #[test]
    fn floor_without_floor() {
        let cases = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            2.999,
            -2.999,
            1e9,
            -1e9,
            2147483647.5,
            -2147483648.5,
            3e9,
            -3e9,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            1e-300,
            -1e-300,
        ];
        for q in cases {
            assert_eq!(floor_i32(q), q.floor() as i32, "{q}");
        }
    }

    #[test]
    fn dots_merge_per_cell_and_colour_keeping_counts() {
        let mut s = DotSet::new(16);
        for i in 0..1000 {
            s.add(JunctionDot {
                at: [(i % 10) as f64, 0.0],
                red: i % 3 == 0,
                count: 1,
                label: None,
            });
        }
        assert!(s.len() <= 16);
        let d = s.at(0.0);
        assert_eq!(d.iter().map(|d| d.count).sum::<u64>(), 1000);
        assert_eq!(
            d.iter().filter(|d| d.red).map(|d| d.count).sum::<u64>(),
            334
        );
    }
}
