//! Shared toolpaths, machine settings and a virtual-time runner for the planner tests and the
//! planner bench. Blocks are built as `kernel::block::Block` values directly.
#![allow(dead_code)]

use std::f64::consts::TAU;

use kernel::block::{ArcDir, Block, BlockKind, Comp, Continuity, Feed, Path, Plane, Spindle};
use kernel::constants::Constants;
use kernel::interp::{InterpState, Interpolator, TickOut};
use kernel::plan::{PlannerConfig, Segment};
use kernel::units::{AxesMm, TS_S};

pub fn p3(x: f64, y: f64, z: f64) -> AxesMm {
    AxesMm([x, y, z, 0.0, 0.0, 0.0])
}

/// Builds program blocks with a running position and sequence number.
pub struct Prog {
    pub blocks: Vec<Block>,
    pub pos: AxesMm,
    pub feed_mm_min: f64,
    pub continuity: Continuity,
    pub dyn_set: u8,
}

impl Prog {
    pub fn new(start: AxesMm, feed_mm_min: f64, continuity: Continuity) -> Self {
        Prog {
            blocks: vec![],
            pos: start,
            feed_mm_min,
            continuity,
            dyn_set: 1,
        }
    }

    fn block(&self, kind: BlockKind) -> Block {
        let seq = self.blocks.len() as u32;
        Block {
            seq,
            n: Some(seq * 10),
            line: seq + 1,
            kind,
            feed: Feed::MmPerMin(self.feed_mm_min),
            plane: Plane::G17,
            comp: Comp::Off,
            continuity: self.continuity,
            dyn_set: self.dyn_set,
            spindle: Spindle::default(),
            m: [None; 4],
        }
    }

    pub fn motion(&mut self, end: AxesMm, path: Path) -> &mut Self {
        let b = self.block(BlockKind::Motion {
            start: self.pos,
            end,
            path,
        });
        self.blocks.push(b);
        self.pos = end;
        self
    }

    /// Dwell (G4-like block without motion).
    pub fn dwell(&mut self, seconds: f64) -> &mut Self {
        let b = self.block(BlockKind::Dwell { seconds });
        self.blocks.push(b);
        self
    }

    pub fn g1(&mut self, end: AxesMm) -> &mut Self {
        self.motion(end, Path::Line)
    }

    pub fn g0(&mut self, end: AxesMm) -> &mut Self {
        self.motion(end, Path::Rapid)
    }

    /// Arc in G17 about an absolute centre.
    pub fn arc(&mut self, end: AxesMm, center: AxesMm, dir: ArcDir) -> &mut Self {
        self.motion(
            end,
            Path::Arc {
                dir,
                center,
                plane: Plane::G17,
            },
        )
    }
}

/// The documented toolpath suite (see `docs/planner.md`).
pub fn suite() -> Vec<(&'static str, Vec<Block>)> {
    vec![
        ("dense circle 0.05 mm", dense_circle(10.0, 0.05, 6000.0)),
        ("zig-zag surface", zigzag(12, 40.0, 1.0, 3000.0)),
        ("pocket sharp corners", pocket(30.0, 20.0, 2.0, 2000.0)),
        ("long lines + rapids", long_lines()),
        ("mixed arcs", mixed_arcs()),
        (
            "3D surface 0.1 mm raster",
            surface(8, 30.0, 1.0, 0.1, 4000.0),
        ),
    ]
}

/// Finishing raster over the surface z = 2·sin(x/5)·cos(y/7) in CAD-sized steps along X,
/// passes joined by step-overs in Y.
pub fn surface(passes: usize, width: f64, step: f64, seg: f64, feed: f64) -> Vec<Block> {
    let z = |x: f64, y: f64| 2.0 * (x / 5.0).sin() * (y / 7.0).cos();
    let mut p = Prog::new(p3(0.0, 0.0, z(0.0, 0.0)), feed, Continuity::G23);
    let n = (width / seg).round() as usize;
    for k in 0..passes {
        let y = k as f64 * step;
        for i in 1..=n {
            let x = if k % 2 == 0 {
                i as f64 * seg
            } else {
                width - i as f64 * seg
            };
            p.g1(p3(x, y, z(x, y)));
        }
        let (x, y1) = (p.pos[0], y + step);
        p.g1(p3(x, y1, z(x, y1)));
    }
    p.blocks
}

/// A circle of radius `r` as a polyline of chords `chord` long, G23, at `feed` mm/min.
pub fn dense_circle(r: f64, chord: f64, feed: f64) -> Vec<Block> {
    let mut p = Prog::new(p3(r, 0.0, 0.0), feed, Continuity::G23);
    let n = (TAU * r / chord).round() as usize;
    for i in 1..=n {
        let a = TAU * i as f64 / n as f64;
        p.g1(p3(r * a.cos(), r * a.sin(), 0.0));
    }
    p.blocks
}

/// Parallel passes along X joined by short step-overs in Y (90° corners).
pub fn zigzag(passes: usize, width: f64, step: f64, feed: f64) -> Vec<Block> {
    let mut p = Prog::new(p3(0.0, 0.0, 0.0), feed, Continuity::G23);
    for i in 0..passes {
        let x = if i % 2 == 0 { width } else { 0.0 };
        p.g1(p3(x, i as f64 * step, 0.0));
        p.g1(p3(x, (i + 1) as f64 * step, 0.0));
    }
    p.blocks
}

/// Rectangular pocket cleared by concentric rectangles with sharp corners, plunges in Z.
pub fn pocket(w: f64, h: f64, step: f64, feed: f64) -> Vec<Block> {
    let mut p = Prog::new(p3(0.0, 0.0, 5.0), feed, Continuity::G23);
    p.g0(p3(w / 2.0, h / 2.0, 5.0));
    p.g1(p3(w / 2.0, h / 2.0, -2.0));
    let mut k = step;
    while k < h / 2.0 {
        let (x0, x1) = (w / 2.0 - k * w / h, w / 2.0 + k * w / h);
        let (y0, y1) = (h / 2.0 - k, h / 2.0 + k);
        p.g1(p3(x0, y0, -2.0));
        p.g1(p3(x1, y0, -2.0));
        p.g1(p3(x1, y1, -2.0));
        p.g1(p3(x0, y1, -2.0));
        p.g1(p3(x0, y0, -2.0));
        k += step;
    }
    p.g0(p3(p.pos[0], p.pos[1], 5.0));
    p.blocks
}

/// Long 3D lines with rapid repositioning.
pub fn long_lines() -> Vec<Block> {
    let mut p = Prog::new(p3(0.0, 0.0, 0.0), 9000.0, Continuity::G23);
    p.g1(p3(200.0, 50.0, -5.0));
    p.g1(p3(400.0, 60.0, -5.0));
    p.g0(p3(0.0, 100.0, 10.0));
    p.feed_mm_min = 4000.0;
    p.g1(p3(300.0, 100.0, 0.0));
    p.g1(p3(300.0, 300.0, -10.0));
    p.g0(p3(0.0, 0.0, 0.0));
    p.blocks
}

/// Arcs of several radii joined tangentially and at corners, with lines between.
pub fn mixed_arcs() -> Vec<Block> {
    let mut p = Prog::new(p3(0.0, 0.0, 0.0), 4000.0, Continuity::G23);
    p.g1(p3(20.0, 0.0, 0.0));
    // Tangent quarter arc R10 CCW to (30, 10).
    p.arc(p3(30.0, 10.0, 0.0), p3(20.0, 10.0, 0.0), ArcDir::Ccw);
    p.g1(p3(30.0, 30.0, 0.0));
    // Semicircle R5 CW (tangent), then a corner into a small arc R2.
    p.arc(p3(40.0, 30.0, 0.0), p3(35.0, 30.0, 0.0), ArcDir::Cw);
    p.arc(p3(44.0, 30.0, 0.0), p3(42.0, 30.0, 0.0), ArcDir::Ccw);
    p.feed_mm_min = 1500.0;
    p.g1(p3(44.0, 0.0, 0.0));
    // Full circle R15 with a helix drop in Z.
    p.arc(p3(44.0, 0.0, -3.0), p3(29.0, 0.0, 0.0), ArcDir::Ccw);
    p.g1(p3(0.0, 0.0, -3.0));
    p.blocks
}

/// A 3-axis mill with different axis dynamics.
pub fn machine() -> PlannerConfig {
    let mut cfg = PlannerConfig::uniform(3, 200.0, 1500.0);
    cfg.axis_v_max_mm_s[1] = 180.0;
    cfg.axis_v_max_mm_s[2] = 100.0;
    cfg.axis_a_max_mm_s2[1] = 1200.0;
    cfg.axis_a_max_mm_s2[2] = 800.0;
    cfg.axis_j_max_mm_s3 = [40_000.0; kernel::MAX_AXES];
    cfg
}

/// Envelope constants used by the suite: Lm 8 µm, drop 20 %, am 3000 mm/s², R395 = 1 ms,
/// automatic continuity with R39 = 60°, and the given profile (1 linear, 2 parabolic).
pub fn constants(profile: u8) -> Constants {
    let mut c = Constants::new();
    c.set(338, profile as f64 * 0.010);
    c.set(97, 0.002);
    c.set(384, 200.008);
    c.set(385, 3.000);
    c.set(395, 0.001);
    c.set(52, 1500.0);
    c.set(236, 1200.0);
    c.set(237, 1500.0);
    c.set(406, 0.001);
    c.set(407, 300.000); // P = 300000 → J ≈ 9150 mm/s³
    c.set(408, 1.200); // A = 1200 mm/s²
    c.set(409, 200.008);
    c.set(410, 3.000);
    c
}

pub fn config(profile: u8) -> PlannerConfig {
    machine().with_constants(&constants(profile))
}

/// The suite's machine, linear profile, with no path-level acceleration (R52, R236, R237 and
/// the set's A at 0: the axes' limits alone, as the daemon's machine without constants and the
/// issue #32 machine have it), so the per-axis box on the setpoints (`interp::setpoint_box`)
/// chooses the setpoints on its lines.
pub fn config_box() -> PlannerConfig {
    let mut c = constants(1);
    for r in [52, 236, 237, 408] {
        c.set(r, 0.0);
    }
    machine().with_constants(&c)
}

/// Result of a virtual-time run.
pub struct Run {
    /// Tick outputs, with the start position first.
    pub ticks: Vec<TickOut>,
    /// Committed segments in order.
    pub segments: Vec<Segment>,
    /// Largest number of blocks the planner held.
    pub max_window: usize,
    /// Blocks pushed before the first tick moved the machine.
    pub pushed_before_motion: usize,
}

impl Run {
    pub fn time_s(&self) -> f64 {
        (self.ticks.len() - 1) as f64 * TS_S
    }
}

/// Streams `blocks` through planner and interpolator the way the daemon does; `each_tick` may
/// act on the interpolator before every tick (override, hold ...).
pub fn run_with(
    cfg: PlannerConfig,
    blocks: &[Block],
    max_ticks: usize,
    each_tick: impl FnMut(usize, &mut Interpolator),
) -> Run {
    run_stream(cfg, blocks.iter().copied(), max_ticks, each_tick)
}

/// As [`run_with`], with blocks generated on the fly (for very long programs).
pub fn run_stream(
    cfg: PlannerConfig,
    blocks: impl Iterator<Item = Block>,
    max_ticks: usize,
    mut each_tick: impl FnMut(usize, &mut Interpolator),
) -> Run {
    let mut blocks = blocks.peekable();
    let start = match blocks.peek().and_then(Block::motion) {
        Some((s, _, _)) => s,
        None => AxesMm::ZERO,
    };
    let axes = cfg.axes;
    let mut feed = Feeder {
        blocks,
        exhausted: false,
        planner: kernel::plan::Planner::new(cfg, 1),
        next: 0,
        held: None,
        segments: vec![],
        max_window: 0,
    };
    let mut ip = Interpolator::new(axes, start);
    let mut ticks = vec![TickOut {
        position: start,
        ..TickOut::default()
    }];
    let mut pushed_before_motion = 0;
    for t in 0..max_ticks {
        feed.feed(&mut ip, t == 0);
        each_tick(t, &mut ip);
        let out = ip.tick();
        if pushed_before_motion == 0 && out.path_v_mm_s > 0.0 {
            pushed_before_motion = feed.next;
        }
        ticks.push(out);
        if feed.planner.is_done() && feed.held.is_none() && ip.state() == InterpState::Idle {
            break;
        }
    }
    Run {
        ticks,
        segments: feed.segments,
        max_window: feed.max_window,
        pushed_before_motion,
    }
}

/// The planner side of a run: blocks into the planner, segments into the interpolator.
struct Feeder<I: Iterator<Item = Block>> {
    blocks: I,
    exhausted: bool,
    planner: kernel::plan::Planner,
    /// Blocks pushed so far.
    next: usize,
    /// A segment the interpolator had no room for.
    held: Option<Segment>,
    segments: Vec<Segment>,
    max_window: usize,
}

impl<I: Iterator<Item = Block>> Feeder<I> {
    /// Before a tick: motion starts with the first segment; after that the planner runs
    /// ahead until the interpolator's buffer is full, like the daemon's planner thread
    /// (feeding one block per tick starved dense paths whose window is full of unsettled
    /// blocks).
    fn feed(&mut self, ip: &mut Interpolator, first_tick: bool) {
        loop {
            self.push_blocks();
            let progressed = self.hand_out(ip);
            self.max_window = self
                .max_window
                .max(self.next.saturating_sub(self.segments.len()));
            if (ip.buffered() > 0 && first_tick) || self.planner.is_done() || self.held.is_some() {
                break;
            }
            // Nothing committed yet: the planner needs more input (or the program is over).
            if !progressed && (!self.planner.wants_input() || self.exhausted) {
                break;
            }
        }
    }

    fn push_blocks(&mut self) {
        while self.planner.wants_input() && !self.exhausted {
            match self.blocks.next() {
                Some(b) => {
                    self.planner.push(&b).expect("valid block");
                    self.next += 1;
                }
                None => self.exhausted = true,
            }
        }
        if self.exhausted {
            self.planner.finish();
        }
    }

    /// Committed segments into the interpolator while it has room; whether any went in.
    fn hand_out(&mut self, ip: &mut Interpolator) -> bool {
        let mut progressed = false;
        loop {
            let seg = match self.held.take() {
                Some(s) => s,
                None => match self.planner.poll() {
                    Some(s) => {
                        self.segments.push(s);
                        s
                    }
                    None => break,
                },
            };
            if let Err(s) = ip.push(seg) {
                self.held = Some(s);
                break;
            }
            progressed = true;
        }
        progressed
    }
}

pub fn run(cfg: PlannerConfig, blocks: &[Block]) -> Run {
    run_with(cfg, blocks, 2_000_000, |_, _| {})
}

/// Worst ratios of the setpoint stream to its limits (1.0 = at the limit).
#[derive(Clone, Copy, Debug, Default)]
pub struct Worst {
    pub axis_v: f64,
    pub axis_a: f64,
    pub axis_j: f64,
    pub path_v: f64,
    pub path_a: f64,
    pub path_j: f64,
    /// Largest distance of a smooth corner from the setpoint polyline near it, relative to Lm.
    pub corner_dev: f64,
    /// Largest distance of a setpoint from the programmed path (its segment or a neighbour,
    /// since the axis filter lags the path position), mm.
    pub off_path_mm: f64,
    /// Stop points (and the program end) not hit exactly.
    pub missed_stops: usize,
}

fn dist_to_chord(c: &AxesMm, a: &AxesMm, b: &AxesMm, axes: usize) -> f64 {
    let ab = *b - *a;
    let l2 = ab.norm(axes).powi(2);
    let t = if l2 > 0.0 {
        ((0..axes).map(|i| (c[i] - a[i]) * ab[i]).sum::<f64>() / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (*a + ab * t - *c).norm(axes)
}

fn dist_to_path(p: &AxesMm, seg: &Segment, axes: usize) -> f64 {
    match seg.path {
        kernel::plan::SegPath::Line { start, end } => dist_to_chord(p, &start, &end, axes),
        kernel::plan::SegPath::Arc {
            center,
            plane,
            radius_mm,
            ..
        } => {
            let (a, b) = plane.axes();
            ((p[a] - center[a]).hypot(p[b] - center[b]) - radius_mm).abs()
        }
    }
}

/// Measures a run against the limits (finite differences of the setpoints).
pub fn measure(cfg: &PlannerConfig, r: &Run, lm_um: f64) -> Worst {
    let mut w = Worst::default();
    measure_dynamics(cfg, r, &mut w);
    measure_off_path(cfg.axes, r, &mut w);
    w.missed_stops = missed_stops(cfg.axes, r);
    if lm_um > 0.0 {
        w.corner_dev = corner_deviation(cfg.axes, r, lm_um);
    }
    w
}

/// Axis and path velocity, acceleration and jerk of the setpoints against their limits.
fn measure_dynamics(cfg: &PlannerConfig, r: &Run, w: &mut Worst) {
    let axes = cfg.axes;
    let by_seq: std::collections::HashMap<u32, Segment> =
        r.segments.iter().map(|s| (s.seq, *s)).collect();
    // A segment the per-axis box judges (`Segment::axis_box`) has its axes' limits, its path
    // acceleration (`BoxAccel::path`, ∞: none) and the box's ceiling `SegmentBox::v_max_mm_s`.
    let boxed = |s: &Segment| s.axis_box.accel_mm_s2.is_set();
    let a_path = r.segments.iter().fold(0.0f64, |m, s| {
        if boxed(s) {
            m.max(s.axis_box.accel_mm_s2.path())
        } else {
            m.max(s.accel_mm_s2)
                .max(s.stop_accel_mm_s2)
                .max(s.free_accel_mm_s2)
        }
    });
    // (The jerk-limited box keeps the constants' path jerk within the axes, `BoxJerk::path`;
    // the envelope a share of it where the axis filter turns.)
    let j_path = r.segments.iter().fold(0.0f64, |m, s| {
        if s.axis_box.jerk.is_set() {
            m.max(s.axis_box.jerk.path()).max(s.jerk_mm_s3)
        } else {
            m.max(s.jerk_mm_s3)
        }
    });
    // The reported path speed is the difference of two arc lengths of up to the program's
    // length over a tick, so it rounds by a few ulp of that length per tick: 4.3e-11 mm/s
    // (1.6e-9 of a 0.027 mm/s ceiling) after 1250 mm in a random run.
    let length_mm: f64 = r.segments.iter().map(|s| s.length_mm).sum();
    let v_eps = 8.0 * length_mm.max(1.0) * f64::EPSILON / TS_S;
    let t = &r.ticks;
    let v = |k: usize, i: usize| (t[k].position[i] - t[k - 1].position[i]) / TS_S;
    for k in 1..t.len() {
        for i in 0..axes {
            w.axis_v = w.axis_v.max(v(k, i).abs() / cfg.axis_v_max_mm_s[i]);
            if k >= 2 {
                let a = (v(k, i) - v(k - 1, i)) / TS_S;
                w.axis_a = w.axis_a.max(a.abs() / cfg.axis_a_max_mm_s2[i]);
                if k >= 3 {
                    let a0 = (v(k - 1, i) - v(k - 2, i)) / TS_S;
                    w.axis_j = w
                        .axis_j
                        .max(((a - a0) / TS_S).abs() / cfg.axis_j_max_mm_s3[i]);
                }
            }
        }
        let ceil = |seq: u32| {
            by_seq.get(&seq).map_or(f64::INFINITY, |s| {
                let v_max = if boxed(s) {
                    s.axis_box.v_max_mm_s
                } else {
                    s.v_max_mm_s
                };
                s.feed_mm_s.min(v_max)
            })
        };
        // (A step may cross a whole boxed segment and end on the next one's start: every
        // block from the tick two before to this one counts.)
        let on_box = |k: usize| {
            let (lo, hi) = (t[k.saturating_sub(2)].seq, t[k].seq);
            (lo.min(hi)..=hi.max(lo)).any(|q| {
                by_seq
                    .get(&q)
                    .is_some_and(|s| boxed(s) && s.axis_box.accel_mm_s2.path().is_infinite())
            })
        };
        let lim = if k == 1 {
            ceil(t[k].seq)
        } else {
            ceil(t[k - 1].seq).max(ceil(t[k].seq))
        };
        w.path_v = w.path_v.max((t[k].path_v_mm_s - v_eps) / lim);
        if k >= 2 && !on_box(k) {
            let a = (t[k].path_v_mm_s - t[k - 1].path_v_mm_s) / TS_S;
            w.path_a = w.path_a.max((a.abs() - 2.0 * v_eps / TS_S) / a_path);
            if k >= 3 && j_path.is_finite() {
                let a0 = (t[k - 1].path_v_mm_s - t[k - 2].path_v_mm_s) / TS_S;
                let j = ((a - a0) / TS_S).abs() - 4.0 * v_eps / (TS_S * TS_S);
                w.path_j = w.path_j.max(j / j_path);
            }
        }
    }
}

/// Largest distance of a setpoint from its segment or the 64 before it (the axis filter
/// lags the path position).
fn measure_off_path(axes: usize, r: &Run, w: &mut Worst) {
    let index_of: std::collections::HashMap<u32, usize> = r
        .segments
        .iter()
        .enumerate()
        .map(|(i, s)| (s.seq, i))
        .collect();
    for o in &r.ticks[1..] {
        if let Some(&i) = index_of.get(&o.seq) {
            let d = r.segments[i.saturating_sub(64)..(i + 2).min(r.segments.len())]
                .iter()
                .map(|s| dist_to_path(&o.position, s, axes))
                .fold(f64::INFINITY, f64::min);
            w.off_path_mm = w.off_path_mm.max(d);
        }
    }
}

/// Stop points and the program end not hit exactly by a setpoint.
fn missed_stops(axes: usize, r: &Run) -> usize {
    r.segments
        .iter()
        .filter(|s| s.junction == kernel::plan::Junction::Stop || s.last)
        .filter(|s| {
            let end = s.path.end();
            !r.ticks
                .iter()
                .any(|o| o.position.0[..axes] == end.0[..axes])
        })
        .count()
}

/// Smooth corners: largest distance of the corner from the chord of the tick that crosses
/// it, relative to Lm.
fn corner_deviation(axes: usize, r: &Run, lm_um: f64) -> f64 {
    let t = &r.ticks;
    let mut worst = 0.0f64;
    let mut k = 1;
    for (idx, s) in r.segments.iter().enumerate() {
        if s.junction == kernel::plan::Junction::Stop || idx + 1 >= r.segments.len() {
            continue;
        }
        let nx = &r.segments[idx + 1];
        let turn = s
            .path
            .tangent_at(1.0, axes)
            .0
            .iter()
            .zip(nx.path.tangent_at(0.0, axes).0.iter())
            .map(|(a, b)| a * b)
            .sum::<f64>();
        if turn > 1.0 - 1e-12 {
            continue;
        }
        while k < t.len() && t[k].seq <= s.seq {
            k += 1;
        }
        if k >= t.len() {
            break;
        }
        // The axis filter lags and spreads the corner over 2n ticks: the nearest chord.
        let n = usize::from(s.axis_filter_ticks.max(1));
        let (lo, hi) = (
            k.saturating_sub(2 * n + 3).max(1),
            (k + 2 * n + 3).min(t.len()),
        );
        let d = (lo..hi)
            .map(|j| dist_to_chord(&s.path.end(), &t[j - 1].position, &t[j].position, axes))
            .fold(f64::INFINITY, f64::min);
        worst = worst.max(d / (lm_um * 1e-3));
    }
    worst
}

/// A random program from generated steps (kind, angles, length, feed, continuity).
pub fn random_program(steps: &[(u8, f64, f64, f64, u8, u8)]) -> Vec<Block> {
    let mut p = Prog::new(p3(0.0, 0.0, 0.0), 3000.0, Continuity::G23);
    for &(kind, a, b, len, feed, cont) in steps {
        p.feed_mm_min = 300.0 + feed as f64 * 40.0;
        p.continuity = match cont % 5 {
            0 => Continuity::G98,
            1 => Continuity::G24,
            _ => Continuity::G23,
        };
        let dir = p3(a.cos() * b.cos(), a.sin() * b.cos(), b.sin() * 0.3);
        let n = dir.norm(3);
        let end = p.pos + dir * (len / n);
        match kind % 6 {
            0 => {
                p.g0(end);
            }
            1 | 2 => {
                // Arc through `end` with the centre on the perpendicular bisector.
                let mid = p.pos.lerp(&end, 0.5);
                let d = end - p.pos;
                let off = 0.5 + (a * 3.0).sin().abs() * 2.0;
                let mut c = mid;
                c[0] += -d[1] * off;
                c[1] += d[0] * off;
                let mut e2 = end;
                e2[2] = p.pos[2];
                if (e2 - p.pos).norm(2) > 1e-3 {
                    let dirn = if kind % 6 == 1 {
                        ArcDir::Ccw
                    } else {
                        ArcDir::Cw
                    };
                    p.arc(e2, c, dirn);
                }
            }
            _ => {
                p.g1(end);
            }
        }
    }
    p.blocks
}

/// The toolpaths of issue #16 (machining time on the daemon's configuration, `kernel/benches/plan.rs`).
pub fn daemon_suite() -> Vec<(&'static str, Vec<Block>)> {
    vec![
        ("100 mm line", line_100()),
        (
            "circle r20 of 0.05 mm chords",
            dense_circle(20.0, 0.05, 6000.0),
        ),
        (
            "zig-zag of 0.2 mm blocks",
            surface(50, 40.0, 1.0, 0.2, 6000.0),
        ),
        (
            "rectangular pocket spiral",
            pocket_spiral(60.0, 40.0, 1.0, 41, 6000.0),
        ),
        ("Lissajous 0.02..0.1 mm chords", lissajous(6000.0)),
        ("3D raster 0.1 mm", surface(8, 30.0, 1.0, 0.1, 4000.0)),
        ("star (long blocks)", star(40.0, 6000.0)),
    ]
}

/// Issue #24's path for a machine with unequal axis limits: ramps in XZ and diagonals in XY.
pub fn unequal_limits_path() -> Vec<Block> {
    let mut p = Prog::new(p3(0.0, 0.0, 0.0), 6000.0, Continuity::G23);
    for i in 0..6 {
        let y = i as f64 * 4.0;
        p.g1(p3(40.0, y, -1.0 - i as f64));
        p.g1(p3(60.0, y + 2.0, -1.0 - i as f64));
        p.g1(p3(0.0, y + 4.0, -i as f64 - 2.0));
    }
    p.g0(p3(0.0, 0.0, 10.0));
    p.blocks
}

pub fn line_100() -> Vec<Block> {
    let mut p = Prog::new(p3(0.0, 0.0, 0.0), 6000.0, Continuity::G23);
    p.g1(p3(100.0, 0.0, 0.0));
    p.blocks
}

/// A rectangular spiral inwards with 90° corners: `sides` lines, G23.
pub fn pocket_spiral(w: f64, h: f64, step: f64, sides: usize, feed: f64) -> Vec<Block> {
    let mut p = Prog::new(p3(0.0, 0.0, 0.0), feed, Continuity::G23);
    let (mut x0, mut y0, mut x1, mut y1) = (0.0, 0.0, w, h);
    for k in 0..sides {
        match k % 4 {
            0 => p.g1(p3(x1, y0, 0.0)),
            1 => p.g1(p3(x1, y1, 0.0)),
            2 => p.g1(p3(x0, y1, 0.0)),
            _ => {
                x0 += step;
                y0 += step;
                x1 -= step;
                y1 -= step;
                p.g1(p3(x0 - step, y0, 0.0))
            }
        };
        if k % 4 == 3 {
            p.g1(p3(x0, y0, 0.0));
        }
    }
    p.blocks
}

/// Lissajous figure x = 30·sin 3t, y = 20·sin 4t as chords of 0.02..0.1 mm, G23.
pub fn lissajous(feed: f64) -> Vec<Block> {
    let at = |t: f64| p3(30.0 * (3.0 * t).sin(), 20.0 * (4.0 * t).sin(), 0.0);
    let mut p = Prog::new(at(0.0), feed, Continuity::G23);
    let mut t = 0.0;
    let mut k = 0usize;
    while t < TAU {
        // Chord length cycles through 0.02..0.1 mm.
        let chord = 0.06 + 0.04 * (k as f64 * 0.37).sin();
        let speed = (90.0f64 * (3.0 * t).cos())
            .hypot(80.0 * (4.0 * t).cos())
            .max(1e-3);
        t = (t + chord / speed).min(TAU);
        p.g1(at(t));
        k += 1;
    }
    p.blocks
}

/// Five-pointed star of long lines (sharp corners), G23.
pub fn star(r: f64, feed: f64) -> Vec<Block> {
    let pt = |k: usize| {
        let a = TAU * (k % 5) as f64 * 2.0 / 5.0;
        p3(r * a.cos(), r * a.sin(), 0.0)
    };
    let mut p = Prog::new(pt(0), feed, Continuity::G23);
    for k in 1..=5 {
        p.g1(pt(k));
    }
    p.blocks
}

/// One path of the independent reference (issue #32, `scripts/planner-reference/`): its
/// program and the limit times the reference computed without the planner.
pub struct ReferencePath {
    pub name: String,
    pub title: String,
    pub blocks: Vec<Block>,
    pub exact_s: f64,
    pub smooth_s: f64,
    pub limit_s: f64,
}

/// Directory of the committed reference paths.
pub fn reference_dir() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/planner-reference")
}

/// The machine of issue #32: per axis 20000 mm/min and 1000 mm/s², constants
/// `scripts/planner-reference/machine.rek` (R384 Lm = 8 µm, R385 am = 1000, R52 = R237 = 0:
/// the axes' limits), default `[planner] min_block_time_ms` 0: the configuration `cncd`
/// builds for it.
pub fn reference_config() -> PlannerConfig {
    reference_config_with("machine.rek")
}

/// The machine of issue #32 with the constants file `name` of `scripts/planner-reference/`,
/// which `cncd` must accept as it is (issue #49: `machine-default.rek` leaves R52/R236/R237
/// at their defaults, 500 mm/s²; `machine-above.rek` sets them to 5000, above what the axes
/// allow along any direction).
pub fn reference_config_with(name: &str) -> PlannerConfig {
    let text = std::fs::read_to_string(reference_dir().join(name)).unwrap();
    let c = Constants::parse(&text).unwrap();
    assert!(c.validate().is_empty(), "{name}: {:?}", c.validate());
    let axis = kernel::plan::AxisLimits {
        v_max_mm_s: 20000.0 / 60.0,
        a_max_mm_s2: 1000.0,
    };
    PlannerConfig::for_machine(&[axis; 3], 0.0, Some(&c))
}

/// The time of the greedy 4 ms setpoint sequence of `ticks.py` on path `name`, s, from its
/// table `table` (`ticks.tsv`: the axes' limits alone; `ticks-a500.tsv`: a path
/// acceleration of 500 mm/s²).
pub fn ticks_s(table: &str, name: &str) -> f64 {
    table_value(&reference_dir().join(table), name, 2)
}

/// Column `col` of row `name` of a tab-separated table (`#` lines are comments).
pub fn table_value(file: &std::path::Path, name: &str, col: usize) -> f64 {
    let text = std::fs::read_to_string(file).unwrap();
    text.lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| l.split('\t').collect::<Vec<_>>())
        .find(|f| f[0] == name)
        .unwrap_or_else(|| panic!("no {name} in {}", file.display()))[col]
        .parse()
        .unwrap()
}

/// The reference paths with their limits (`reference.tsv`).
pub fn reference_paths() -> Vec<ReferencePath> {
    let dir = reference_dir();
    let table = std::fs::read_to_string(dir.join("reference.tsv")).unwrap();
    table
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let f: Vec<&str> = l.split('\t').collect();
            let nc =
                std::fs::read_to_string(dir.join("paths").join(format!("{}.nc", f[0]))).unwrap();
            ReferencePath {
                name: f[0].to_string(),
                title: f[6].to_string(),
                blocks: program_of_g1(&nc),
                exact_s: f[3].parse().unwrap(),
                smooth_s: f[4].parse().unwrap(),
                limit_s: f[5].parse().unwrap(),
            }
        })
        .collect()
}

/// Blocks of a program of `G1 X Y Z` lines from the origin (the reference's programs; the
/// first line also carries G23 and F).
pub fn program_of_g1(text: &str) -> Vec<Block> {
    let mut p = Prog::new(p3(0.0, 0.0, 0.0), 6000.0, Continuity::G23);
    for line in text.lines() {
        let mut q = p.pos;
        for w in line.split_whitespace() {
            let (k, v) = w.split_at(1);
            match k {
                "X" => q[0] = v.parse().unwrap(),
                "Y" => q[1] = v.parse().unwrap(),
                "Z" => q[2] = v.parse().unwrap(),
                "F" => p.feed_mm_min = v.parse().unwrap(),
                _ => {}
            }
        }
        p.g1(q);
    }
    p.blocks
}

/// Blocks of an arc-fitted program of `scripts/planner-reference/arcs` (`arcs.py`): `G2`/`G3
/// X Y I J` arcs in G17, centre relative to the arc's start, and `G1 X Y Z` lines, from the
/// origin (the first line also carries G23 and F).
pub fn program_of_arcs(text: &str) -> Vec<Block> {
    let mut p = Prog::new(p3(0.0, 0.0, 0.0), 6000.0, Continuity::G23);
    for line in text.lines() {
        let (mut q, mut c, mut dir) = (p.pos, p.pos, Some(ArcDir::Ccw));
        for w in line.split_whitespace() {
            let (k, v) = w.split_at(1);
            match (k, v) {
                ("G", "1") => dir = None,
                ("G", "2") => dir = Some(ArcDir::Cw),
                ("G", "3") => dir = Some(ArcDir::Ccw),
                ("X", v) => q[0] = v.parse().unwrap(),
                ("Y", v) => q[1] = v.parse().unwrap(),
                ("Z", v) => q[2] = v.parse().unwrap(),
                ("I", v) => c[0] = p.pos[0] + v.parse::<f64>().unwrap(),
                ("J", v) => c[1] = p.pos[1] + v.parse::<f64>().unwrap(),
                ("F", v) => p.feed_mm_min = v.parse().unwrap(),
                _ => {}
            }
        }
        match dir {
            Some(dir) => p.arc(q, c, dir),
            None => p.g1(q),
        };
    }
    p.blocks
}

/// The programs of directory `sub` of `scripts/planner-reference` (`arcs`: the arc-fitted
/// ones, `fast`: long lines at the axes' speed), by name.
pub fn programs_in(sub: &str) -> Vec<(String, Vec<Block>)> {
    let dir = reference_dir().join(sub);
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| {
            let name = e.unwrap().file_name().into_string().unwrap();
            name.strip_suffix(".nc").map(str::to_string)
        })
        .collect();
    names.sort();
    names
        .into_iter()
        .map(|n| {
            let text = std::fs::read_to_string(dir.join(format!("{n}.nc"))).unwrap();
            (n, program_of_arcs(&text))
        })
        .collect()
}
