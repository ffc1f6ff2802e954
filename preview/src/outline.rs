//! The outline of a whole program for a screen that draws it itself (issue #30: a CAM-size
//! program in the browser HMI): the programmed path (feed and rapid), the tool-centre path of
//! radius compensation and the junction dots (SPEC §7.5), kept in 3-D (X, Y, Z) on a grid
//! ([`crate::decimate`]) so its size is bounded whatever the program. The daemon collects it in
//! the pass that validates the selected program, so it is the program that runs; a screen asks
//! for a view ([`Outline::view`]): projected on a plane, clipped to the extent shown and
//! decimated again to its pixels.

use kernel::block::Block;
use kernel::comp::CompBlock;
use kernel::pipeline::{Flow, Observer};
use kernel::plan::{SegPath, Segment};
use kernel::program::Modal;
use kernel::{AxesMm, MAX_AXES};

use crate::collect::{Bounds, ToolCentre};
use crate::decimate::{DotSet, JunctionDot, Track};
use crate::pipeline::Sink;
use crate::plane::{arc_points, block_path};

/// Points kept per path (feed, rapid, tool centre) of an outline, and dots before merging.
pub const OUTLINE_POINTS: usize = 1 << 17;
const OUTLINE_DOTS: usize = 1 << 16;
/// Most points per path in a view (bounds what a screen receives and draws).
pub const VIEW_POINTS: usize = 1 << 16;
/// Grid an outline starts with, mm: a micrometre (each doubling of the grid on the way to
/// what a large program needs redraws the outline; a zoom finer than the outline's grid
/// makes a pass of its own anyway).
pub const START_CELL_MM: f64 = 1e-3;
/// Finest chord tolerance of arcs, mm (a micrometre: no screen shows finer).
const ARC_TOL_MIN_MM: f64 = 1e-3;
/// Junction dots closer than this many pixels are one dot in a view.
const DOT_MERGE_PX: f64 = 3.0;

/// A view plane by its axes: indices 0..3 into X, Y, Z.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Plane {
    pub h: usize,
    pub v: usize,
}

impl Plane {
    /// `xy`, `xz`, `yz`, `zx` ... (horizontal letter first).
    pub fn parse(s: &str) -> Option<Plane> {
        let idx = |c: char| "XYZ".find(c.to_ascii_uppercase());
        let mut it = s.chars();
        let (h, v) = (idx(it.next()?)?, idx(it.next()?)?);
        (it.next().is_none() && h != v).then_some(Plane { h, v })
    }

    fn project(&self, p: &[f64; 3]) -> [f64; 2] {
        [p[self.h], p[self.v]]
    }
}

/// Only what falls in `extent` of `plane` is kept (a zoomed view drawn finer than the whole
/// program's outline).
#[derive(Clone, Copy, Debug)]
pub struct Clip {
    pub plane: Plane,
    pub extent: Bounds,
}

/// The outline; feed it a pass (it is a [`Sink`] and a pipeline [`Observer`]).
#[derive(Clone, Debug)]
pub struct Outline {
    /// Machine axis index of X, Y and Z (`None`: the machine has no such axis, drawn at 0).
    dims: [Option<usize>; 3],
    feed: Track<3>,
    rapid: Track<3>,
    comp: Track<3>,
    dots: DotSet<3>,
    clip: Option<Clip>,
    pub smooth: u64,
    pub red: u64,
    pub blocks: u32,
    centre: ToolCentre,
    scratch: Vec<[f64; 3]>,
}

/// Polylines of a view: `xy` holds x, y per point; polyline k is points
/// `starts[k]..starts[k + 1]` (the last one to the end).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Runs {
    pub xy: Vec<f32>,
    pub starts: Vec<u32>,
}

/// What a screen draws of a program on one plane and extent.
#[derive(Clone, Debug, Default)]
pub struct View {
    pub feed: Runs,
    pub rapid: Runs,
    pub comp: Runs,
    /// x, y per dot (merged within [`DOT_MERGE_PX`]).
    pub smooth: Vec<f32>,
    pub red: Vec<f32>,
    /// The whole program on this plane (for "fit").
    pub bounds: Option<Bounds>,
    /// Resolution of the view, mm: no drawn point is farther than this from the path.
    pub cell_mm: f64,
}

impl Outline {
    /// An outline for a machine with these axis letters, of the whole program.
    pub fn new(axis_names: &[char]) -> Self {
        Self::clipped(axis_names, None, START_CELL_MM)
    }

    /// An outline of what falls in `clip`, starting at grid `cell_mm`.
    pub fn clipped(axis_names: &[char], clip: Option<Clip>, cell_mm: f64) -> Self {
        let dim = |c| axis_names.iter().position(|&a| a == c);
        let track = || Track::with_start(cell_mm, OUTLINE_POINTS);
        Outline {
            dims: [dim('X'), dim('Y'), dim('Z')],
            feed: track(),
            rapid: track(),
            comp: track(),
            dots: DotSet::new(OUTLINE_DOTS),
            clip,
            smooth: 0,
            red: 0,
            blocks: 0,
            centre: ToolCentre::default(),
            scratch: Vec::new(),
        }
    }

    /// The pass is over: frees what only collecting needs (the outline is kept to be read).
    pub fn freeze(&mut self) {
        for t in [&mut self.feed, &mut self.rapid, &mut self.comp] {
            t.freeze();
        }
        self.dots.shrink_to_fit();
        self.scratch = Vec::new();
    }

    /// Grid of the outline, mm (a view finer than this needs a clipped pass).
    pub fn cell_mm(&self) -> f64 {
        self.feed
            .cell()
            .max(self.rapid.cell())
            .max(self.comp.cell())
    }

    fn xyz(&self, p: &AxesMm) -> [f64; 3] {
        self.dims
            .map(|d| d.filter(|&i| i < MAX_AXES).map_or(0.0, |i| p[i]))
    }

    fn inside(&self, p: &[f64; 3], margin: f64) -> bool {
        self.clip.is_none_or(|c| {
            let q = c.plane.project(p);
            (0..2).all(|k| q[k] >= c.extent.min[k] - margin && q[k] <= c.extent.max[k] + margin)
        })
    }

    fn draw(&mut self, path: &SegPath, which: Which) {
        let track = match which {
            Which::Feed => &mut self.feed,
            Which::Rapid => &mut self.rapid,
            Which::Comp => &mut self.comp,
        };
        // Half the grid, but not below ARC_TOL_MIN_MM: on the first fine grid an arc would
        // otherwise be cut into the most chords a curve may have (MAX_ARC_POINTS).
        let tol = (track.cell() / 2.0).max(ARC_TOL_MIN_MM);
        self.scratch.clear();
        let from = self.xyz(&path.start());
        match *path {
            SegPath::Line { end, .. } => self.scratch.push(self.xyz(&end)),
            SegPath::Arc {
                radius_mm,
                sweep_rad,
                ..
            } => {
                let n = arc_points(radius_mm, sweep_rad, tol);
                for k in 1..=n {
                    let p = self.xyz(&path.point_at(k as f64 / n as f64));
                    self.scratch.push(p);
                }
            }
        }
        let Some(clip) = self.clip else {
            track_of(&mut self.feed, &mut self.rapid, &mut self.comp, which)
                .segment(from, &self.scratch);
            return;
        };
        // Clipped: pieces with an end inside (a margin of a tenth of the extent keeps the
        // lines that cross the border).
        let span =
            (clip.extent.max[0] - clip.extent.min[0]).max(clip.extent.max[1] - clip.extent.min[1]);
        let pts = std::mem::take(&mut self.scratch);
        let mut prev = from;
        for p in &pts {
            let keep = self.inside(&prev, span * 0.1) || self.inside(p, span * 0.1);
            let t = track_of(&mut self.feed, &mut self.rapid, &mut self.comp, which);
            if keep {
                t.segment(prev, std::slice::from_ref(p));
            } else {
                t.pen_up();
            }
            prev = *p;
        }
        self.scratch = pts;
    }

    /// The view of `plane` in `extent` (`None`: the whole program) at `width_px` × `height_px`.
    pub fn view(
        &self,
        plane: Plane,
        extent: Option<Bounds>,
        width_px: u32,
        height_px: u32,
    ) -> View {
        let bounds = self.bounds(plane);
        let shown = extent.or(bounds).unwrap_or(Bounds {
            min: [-10.0; 2],
            max: [10.0; 2],
        });
        let px_mm = ((shown.max[0] - shown.min[0]) / f64::from(width_px.max(1)))
            .max((shown.max[1] - shown.min[1]) / f64::from(height_px.max(1)))
            .max(1e-6);
        let cell = px_mm.max(self.cell_mm());
        let inside = |q: [f64; 2]| {
            let m = 2.0 * cell;
            (0..2).all(|k| q[k] >= shown.min[k] - m && q[k] <= shown.max[k] + m)
        };
        let runs = |t: &Track<3>| {
            let mut flat = Track::with_start(cell, VIEW_POINTS);
            for run in t.runs_at(0.0) {
                let mut prev = plane.project(&run[0]);
                flat.pen_up();
                for p in &run[1..] {
                    let q = plane.project(p);
                    if inside(prev) || inside(q) {
                        flat.segment(prev, &[q]);
                    } else {
                        flat.pen_up();
                    }
                    prev = q;
                }
            }
            let mut r = Runs::default();
            for run in flat.runs_at(cell) {
                r.starts.push((r.xy.len() / 2) as u32);
                r.xy.extend(run.iter().flat_map(|p| [p[0] as f32, p[1] as f32]));
            }
            r
        };
        let mut dots = DotSet::new(usize::MAX);
        for d in self.dots.at(0.0) {
            let q = plane.project(&d.at);
            if inside(q) {
                dots.add(JunctionDot { at: q, ..d.flat() });
            }
        }
        let (mut smooth, mut red) = (Vec::new(), Vec::new());
        for d in dots.at(cell * DOT_MERGE_PX) {
            let list = if d.red { &mut red } else { &mut smooth };
            list.extend([d.at[0] as f32, d.at[1] as f32]);
        }
        View {
            feed: runs(&self.feed),
            rapid: runs(&self.rapid),
            comp: runs(&self.comp),
            smooth,
            red,
            bounds,
            cell_mm: cell,
        }
    }

    /// The whole outline's box on `plane` (`None` when there is nothing to draw).
    fn bounds(&self, plane: Plane) -> Option<Bounds> {
        let mut b = Bounds::EMPTY;
        for t in [&self.feed, &self.rapid, &self.comp] {
            for run in t.runs_at(0.0) {
                for p in &run {
                    b.add(plane.project(p));
                }
            }
        }
        for d in self.dots.at(0.0) {
            b.add(plane.project(&d.at));
        }
        (!b.is_empty()).then_some(b)
    }
}

impl JunctionDot<3> {
    /// The dot's colour and count with a 2-D position placeholder.
    fn flat(&self) -> JunctionDot<2> {
        JunctionDot {
            at: [0.0; 2],
            red: self.red,
            count: self.count,
            label: None,
        }
    }
}

fn track_of<'a>(
    feed: &'a mut Track<3>,
    rapid: &'a mut Track<3>,
    comp: &'a mut Track<3>,
    which: Which,
) -> &'a mut Track<3> {
    match which {
        Which::Feed => feed,
        Which::Rapid => rapid,
        Which::Comp => comp,
    }
}

#[derive(Clone, Copy)]
enum Which {
    Feed,
    Rapid,
    Comp,
}

impl Sink for Outline {
    fn programmed(&mut self, b: &Block) {
        self.blocks += 1;
        if let Some((path, rapid)) = block_path(b) {
            self.draw(&path, if rapid { Which::Rapid } else { Which::Feed });
        }
    }

    fn compensated(&mut self, c: &CompBlock) {
        // The picture's rule (`collect::ToolCentre`, SPEC §4.2).
        if !self.centre.next(c).drawn() {
            self.comp.pen_up();
            return;
        }
        if let Some((path, _)) = block_path(&c.block) {
            self.draw(&path, Which::Comp);
        }
    }

    fn segment(&mut self, s: &Segment) {
        // The end of the program is not a junction.
        if s.last {
            return;
        }
        let at = self.xyz(&s.path.end());
        if !self.inside(&at, 0.0) {
            return;
        }
        let red = s.junction.is_red();
        if red {
            self.red += 1;
        } else {
            self.smooth += 1;
        }
        self.dots.add(JunctionDot {
            at,
            red,
            count: 1,
            label: None,
        });
    }
}

/// One polyline through `points` (machine axes, mm) on `plane` of a machine with these axis
/// letters, unreduced: a restart's approach, a few legs drawn apart from the outline.
pub fn polyline(axis_names: &[char], plane: Plane, points: &[AxesMm]) -> Runs {
    let dim = |c| axis_names.iter().position(|&a| a == c);
    let dims = [dim('X'), dim('Y'), dim('Z')];
    let at = |p: &AxesMm, d: usize| dims[d].map_or(0.0, |i| p[i]) as f32;
    let mut r = Runs::default();
    if !points.is_empty() {
        r.starts.push(0);
    }
    for p in points {
        r.xy.extend([at(p, plane.h), at(p, plane.v)]);
    }
    r
}

impl Observer for Outline {
    fn programmed(&mut self, b: &Block, _modal: &Modal) {
        Sink::programmed(self, b);
    }
    fn compensated(&mut self, c: &CompBlock) {
        Sink::compensated(self, c);
    }
    fn segment(&mut self, s: &Segment) -> Flow {
        Sink::segment(self, s);
        Flow::Go
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::PreviewOptions;
    use kernel::program::Setup;

    fn outline_of(text: &str) -> Outline {
        let opts = PreviewOptions::new(Setup::new(&['X', 'Y', 'Z']));
        let mut o = Outline::new(&opts.setup.axis_names);
        crate::pipeline::run(text, &opts, &mut o).expect("valid");
        o
    }

    #[test]
    fn a_small_program_is_kept_exactly_and_bounded_views_of_a_large_one() {
        let o = outline_of("N10 G0 X0 Y0\nN20 G1 X10 F600\nN30 Y10\nN40 X0\n");
        let v = o.view(Plane::parse("xy").unwrap(), None, 1000, 1000);
        assert_eq!(
            v.rapid.xy.len(),
            0,
            "G0 X0 Y0 from the origin draws nothing"
        );
        assert_eq!(v.feed.starts, vec![0]);
        assert_eq!(v.feed.xy, vec![0.0, 0.0, 10.0, 0.0, 10.0, 10.0, 0.0, 10.0]);
        assert_eq!(v.smooth.len() / 2 + v.red.len() / 2, 2);
        let b = v.bounds.unwrap();
        assert_eq!((b.min, b.max), ([0.0, 0.0], [10.0, 10.0]));
        // 60,000 blocks of a raster: the view is bounded, a zoomed clip is finer.
        let mut text = String::from("G0 X0 Y0\n");
        for i in 0..60_000 {
            let (row, col) = (i / 1000, i % 1000);
            let x = if row % 2 == 0 { col } else { 999 - col } as f64 * 0.1;
            text += &format!("G1 X{x:.3} Y{:.3} F3000\n", row as f64 * 0.1);
        }
        let o = outline_of(&text);
        let v = o.view(Plane::parse("xy").unwrap(), None, 1280, 800);
        assert!(v.feed.xy.len() / 2 <= VIEW_POINTS, "{}", v.feed.xy.len());
        assert!(o.cell_mm() > 0.0);
        let zoom = Bounds {
            min: [10.0, 2.0],
            max: [11.0, 3.0],
        };
        let opts = PreviewOptions::new(Setup::new(&['X', 'Y', 'Z']));
        let clip = Clip {
            plane: Plane::parse("xy").unwrap(),
            extent: zoom,
        };
        let mut fine = Outline::clipped(&opts.setup.axis_names, Some(clip), 1e-3);
        crate::pipeline::run(&text, &opts, &mut fine).expect("valid");
        let z = fine.view(clip.plane, Some(zoom), 1000, 1000);
        assert!(
            z.cell_mm < v.cell_mm && z.cell_mm <= 1e-3 + 1e-12,
            "{} {}",
            z.cell_mm,
            v.cell_mm
        );
        assert!(!z.feed.xy.is_empty());
        assert_eq!(Plane::parse("zx"), Some(Plane { h: 2, v: 0 }));
        assert_eq!(Plane::parse("xx"), None);
    }
}
