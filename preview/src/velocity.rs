//! Velocity over time of the planned run (SPEC §7.5, the manual's speed trace with white
//! vertical lines per block): the segments go through the same 4 ms interpolator the machine
//! runs, at 100 % override, and every tick is recorded into a bounded [`Series`].

use std::collections::VecDeque;

use kernel::interp::{InterpState, Interpolator};
use kernel::plan::Segment;
use kernel::{AxesMm, MAX_AXES, TS_S};

use crate::collect::Bounds;
use crate::layout;
use crate::paging::Page;
use crate::pipeline::Sink;
use crate::scene::{Anchor, Item, Map, Plot, Rgb, Scene, Stroke, WorldItem};
use crate::series::{Sample, Series};

/// Time buckets kept (about two per pixel of a wide picture).
const BUCKETS: usize = 4096;

pub const SPEED: Rgb = Rgb(0, 90, 230);
pub const FEED: Rgb = Rgb(230, 120, 0);
pub const BOUNDARY: Rgb = Rgb(205, 205, 205);
pub const RED_BOUNDARY: Rgb = Rgb(240, 130, 130);
const AXIS_COLORS: [Rgb; MAX_AXES] = [
    Rgb(210, 40, 40),
    Rgb(30, 150, 60),
    Rgb(40, 80, 220),
    Rgb(160, 60, 170),
    Rgb(0, 150, 160),
    Rgb(120, 90, 40),
];

#[derive(Clone, Copy, Debug)]
struct SegInfo {
    seq: u32,
    feed_mm_s: f64,
    red: bool,
}

/// The velocity plot's sink: feeds the interpolator and records its ticks.
pub struct Recorder {
    interp: Interpolator,
    page: Page,
    /// Segments pushed to the interpolator and not yet left behind.
    pending: VecDeque<SegInfo>,
    pub series: Series,
    tick: u64,
    last_seq: Option<u32>,
    /// Positions of the last two ticks (for the axis accelerations).
    prev: [AxesMm; 2],
    axes: usize,
    done: bool,
    /// Ticks the plot runs at most ([`crate::PreviewOptions::plot_max_ticks`]).
    max_ticks: u64,
    /// Where the plot stopped at `max_ticks`: the block (`N`, line) then running.
    pub cut: Option<(Option<u32>, u32)>,
    /// The block of the last tick (`N`, line).
    at: (Option<u32>, u32),
}

impl Recorder {
    pub fn new(axes: usize, start: AxesMm, page: Page, max_ticks: u64) -> Self {
        Recorder {
            interp: Interpolator::new(axes, start),
            page,
            pending: VecDeque::new(),
            series: Series::new(BUCKETS),
            tick: 0,
            last_seq: None,
            prev: [start; 2],
            axes,
            done: false,
            max_ticks,
            cut: None,
            at: (None, 0),
        }
    }

    fn step(&mut self) {
        if self.tick >= self.max_ticks {
            // The plot's work grows with the motion's duration, not with the text (a short
            // program can travel for days): it stops at its bound and says so.
            self.cut = Some(self.at);
            self.done = true;
            return;
        }
        // A program stop (M0, M1, a tool change) is resumed at once: the plot is the
        // machining, not the operator's time (and a held interpolator would never end).
        if self.interp.at_program_stop() {
            self.interp.resume();
        }
        let out = self.interp.tick();
        self.tick += 1;
        self.at = (out.n, out.line);
        let mut acc = [0.0; MAX_AXES];
        for (i, a) in acc.iter_mut().enumerate().take(self.axes) {
            *a = (out.position[i] - 2.0 * self.prev[1][i] + self.prev[0][i]) / (TS_S * TS_S);
        }
        self.prev = [self.prev[1], out.position];
        // Segments left behind: the one the position lies on is the first with its seq.
        // The last segment left behind ends at the junction just crossed.
        let mut prev_red = false;
        while self.pending.front().is_some_and(|s| s.seq < out.seq) {
            prev_red = self.pending.pop_front().is_some_and(|s| s.red);
        }
        let feed = self.pending.front().map_or(0.0, |s| s.feed_mm_s);
        let boundary = self.last_seq.is_some_and(|q| q != out.seq);
        self.last_seq = Some(out.seq);
        if out.seq >= self.page.end {
            self.done = true;
        }
        if self.page.contains(out.seq) && out.state != InterpState::Idle {
            self.series.record(
                self.tick,
                &Sample {
                    v: out.path_v_mm_s * 60.0,
                    feed: feed * 60.0,
                    acc,
                    boundary,
                    red_boundary: boundary && prev_red,
                },
            );
        }
    }
}

impl Sink for Recorder {
    fn segment(&mut self, s: &Segment) {
        if self.done {
            return;
        }
        let info = SegInfo {
            seq: s.seq,
            feed_mm_s: s.feed_mm_s,
            red: s.junction.is_red() && !s.last,
        };
        let mut seg = *s;
        // Tick only when the buffer is full, so the interpolator always sees its whole
        // look-ahead (the end of what it has is a stop point for it).
        while !self.done {
            if !self.interp.has_room() {
                self.step();
                continue;
            }
            match self.interp.push(seg) {
                Ok(()) => {
                    self.pending.push_back(info);
                    break;
                }
                // Refused with room left: an empty segment, nothing to run.
                Err(_) if self.interp.has_room() => break,
                Err(back) => seg = back,
            }
        }
    }

    fn done(&self) -> bool {
        self.done
    }

    fn finish(&mut self) {
        // Run out what is buffered (bounded by `max_ticks`).
        while self.interp.state() != InterpState::Idle && !self.done {
            self.step();
        }
    }
}

/// Lays out the velocity plot: path speed and programmed feed over time with block
/// boundaries, and (optionally) a second panel with the per-axis accelerations.
pub fn layout(
    r: &Recorder,
    title: &str,
    axis_names: &[char],
    with_accel: bool,
    width_px: u32,
    height_px: u32,
) -> Scene {
    let (w, h) = (f64::from(width_px), f64::from(height_px));
    let mut scene = Scene::page(width_px, height_px, title);
    let s = &r.series;
    let tpb = s.ticks_per_bucket as f64;
    let t_of = |k: usize| (s.first_tick.unwrap_or(0) as f64 + k as f64 * tpb) * TS_S;
    let t0 = t_of(0);
    let t1 = (s.last_tick as f64 * TS_S).max(t0 + TS_S);
    let v_top = s
        .buckets
        .iter()
        .filter(|b| b.ticks > 0)
        .fold(1.0f64, |m, b| m.max(b.v_max).max(b.feed_max))
        * 1.08;
    let (left, right, top) = (80.0, 30.0, 76.0);
    let pw = w - left - right;
    let speed_h = if with_accel {
        (h - top - 100.0) * 0.6
    } else {
        h - top - 48.0
    };
    let rect = [left, top, pw, speed_h.max(40.0)];
    let map = Map {
        sx: pw / (t1 - t0),
        sy: -rect[3] / v_top,
        tx: left - t0 * pw / (t1 - t0),
        ty: top + rect[3],
    };
    let vis = Bounds {
        min: [t0, 0.0],
        max: [t1, v_top],
    };
    layout::axes(&mut scene, rect, &map, &vis, ("time s", "speed mm/min"));
    scene.items.push(Item::Plot(Plot {
        id: "speed",
        rect_px: rect,
        map,
        attrs: vec![("data-ticks-per-bucket", s.ticks_per_bucket.to_string())],
        items: speed_items(s, &t_of, v_top),
    }));
    legend(&mut scene, left);
    if with_accel {
        accel_panel(
            &mut scene,
            r,
            axis_names,
            [
                left,
                top + rect[3] + 56.0,
                pw,
                h - (top + rect[3] + 56.0) - 44.0,
            ],
            t0,
            t1,
        );
    }
    scene
}

/// The speed panel's curves: block boundaries first (under the curves; red after a red
/// junction), then the programmed feed and the path speed, each as the min..max of its
/// buckets, a run broken where no tick fell.
fn speed_items(s: &Series, t_of: &dyn Fn(usize) -> f64, v_top: f64) -> Vec<WorldItem> {
    let tpb = s.ticks_per_bucket as f64;
    let mut grey = Vec::new();
    let mut red = Vec::new();
    let mut speed = Vec::new();
    let mut feed = Vec::new();
    let mut run_v: Vec<[f64; 2]> = Vec::new();
    let mut run_f: Vec<[f64; 2]> = Vec::new();
    for (k, b) in s.buckets.iter().enumerate() {
        let t = t_of(k);
        if b.ticks == 0 {
            for (run, out) in [(&mut run_v, &mut speed), (&mut run_f, &mut feed)] {
                if !run.is_empty() {
                    out.push(std::mem::take(run));
                }
            }
            continue;
        }
        if b.red_boundaries > 0 {
            red.push(vec![[t, 0.0], [t, v_top]]);
        } else if b.boundaries > 0 {
            grey.push(vec![[t, 0.0], [t, v_top]]);
        }
        let tm = t + 0.5 * (tpb - 1.0) * TS_S;
        run_v.push([tm, b.v_min]);
        if b.v_max > b.v_min {
            run_v.push([tm, b.v_max]);
        }
        run_f.push([tm, b.feed_min]);
        if b.feed_max > b.feed_min {
            run_f.push([tm, b.feed_max]);
        }
    }
    speed.push(run_v);
    feed.push(run_f);
    vec![
        WorldItem::Path {
            class: "boundary",
            stroke: Stroke::solid(BOUNDARY, 1.0),
            runs: grey,
        },
        WorldItem::Path {
            class: "boundary-red",
            stroke: Stroke::solid(RED_BOUNDARY, 1.0),
            runs: red,
        },
        WorldItem::Path {
            class: "feed",
            stroke: FEED_STROKE,
            runs: feed,
        },
        WorldItem::Path {
            class: "speed",
            stroke: Stroke::solid(SPEED, 1.6),
            runs: speed,
        },
    ]
}

/// The programmed feed's dashed line.
const FEED_STROKE: Stroke = Stroke {
    color: FEED,
    width_px: 1.5,
    dash_px: Some([6.0, 4.0]),
};

/// The legend in a row under the title (8 px per character: the bitmap font's advance).
fn legend(scene: &mut Scene, left: f64) {
    let mut x = left;
    let y = 44.0;
    for (stroke, text) in [
        (Stroke::solid(SPEED, 1.6), "path speed"),
        (FEED_STROKE, "programmed feed (G0: rapid speed)"),
        (Stroke::solid(BOUNDARY, 2.0), "block boundary"),
        (
            Stroke::solid(RED_BOUNDARY, 2.0),
            "boundary after a red junction",
        ),
    ] {
        scene.line([x, y - 4.0], [x + 24.0, y - 4.0], stroke);
        scene.text([x + 30.0, y], 12.0, Anchor::Start, "legend", text);
        x += 30.0 + 8.0 * text.len() as f64 + 24.0;
    }
}

fn accel_panel(scene: &mut Scene, r: &Recorder, names: &[char], rect: [f64; 4], t0: f64, t1: f64) {
    let s = &r.series;
    let tpb = s.ticks_per_bucket as f64;
    let first = s.first_tick.unwrap_or(0) as f64;
    let axes = r.axes.min(names.len());
    let a_top = s
        .buckets
        .iter()
        .filter(|b| b.ticks > 0)
        .flat_map(|b| (0..axes).map(move |i| b.acc_max[i].abs().max(b.acc_min[i].abs())))
        .fold(1.0f64, f64::max)
        * 1.08;
    let map = Map {
        sx: rect[2] / (t1 - t0),
        sy: -rect[3] / (2.0 * a_top),
        tx: rect[0] - t0 * rect[2] / (t1 - t0),
        ty: rect[1] + rect[3] / 2.0,
    };
    let vis = Bounds {
        min: [t0, -a_top],
        max: [t1, a_top],
    };
    layout::axes(
        scene,
        rect,
        &map,
        &vis,
        ("time s", "axis acceleration mm/s²"),
    );
    let mut items = Vec::new();
    for (i, &color) in AXIS_COLORS.iter().enumerate().take(axes) {
        let mut runs = Vec::new();
        let mut run = Vec::new();
        for (k, b) in s.buckets.iter().enumerate() {
            if b.ticks == 0 {
                if !run.is_empty() {
                    runs.push(std::mem::take(&mut run));
                }
                continue;
            }
            let tm = (first + (k as f64 + 0.5) * tpb) * TS_S;
            run.push([tm, b.acc_min[i]]);
            if b.acc_max[i] > b.acc_min[i] {
                run.push([tm, b.acc_max[i]]);
            }
        }
        runs.push(run);
        items.push(WorldItem::Path {
            class: "accel",
            stroke: Stroke::solid(color, 1.0),
            runs,
        });
    }
    scene.items.push(Item::Plot(Plot {
        id: "accel",
        rect_px: rect,
        map,
        attrs: Vec::new(),
        items,
    }));
    let mut x = rect[0] + rect[2] - 70.0 * axes as f64;
    for i in 0..axes {
        scene.line(
            [x, rect[1] - 12.0],
            [x + 20.0, rect[1] - 12.0],
            Stroke::solid(AXIS_COLORS[i], 2.0),
        );
        scene.text(
            [x + 26.0, rect[1] - 8.0],
            12.0,
            Anchor::Start,
            "legend",
            names[i].to_string(),
        );
        x += 70.0;
    }
}
