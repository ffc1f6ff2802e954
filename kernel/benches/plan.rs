//! Planner and interpolator figures (issues #5, #16, #24): machining time per toolpath on the
//! configuration `cncd` builds (`PlannerConfig::for_machine`, the same function the daemon
//! calls), against the time-optimal time under the same constraints (an independent exact
//! forward/backward pass in this file) and a reference planner (16-block look-ahead, one block
//! per tick); planner throughput; interpolation cost per tick. Prints tables; asserts nothing.
//!
//! Run: `cargo bench -p kernel --bench plan`. `PLAN_CONSTANTS=path/to/TAB0.REK` adds a run
//! with that constants file (on the daemon's default axes).

#[path = "../tests/plan_common/mod.rs"]
mod plan_common;

use std::time::Instant;

use kernel::block::{Block, Continuity};
use kernel::constants::Constants;
use kernel::interp::{InterpState, Interpolator};
use kernel::plan::{
    AxisLimits, DEFAULT_AXIS_LIMITS, Junction, Planner, PlannerConfig, SegPath, Segment,
};
use plan_common::*;

/// The daemon's default machine: three axes at the configuration defaults.
fn default_axes() -> Vec<AxisLimits> {
    vec![DEFAULT_AXIS_LIMITS; 3]
}

/// The machine of `deploy/cncd.toml`: X/Y 200 mm/s 800 mm/s², Z 100 mm/s 500 mm/s².
fn unequal_axes() -> Vec<AxisLimits> {
    let z = AxisLimits {
        v_max_mm_s: 100.0,
        a_max_mm_s2: 500.0,
    };
    vec![DEFAULT_AXIS_LIMITS, DEFAULT_AXIS_LIMITS, z]
}

fn constants_file(path: &str) -> Constants {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    Constants::parse(&text).unwrap_or_else(|e| panic!("{path}: {e:?}"))
}

/// A daemon configuration: axes, constants file (None = none on the machine), default
/// `[planner] min_block_time_ms` (0).
fn daemon_config(axes: &[AxisLimits], constants: Option<&Constants>) -> PlannerConfig {
    PlannerConfig::for_machine(axes, 0.0, constants)
}

/// Reference planner in the style of LinuxCNC/Grbl: the same configuration and criteria, but
/// a 16-block look-ahead window and every block lasting at least one tick.
fn reference(cfg: &PlannerConfig) -> PlannerConfig {
    let mut c = cfg.clone();
    c.lookahead_blocks = 16;
    c.min_block_time_s = kernel::TS_S;
    c.envelope.rule = kernel::plan::ContinuityRule::Manual;
    c
}

/// Path acceleration limit of a segment under the constraint set: the axes it moves
/// (a_i/|u_i|; arcs with both plane axes at full share, as the planner) and the path
/// accelerations of the constants (R52 / R236 / set A / R237 and the rapid set).
fn path_accel(cfg: &PlannerConfig, seg: &Segment, continuous: bool) -> f64 {
    let axes = cfg.axes;
    let mut dir = seg.path.tangent_at(0.0, axes);
    if let SegPath::Arc {
        plane,
        radius_mm,
        sweep_rad,
        ..
    } = seg.path
    {
        let (a, b) = plane.axes();
        let share = radius_mm * sweep_rad.abs() / seg.length_mm;
        dir[a] = share;
        dir[b] = share;
    }
    let mut acc = f64::INFINITY;
    for i in 0..axes {
        if dir[i].abs() > 1e-12 {
            acc = acc.min(cfg.axis_a_max_mm_s2[i] / dir[i].abs());
        }
    }
    let env = &cfg.envelope;
    let set_a = env.sets[usize::from(seg.dyn_set.clamp(1, 4) - 1)].accel_mm_s2;
    let path = if seg.rapid {
        env.accel_rapid_mm_s2.min(env.rapid_accel_mm_s2)
    } else if continuous {
        set_a
    } else {
        env.accel_stop_mm_s2.min(set_a)
    };
    acc.min(path)
}

/// Time-optimal machining time under the planner's constraints, computed independently of
/// the planner's speed decisions: per segment the ceiling (feed, axis velocities, arc
/// criteria: `min(feed, v_max)`), per junction the criteria cap (dynamic, accuracy, local
/// curvature; 0 at stops), per segment the full path acceleration of the axes it moves.
/// Exact forward/backward pass, continuous time.
fn time_optimal_s(cfg: &PlannerConfig, segs: &[Segment]) -> f64 {
    let n = segs.len();
    let ceil: Vec<f64> = segs.iter().map(|s| s.feed_mm_s.min(s.v_max_mm_s)).collect();
    let acc: Vec<f64> = (0..n)
        .map(|k| {
            let prev_smooth = k > 0 && segs[k - 1].junction != Junction::Stop;
            let continuous = prev_smooth || segs[k].junction != Junction::Stop;
            path_accel(cfg, &segs[k], continuous)
        })
        .collect();
    let mut end: Vec<f64> = (0..n)
        .map(|k| {
            let next = if k + 1 < n { ceil[k + 1] } else { 0.0 };
            // The criteria cap, also where the planner chose to stop (0 at real stops).
            if segs[k].last {
                0.0
            } else {
                segs[k].junction_cap_mm_s.min(ceil[k]).min(next)
            }
        })
        .collect();
    for k in (1..n).rev() {
        let v = (end[k] * end[k] + 2.0 * acc[k] * segs[k].length_mm).sqrt();
        end[k - 1] = end[k - 1].min(v);
    }
    let mut t = 0.0;
    let mut v0 = 0.0;
    for k in 0..n {
        let (a, l) = (acc[k], segs[k].length_mm);
        end[k] = end[k].min((v0 * v0 + 2.0 * a * l).sqrt());
        let v1 = end[k];
        let peak = ceil[k].min(((2.0 * a * l + v0 * v0 + v1 * v1) / 2.0).sqrt());
        let ramps = (2.0 * peak * peak - v0 * v0 - v1 * v1) / (2.0 * a);
        t += (peak - v0) / a + (peak - v1) / a + (l - ramps).max(0.0) / peak;
        v0 = v1;
    }
    t
}

/// Largest per-axis acceleration and jerk of the setpoints, as fractions of the axis limits.
fn axis_peaks(cfg: &PlannerConfig, r: &Run) -> (f64, f64) {
    let ts = kernel::TS_S;
    let t = &r.ticks;
    let (mut a_max, mut j_max) = (0.0f64, 0.0f64);
    for i in 0..cfg.axes {
        let v: Vec<f64> = t
            .windows(2)
            .map(|w| (w[1].position[i] - w[0].position[i]) / ts)
            .collect();
        let a: Vec<f64> = v.windows(2).map(|w| (w[1] - w[0]) / ts).collect();
        for x in &a {
            a_max = a_max.max(x.abs() / cfg.axis_a_max_mm_s2[i]);
        }
        for w in a.windows(2) {
            j_max = j_max.max(((w[1] - w[0]) / ts).abs() / cfg.axis_j_max_mm_s3[i]);
        }
    }
    (a_max, j_max)
}

fn machining_table(title: &str, cfg: &PlannerConfig, paths: &[(&str, Vec<Block>)]) {
    println!("#### {title}\n");
    println!(
        "| toolpath | blocks | time s | time-optimal s | ratio | reference s (16 blocks, 1 block/tick) | reference / time | max axis a / limit | max axis jerk / limit |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|");
    for (name, blocks) in paths {
        let r = run(cfg.clone(), blocks);
        let t = r.time_s();
        let opt = time_optimal_s(cfg, &r.segments);
        let refr = run(reference(cfg), blocks).time_s();
        let (a, j) = axis_peaks(cfg, &r);
        println!(
            "| {name} | {} | {t:.3} | {opt:.3} | {:.3} | {refr:.3} | {:.2} | {a:.3} | {j:.3} |",
            blocks.len(),
            t / opt,
            refr / t
        );
    }
    println!();
}

fn machining_times() {
    println!("## Machining time per toolpath (virtual time, 4 ms ticks)\n");
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/benches/plan");
    let linear = constants_file(&format!("{dir}/linear.rek"));
    let parabolic = constants_file(&format!("{dir}/parabolic.rek"));
    let suite = daemon_suite();
    let unequal = [(
        "unequal limits: XZ ramps, XY diagonals",
        unequal_limits_path(),
    )];
    let runs: [(&str, Option<&Constants>); 3] = [
        (
            "daemon defaults, no constants file (linear, manual continuity)",
            None,
        ),
        (
            "constants benches/plan/linear.rek (R384 = 0.008, R385 = 1.000, R52 = R237 = 1000)",
            Some(&linear),
        ),
        (
            "constants benches/plan/parabolic.rek (as linear.rek, 2.R338 = 2)",
            Some(&parabolic),
        ),
    ];
    for (title, c) in runs {
        machining_table(
            &format!("{title}; axes 3 × 200 mm/s, 800 mm/s²"),
            &daemon_config(&default_axes(), c),
            &suite,
        );
        machining_table(
            &format!("{title}; axes X/Y 200 mm/s 800 mm/s², Z 100 mm/s 500 mm/s²"),
            &daemon_config(&unequal_axes(), c),
            &unequal,
        );
    }
    if let Ok(path) = std::env::var("PLAN_CONSTANTS") {
        let c = constants_file(&path);
        machining_table(
            &format!("constants {path}; axes 3 × 200 mm/s, 800 mm/s²"),
            &daemon_config(&default_axes(), Some(&c)),
            &suite,
        );
    }
}

/// Parabolic single moves from rest to rest (issue #16) on the daemon's configuration: time
/// against the ideal jerk-limited (7-phase) move for the segment's own J and A
/// (`ideal_jerk_limited_move_s`, closed form), and the ramp from rest to F against the
/// manual's T = 1.478·√(F/P) where the set gives P.
fn parabolic_moves() {
    println!("## Parabolic single moves against the ideal jerk-limited move\n");
    println!(
        "| constants | move | J mm/s³ | A mm/s² | time s | ideal s | ratio | ramp to F s | 1.478·√(F/P) s |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|---:|---:|");
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/benches/plan");
    let base = std::fs::read_to_string(format!("{dir}/parabolic.rek")).unwrap();
    let with_p = format!("{base}\nR406=0.001\nR407=50.000\nR408=0.600\n");
    let runs = [
        ("parabolic.rek", base.as_str(), None),
        (
            "parabolic.rek + set 1 P = 50000, A = 600",
            with_p.as_str(),
            Some(50_000.0),
        ),
    ];
    for (title, text, p) in runs {
        let c = Constants::parse(text).unwrap();
        let cfg = daemon_config(&default_axes(), Some(&c));
        for (x, f) in [(100.0, 6000.0), (20.0, 300.0), (2.0, 6000.0)] {
            let mut prog = Prog::new(p3(0.0, 0.0, 0.0), f, Continuity::G98);
            prog.g1(p3(x, 0.0, 0.0));
            let r = run(cfg.clone(), &prog.blocks);
            let seg = r.segments[0];
            let v = seg.feed_mm_s.min(seg.v_max_mm_s);
            let (a, j) = (seg.accel_mm_s2, seg.jerk_mm_s3);
            let ideal = kernel::interp::ideal_jerk_limited_move_s(x, v, a, j);
            let t = r.time_s();
            let speeds: Vec<f64> = r
                .ticks
                .windows(2)
                .map(|w| (w[1].position[0] - w[0].position[0]) / kernel::TS_S)
                .collect();
            let reached = speeds.iter().position(|s| *s >= v * (1.0 - 1e-9));
            let ramp = reached.map_or("-".to_string(), |k| {
                format!("{:.3}", (k + 1) as f64 * kernel::TS_S)
            });
            // (The manual's T is the ramp to F: only for moves that reach F.)
            let manual = match (p, reached) {
                (Some(p), Some(_)) => format!("{:.4}", 1.478 * (v * 60.0 / p).sqrt()),
                _ => "-".to_string(),
            };
            println!(
                "| {title} | X{x} F{f} | {j:.0} | {a:.0} | {t:.3} | {ideal:.3} | {:.3} | {ramp} | {manual} |",
                t / ideal
            );
        }
    }
    println!();
}

/// The configuration of the throughput and tick-cost figures: the daemon's, with the bench's
/// constants file of the given profile (1 linear, 2 parabolic).
fn ours(profile: u8) -> PlannerConfig {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/benches/plan");
    let name = if profile == 1 { "linear" } else { "parabolic" };
    let c = constants_file(&format!("{dir}/{name}.rek"));
    daemon_config(&default_axes(), Some(&c))
}

/// A long program of 0.05 mm chords on circles of 10 mm, generated on the fly.
fn dense_blocks(n: usize) -> Vec<Block> {
    let per_turn = dense_circle(10.0, 0.05, 6000.0);
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        for b in &per_turn {
            if out.len() == n {
                break;
            }
            let mut b = *b;
            b.seq = out.len() as u32;
            out.push(b);
        }
    }
    out
}

/// `n` blocks of 0.1 mm along X alternating 0.02 mm in Y (turns of ±22.6°), F6000.
fn zigzag_blocks(n: usize) -> Vec<Block> {
    let mut zz = Prog::new(p3(0.0, 0.0, 0.0), 6000.0, Continuity::G23);
    for i in 0..n {
        zz.g1(p3((i + 1) as f64 * 0.1, ((i + 1) % 2) as f64 * 0.02, 0.0));
    }
    zz.blocks
}

fn throughput() {
    println!("## Planner throughput (push + poll, 500-block look-ahead)\n");
    println!("| program | profile | blocks | seconds | blocks/s |");
    println!("|---|---|---:|---:|---:|");
    let n = 200_000;
    let blocks = dense_blocks(n);
    let zz = zigzag_blocks(n);
    for (name, prog) in [("0.05 mm circle chords", &blocks), ("0.1 mm zig-zag", &zz)] {
        for profile in [1u8, 2] {
            let mut best = f64::INFINITY;
            for _ in 0..3 {
                let mut pl = Planner::new(ours(profile), 1);
                let t0 = Instant::now();
                let mut polled = 0usize;
                for b in prog.iter() {
                    while !pl.wants_input() {
                        if pl.poll().is_some() {
                            polled += 1;
                        }
                    }
                    pl.push(b).unwrap();
                    while pl.poll().is_some() {
                        polled += 1;
                    }
                }
                pl.finish();
                while pl.poll().is_some() {
                    polled += 1;
                }
                let dt = t0.elapsed().as_secs_f64();
                assert!(polled > 0);
                best = best.min(dt);
            }
            let kind = if profile == 1 { "linear" } else { "parabolic" };
            println!(
                "| {name} | {kind} | {} | {best:.3} | {:.0} |",
                prog.len(),
                prog.len() as f64 / best
            );
        }
    }
    println!();
}

/// Per-tick interpolation time, ns, of one run over `segs` (fed as the RT thread does: as
/// many as the buffer takes before each tick).
fn tick_times_ns(segs: &[Segment]) -> Vec<f64> {
    let mut ip = Interpolator::new(3, segs[0].path.start());
    let mut next = 0;
    let mut ns = vec![];
    loop {
        while next < segs.len() && ip.has_room() {
            ip.push(segs[next]).unwrap();
            next += 1;
        }
        let t0 = Instant::now();
        let out = ip.tick();
        ns.push(t0.elapsed().as_nanos() as f64);
        if out.state == InterpState::Idle && next == segs.len() {
            break;
        }
    }
    ns
}

/// Tick cost: the interpolator is deterministic, so every run has the same ticks; the cost
/// of a tick is its minimum over `RUNS` runs (a tick preempted in one run, which on this
/// shared machine happens for milliseconds, is not the interpolator's work). The largest
/// single measurement is shown too.
fn tick_cost() {
    const RUNS: usize = 5;
    println!("## Interpolation cost per tick (3 axes; per tick the minimum of {RUNS} runs)\n");
    println!("| toolpath | profile | ticks | p50 µs | p99 µs | max µs | max µs of a single run |");
    println!("|---|---|---:|---:|---:|---:|---:|");
    let progs = [
        ("dense circle 0.05 mm", dense_blocks(20_000)),
        ("mixed arcs", mixed_arcs()),
        ("pocket sharp corners", pocket(30.0, 20.0, 2.0, 2000.0)),
    ];
    // Linear and parabolic with the constants files; and the daemon's defaults without
    // constants (the axes' limits alone: the per-axis box on the setpoints chooses them).
    let configs = [
        ("linear", ours(1)),
        ("parabolic", ours(2)),
        ("linear, axes only", daemon_config(&default_axes(), None)),
    ];
    let splines = reference_paths().into_iter().find(|p| p.name == "splines");
    let splines = splines.map(|p| ("random splines (#32)", p.blocks));
    let runs = progs.iter().flat_map(|(name, blocks)| {
        configs
            .iter()
            .map(move |(kind, c)| (*name, blocks, *kind, c))
    });
    let reference = reference_config();
    // Arcs judged by the box (issue #49), with the constants file of defaults.
    let default_rek = reference_config_with("machine-default.rek");
    let arcs: Vec<_> = programs_in("arcs")
        .into_iter()
        .filter_map(|(n, b)| match n.as_str() {
            "arcfit-small" => Some(("arc-fitted, 0.5-5 mm (#49)", b)),
            "fillet-tiny" => Some(("fillets of 0.01-0.05 mm (#49)", b)),
            _ => None,
        })
        .collect();
    // The jerk-limited box (issue #49): the parabolic profile of `machine-parabolic.rek`.
    let parabolic_rek = reference_config_with("machine-parabolic.rek");
    let jerk_paths: Vec<_> = reference_paths()
        .into_iter()
        .filter(|p| ["splines", "lissajous", "surface", "zigzag"].contains(&p.name.as_str()))
        .map(|p| (p.name.clone(), p.blocks))
        .chain(
            programs_in("arcs")
                .into_iter()
                .filter(|(n, _)| n == "arcfit-small" || n == "fillet-tiny"),
        )
        .collect();
    let runs = runs
        .chain(
            splines
                .iter()
                .map(|(name, blocks)| (*name, blocks, "linear, axes only", &reference)),
        )
        .chain(jerk_paths.iter().map(|(name, blocks)| {
            (
                name.as_str(),
                blocks,
                "parabolic, machine-parabolic.rek",
                &parabolic_rek,
            )
        }))
        .chain(
            arcs.iter()
                .map(|(name, blocks)| (*name, blocks, "linear, TAB0.REK defaults", &default_rek)),
        );
    for (name, blocks, kind, cfg) in runs {
        {
            // Plan everything first so only the interpolator is timed.
            let mut pl = Planner::new(cfg.clone(), 1);
            let mut segs = vec![];
            for b in blocks.iter() {
                while !pl.wants_input() {
                    segs.extend(pl.poll());
                }
                pl.push(b).unwrap();
                while let Some(s) = pl.poll() {
                    segs.push(s);
                }
            }
            pl.finish();
            while let Some(s) = pl.poll() {
                segs.push(s);
            }
            let mut ns = tick_times_ns(&segs);
            let mut single_max = ns.iter().copied().fold(0.0, f64::max);
            for _ in 1..RUNS {
                let run = tick_times_ns(&segs);
                assert_eq!(run.len(), ns.len());
                single_max = run.iter().copied().fold(single_max, f64::max);
                for (m, t) in ns.iter_mut().zip(run) {
                    *m = m.min(t);
                }
            }
            ns.sort_by(|a, b| a.partial_cmp(b).unwrap());
            let q = |p: f64| ns[((ns.len() - 1) as f64 * p) as usize] / 1000.0;
            println!(
                "| {name} | {kind} | {} | {:.2} | {:.2} | {:.2} | {:.2} |",
                ns.len(),
                q(0.5),
                q(0.99),
                ns[ns.len() - 1] / 1000.0,
                single_max / 1000.0
            );
        }
    }
    println!();
}

/// Issue #32: the planner on the paths of the independent reference
/// (`scripts/planner-reference/`: exact junction bound on the polyline and TOPP-RA on the
/// smooth curve, per-axis box constraints), on the configuration `cncd` builds for the
/// issue's machine. `scripts/linuxcnc-compare/` reads this table.
fn reference_paths_table() {
    println!("## Dense paths against the independent reference (issue #32)\n");
    println!(
        "| path | blocks | exact s | smooth (TOPP-RA) s | limit s | planner s | planner / limit | max axis a / limit | off path mm |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|");
    let cfg = reference_config();
    for p in reference_paths() {
        let r = run(cfg.clone(), &p.blocks);
        let w = measure(&cfg, &r, 8.0);
        println!(
            "| {} | {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.4} | {:.1e} |",
            p.name,
            p.blocks.len(),
            p.exact_s,
            p.smooth_s,
            p.limit_s,
            r.time_s(),
            r.time_s() / p.limit_s,
            w.axis_a,
            w.off_path_mm
        );
    }
    println!();
}

/// `cargo bench -p kernel --bench plan -- count [zigzag]`: one planner pass over 20000 circle
/// chords (or the throughput table's alternating 0.1 mm zig-zag; linear.rek), for an
/// instruction count under valgrind (load-independent).
fn count_only() {
    let blocks = if std::env::args().any(|a| a == "zigzag") {
        zigzag_blocks(20_000)
    } else {
        dense_blocks(20_000)
    };
    let mut pl = Planner::new(ours(1), 1);
    let mut n = 0usize;
    for b in &blocks {
        while !pl.wants_input() {
            n += usize::from(pl.poll().is_some());
        }
        pl.push(b).unwrap();
        while pl.poll().is_some() {
            n += 1;
        }
    }
    pl.finish();
    while pl.poll().is_some() {
        n += 1;
    }
    println!("{n} segments");
}

/// `cargo bench -p kernel --bench plan -- count-ticks [parabolic]`: the interpolator over
/// 20000 circle chords planned first (linear.rek, or parabolic.rek), for an instruction count
/// of `Interpolator::tick` under valgrind (`--toggle-collect='*Interpolator::tick*'`); prints
/// the number of ticks.
fn count_ticks_only() {
    // `count-ticks <reference path>`: that path on the issue #32 machine (the per-axis box
    // chooses the setpoints; with `parabolic`, see below); `count-ticks box`: the dense circle
    // on it; `count-ticks axes`: the dense circle on the daemon's defaults without constants.
    let path = reference_paths()
        .into_iter()
        .find(|p| std::env::args().any(|a| a == p.name));
    let boxed = path.is_some() || std::env::args().any(|a| a == "box");
    let blocks = path.map_or_else(|| dense_blocks(20_000), |p| p.blocks);
    let profile = if std::env::args().any(|a| a == "parabolic") {
        2
    } else {
        1
    };
    // `count-ticks axes`: the dense circle on the daemon's defaults without constants.
    // `count-ticks <reference path> parabolic`: that path on `machine-parabolic.rek` (the
    // jerk-limited box chooses the setpoints).
    let cfg = if boxed && profile == 2 {
        reference_config_with("machine-parabolic.rek")
    } else if boxed {
        reference_config()
    } else if std::env::args().any(|a| a == "axes") {
        daemon_config(&default_axes(), None)
    } else {
        ours(profile)
    };
    let mut pl = Planner::new(cfg, 1);
    let mut segs = vec![];
    for b in &blocks {
        while !pl.wants_input() {
            segs.extend(pl.poll());
        }
        pl.push(b).unwrap();
        segs.extend(std::iter::from_fn(|| pl.poll()));
    }
    pl.finish();
    segs.extend(std::iter::from_fn(|| pl.poll()));
    println!("{} ticks", tick_times_ns(&segs).len());
}

/// `cargo bench -p kernel --bench plan -- fingerprint`: per path and configuration the
/// number of ticks and a checksum of the setpoints, to see whether a change of the planner's
/// or interpolator's code changed any trajectory. `fingerprint segments` adds a checksum of
/// every committed segment's speeds and limits (the planner's output itself).
fn fingerprint() {
    let segments = std::env::args().any(|a| a == "segments");
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/benches/plan");
    let mut configs = vec![("reference".to_string(), reference_config())];
    for name in ["linear", "parabolic"] {
        let c = constants_file(&format!("{dir}/{name}.rek"));
        configs.push((name.to_string(), daemon_config(&default_axes(), Some(&c))));
        configs.push((
            format!("{name} unequal"),
            daemon_config(&unequal_axes(), Some(&c)),
        ));
    }
    configs.push(("defaults".to_string(), daemon_config(&default_axes(), None)));
    let mut paths: Vec<(String, Vec<Block>)> = reference_paths()
        .into_iter()
        .map(|p| (p.name, p.blocks))
        .collect();
    paths.extend(daemon_suite().into_iter().map(|(n, b)| (n.to_string(), b)));
    paths.push(("unequal".to_string(), unequal_limits_path()));
    for (cname, cfg) in &configs {
        for (pname, blocks) in &paths {
            let r = run(cfg.clone(), blocks);
            let mut h = 0u64;
            for t in &r.ticks {
                for k in 0..cfg.axes {
                    h = h.rotate_left(5) ^ t.position[k].to_bits();
                }
            }
            if segments {
                // Every committed segment's limits and speeds, bit for bit.
                let mut s = 0u64;
                for g in &r.segments {
                    for x in [
                        g.length_mm,
                        g.feed_mm_s,
                        g.v_max_mm_s,
                        g.v_end_mm_s,
                        g.junction_cap_mm_s,
                        g.accel_mm_s2,
                        g.jerk_mm_s3,
                        g.stop_accel_mm_s2,
                    ] {
                        s = s.rotate_left(5) ^ x.to_bits();
                    }
                    s = s.rotate_left(5) ^ g.junction as u64;
                }
                println!(
                    "{cname:18} {pname:40} {:7} ticks {h:016x} {:6} segments {s:016x}",
                    r.ticks.len(),
                    r.segments.len()
                );
                continue;
            }
            println!("{cname:18} {pname:40} {:7} ticks {h:016x}", r.ticks.len());
        }
    }
}

fn main() {
    if std::env::args().any(|a| a == "fingerprint") {
        fingerprint();
        return;
    }
    if std::env::args().any(|a| a == "count") {
        count_only();
        return;
    }
    if std::env::args().any(|a| a == "count-ticks") {
        count_ticks_only();
        return;
    }
    if std::env::args().any(|a| a == "speed") {
        throughput();
        tick_cost();
        return;
    }
    if std::env::args().any(|a| a == "ticks") {
        tick_cost();
        return;
    }
    reference_paths_table();
    if std::env::args().any(|a| a == "reference") {
        return;
    }
    machining_times();
    parabolic_moves();
    throughput();
    tick_cost();
}
