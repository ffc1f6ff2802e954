//! Geometry kept at the picture's resolution, not per block (bounded memory for programs of
//! millions of blocks, issue #10).
//!
//! Points snap to a square grid: a point in the same cell as the vertex before it replaces that
//! vertex instead of adding one, so the drawn path never strays more than one cell from the
//! true one. The grid starts far below any useful resolution (0.1 µm) and doubles whenever the
//! budget is exceeded, so memory stays bounded whatever the program; when the picture is laid
//! out, [`Track::runs_at`] decimates once more to the final pixel size.

/// Cell size the grids start with, mm: far below what any picture shows.
pub const START_CELL: f64 = 1e-4;

fn cell_of(p: [f64; 2], cell: f64) -> (i64, i64) {
    ((p[0] / cell).floor() as i64, (p[1] / cell).floor() as i64)
}

/// Open polylines with grid decimation.
#[derive(Clone, Debug)]
pub struct Track {
    pts: Vec<[f64; 2]>,
    /// Index in `pts` where each polyline starts.
    starts: Vec<usize>,
    cell: f64,
    budget: usize,
    /// Cell of the last vertex, while a polyline is open.
    last_cell: Option<(i64, i64)>,
}

impl Track {
    pub fn new(budget_points: usize) -> Self {
        Track {
            pts: Vec::new(),
            starts: Vec::new(),
            cell: START_CELL,
            budget: budget_points.max(16),
            last_cell: None,
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

    /// Continues the open polyline to `p`, or starts one at `from` when none is open or it
    /// ended elsewhere.
    pub fn segment(&mut self, from: [f64; 2], to: &[[f64; 2]]) {
        let joined = self.last_cell.is_some() && self.pts.last() == Some(&from);
        if !joined {
            self.starts.push(self.pts.len());
            self.pts.push(from);
            self.last_cell = Some(cell_of(from, self.cell));
        }
        for &p in to {
            self.push(p);
        }
        if self.pts.len() > self.budget {
            self.coarsen();
        }
    }

    /// Ends the open polyline (the next segment starts a new one even if it joins).
    pub fn pen_up(&mut self) {
        self.last_cell = None;
    }

    fn push(&mut self, p: [f64; 2]) {
        let c = cell_of(p, self.cell);
        let run_len = self.pts.len() - self.starts.last().copied().unwrap_or(0);
        // The first vertex of a polyline stays where it is (its start is exact).
        if self.last_cell == Some(c) && run_len > 1 {
            *self.pts.last_mut().expect("open polyline") = p;
        } else {
            self.pts.push(p);
            self.last_cell = Some(c);
        }
    }

    /// Doubles the cell until the points fit half the budget (amortised constant per point).
    fn coarsen(&mut self) {
        while self.pts.len() > self.budget / 2 {
            self.cell *= 2.0;
            let (pts, starts) = decimate(&self.pts, &self.starts, self.cell);
            self.pts = pts;
            self.starts = starts;
        }
        let open = self.last_cell.is_some();
        self.last_cell = if open {
            self.pts.last().map(|p| cell_of(*p, self.cell))
        } else {
            None
        };
    }

    /// The polylines decimated to `cell` (at least the track's own cell).
    pub fn runs_at(&self, cell: f64) -> Vec<Vec<[f64; 2]>> {
        let cell = cell.max(self.cell);
        let (pts, starts) = decimate(&self.pts, &self.starts, cell);
        let mut out = Vec::with_capacity(starts.len());
        for (k, &s) in starts.iter().enumerate() {
            let e = starts.get(k + 1).copied().unwrap_or(pts.len());
            out.push(pts[s..e].to_vec());
        }
        out
    }
}

fn decimate(pts: &[[f64; 2]], starts: &[usize], cell: f64) -> (Vec<[f64; 2]>, Vec<usize>) {
    let mut out = Vec::with_capacity(pts.len() / 2 + 2);
    let mut out_starts = Vec::with_capacity(starts.len());
    for (k, &s) in starts.iter().enumerate() {
        let e = starts.get(k + 1).copied().unwrap_or(pts.len());
        out_starts.push(out.len());
        let mut last = None;
        for (i, &p) in pts[s..e].iter().enumerate() {
            let c = cell_of(p, cell);
            if last == Some(c) && i > 1 {
                *out.last_mut().expect("run has a vertex") = p;
            } else {
                out.push(p);
                last = Some(c);
            }
        }
    }
    (out, out_starts)
}

/// A junction dot before drawing.
#[derive(Clone, Debug, PartialEq)]
pub struct JunctionDot {
    pub at: [f64; 2],
    pub red: bool,
    /// Junctions merged into this dot.
    pub count: u64,
    /// Label of the first red junction merged here.
    pub label: Option<String>,
}

/// Junction dots, merged per grid cell and colour when there are more than the budget.
#[derive(Clone, Debug)]
pub struct DotSet {
    dots: Vec<JunctionDot>,
    cell: f64,
    budget: usize,
}

impl DotSet {
    pub fn new(budget: usize) -> Self {
        DotSet {
            dots: Vec::new(),
            cell: START_CELL,
            budget: budget.max(16),
        }
    }

    pub fn len(&self) -> usize {
        self.dots.len()
    }

    pub fn is_empty(&self) -> bool {
        self.dots.is_empty()
    }

    pub fn add(&mut self, dot: JunctionDot) {
        self.dots.push(dot);
        if self.dots.len() > self.budget {
            while self.dots.len() > self.budget / 2 {
                self.cell *= 2.0;
                self.dots = merge(std::mem::take(&mut self.dots), self.cell);
            }
        }
    }

    /// The dots merged at `cell` (at least the set's own cell), smooth ones first so red ones
    /// are drawn on top.
    pub fn at(&self, cell: f64) -> Vec<JunctionDot> {
        let mut d = merge(self.dots.clone(), cell.max(self.cell));
        d.sort_by_key(|d| d.red);
        d
    }
}

/// Merges dots of the same colour in the same cell (keeps the first one's position and label).
fn merge(mut dots: Vec<JunctionDot>, cell: f64) -> Vec<JunctionDot> {
    // Stable sort: within a cell the earliest junction comes first.
    dots.sort_by_key(|d| (cell_of(d.at, cell), d.red));
    let mut out: Vec<JunctionDot> = Vec::with_capacity(dots.len());
    for d in dots {
        match out.last_mut() {
            Some(l) if l.red == d.red && cell_of(l.at, cell) == cell_of(d.at, cell) => {
                l.count += d.count;
            }
            _ => out.push(d),
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
        assert_eq!(runs.len(), 1);
        assert_eq!(runs[0][0], [0.0, 0.0]);
        assert_eq!(*runs[0].last().unwrap(), prev);
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
