//! Planner and interpolator figures (issue #5): machining time per toolpath in linear and
//! parabolic mode against a reference planner (16-block look-ahead, one block per tick),
//! planner throughput, and interpolation cost per tick. Prints tables; asserts nothing.
//!
//! Run: `cargo bench -p kernel --bench plan`

#[path = "../tests/plan_common/mod.rs"]
mod plan_common;

use std::time::Instant;

use kernel::block::{Block, Continuity};
use kernel::interp::{InterpState, Interpolator};
use kernel::plan::{Planner, PlannerConfig};
use plan_common::*;

/// Our settings: the suite constants with the minimum block duration at 0.
fn ours(profile: u8) -> PlannerConfig {
    let mut c = config(profile);
    c.min_block_time_s = 0.0;
    c
}

/// Reference planner in the style of LinuxCNC/Grbl: the same junction criteria, but a
/// 16-block look-ahead window and every block lasting at least one tick (one block per tick).
fn reference() -> PlannerConfig {
    let mut c = config(1);
    c.lookahead_blocks = 16;
    c.min_block_time_s = kernel::TS_S;
    c.envelope.rule = kernel::plan::ContinuityRule::Manual;
    c
}

fn machining_times() {
    println!("## Machining time per toolpath (virtual time, 4 ms ticks)\n");
    println!(
        "| toolpath | blocks | linear s | parabolic s | reference s (16 blocks, 1 block/tick) | reference / linear |"
    );
    println!("|---|---:|---:|---:|---:|---:|");
    for (name, blocks) in suite() {
        let lin = run(ours(1), &blocks).time_s();
        let par = run(ours(2), &blocks).time_s();
        let refr = run(reference(), &blocks).time_s();
        println!(
            "| {name} | {} | {lin:.3} | {par:.3} | {refr:.3} | {:.2} |",
            blocks.len(),
            refr / lin
        );
    }
    println!();
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

fn throughput() {
    println!("## Planner throughput (push + poll, 500-block look-ahead)\n");
    println!("| program | profile | blocks | seconds | blocks/s |");
    println!("|---|---|---:|---:|---:|");
    let n = 200_000;
    let blocks = dense_blocks(n);
    let mut zz = Prog::new(p3(0.0, 0.0, 0.0), 6000.0, Continuity::G23);
    for i in 0..n {
        zz.g1(p3((i + 1) as f64 * 0.1, ((i + 1) % 2) as f64 * 0.02, 0.0));
    }
    for (name, prog) in [
        ("0.05 mm circle chords", &blocks),
        ("0.1 mm zig-zag", &zz.blocks),
    ] {
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

fn tick_cost() {
    println!("## Interpolation cost per tick (3 axes)\n");
    println!("| toolpath | profile | ticks | p50 µs | p99 µs | max µs |");
    println!("|---|---|---:|---:|---:|---:|");
    let progs = [
        ("dense circle 0.05 mm", dense_blocks(20_000)),
        ("mixed arcs", mixed_arcs()),
        ("pocket sharp corners", pocket(30.0, 20.0, 2.0, 2000.0)),
    ];
    for (name, blocks) in progs.iter() {
        for profile in [1u8, 2] {
            // Plan everything first so only the interpolator is timed.
            let mut pl = Planner::new(ours(profile), 1);
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
            let start = segs[0].path.start();
            let mut ip = Interpolator::new(3, start);
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
            ns.sort_by(|a, b| a.partial_cmp(b).unwrap());
            let q = |p: f64| ns[((ns.len() - 1) as f64 * p) as usize] / 1000.0;
            let kind = if profile == 1 { "linear" } else { "parabolic" };
            println!(
                "| {name} | {kind} | {} | {:.2} | {:.2} | {:.2} |",
                ns.len(),
                q(0.5),
                q(0.99),
                ns[ns.len() - 1] / 1000.0
            );
        }
    }
    println!();
}

fn main() {
    machining_times();
    throughput();
    tick_cost();
}
