//! Radius compensation throughput (issue #4 goal: ≥ 1,000,000 blocks/s): a 100,000-block
//! contour of lines and arcs pushed through the streaming compensator and polled out.
//! Prints a table; no assertions (team rule: figures, not timed tests).

use std::hint::black_box;
use std::time::Instant;

use kernel::block::{ArcDir, Block, BlockKind, Comp, Continuity, Feed, Path, Plane, Spindle};
use kernel::comp::{CompConfig, Compensator, CornerMode};
use kernel::units::AxesMm;

const BLOCKS: usize = 100_000;

fn block(seq: usize, kind: BlockKind, comp: Comp) -> Block {
    Block {
        seq: seq as u32,
        n: Some(seq as u32 * 10),
        line: seq as u32 + 1,
        kind,
        feed: Feed::MmPerMin(1000.0),
        plane: Plane::G17,
        comp,
        continuity: Continuity::G23,
        dyn_set: 1,
        spindle: Spindle::default(),
        m: [None; 4],
    }
}

struct Builder {
    out: Vec<Block>,
    pos: AxesMm,
}

impl Builder {
    fn push(&mut self, end: AxesMm, path: Path, comp: Comp) {
        let seq = self.out.len();
        let start = self.pos;
        self.out
            .push(block(seq, BlockKind::Motion { start, end, path }, comp));
        self.pos = end;
    }
}

fn at(x: f64, y: f64, z: f64) -> AxesMm {
    AxesMm([x, y, z, 0.0, 0.0, 0.0])
}

/// A serpentine of lines and arcs with corners both ways (convex and concave arcs, sharp
/// corners); a Z move (bridged) every 10 cycles of 5 blocks.
fn contour(n: usize) -> Vec<Block> {
    let comp = Comp::Left {
        d: 1,
        radius_mm: 2.0,
    };
    let mut b = Builder {
        out: Vec::with_capacity(n),
        pos: AxesMm::ZERO,
    };
    b.push(at(0.0, -10.0, 0.0), Path::Line, Comp::Off);
    b.push(at(0.0, 0.0, 0.0), Path::Line, comp);
    let mut x = 0.0;
    let mut cycle = 0;
    while b.out.len() + 7 < n {
        let z = b.pos[2];
        if cycle % 10 == 9 {
            b.push(
                at(x, 0.0, if z == 0.0 { -1.0 } else { 0.0 }),
                Path::Line,
                comp,
            );
        }
        let z = b.pos[2];
        let arc = |dir, cx| Path::Arc {
            dir,
            center: at(cx, 20.0, z),
            plane: Plane::G17,
        };
        // Inside corner, convex half circle (G2), tangent concave quarter (G3), outside corner.
        b.push(at(x + 10.0, 0.0, z), Path::Line, comp);
        b.push(at(x + 10.0, 20.0, z), Path::Line, comp);
        b.push(at(x + 20.0, 20.0, z), arc(ArcDir::Cw, x + 15.0), comp);
        b.push(at(x + 30.0, 10.0, z), arc(ArcDir::Ccw, x + 30.0), comp);
        b.push(at(x + 30.0, 0.0, z), Path::Line, comp);
        x += 30.0;
        cycle += 1;
    }
    while b.out.len() + 1 < n {
        x += 1.0;
        let z = b.pos[2];
        b.push(at(x, 0.0, z), Path::Line, comp);
    }
    let (px, pz) = (b.pos[0], b.pos[2]);
    b.push(at(px + 10.0, -10.0, pz), Path::Line, Comp::Off);
    b.out
}

fn run(blocks: &[Block], cfg: CompConfig) -> (usize, usize) {
    let mut c = Compensator::new(cfg);
    let mut n_out = 0;
    let mut errs = 0;
    for b in blocks {
        if c.push(b).is_err() {
            errs += 1;
        }
        while let Some(o) = c.poll() {
            black_box(&o);
            n_out += 1;
        }
    }
    c.finish();
    while let Some(o) = c.poll() {
        black_box(&o);
        n_out += 1;
    }
    black_box(c.take_diagnostics());
    (n_out, errs)
}

/// CPU time this thread has run, ns (Linux `/proc/thread-self/schedstat`, first field): on
/// a machine shared by many processes the wall clock mostly measures waiting for a core.
fn cpu_ns() -> Option<u64> {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

fn main() {
    let blocks = contour(BLOCKS);
    let modes = [
        ("R339=0 intersections", CompConfig::default()),
        (
            "R339=1 arcs >5°",
            CompConfig {
                corner_mode: CornerMode::ArcAboveLimit,
                arc_insertion_limit_deg: 5.0,
                ..CompConfig::default()
            },
        ),
        ("R397 3+4-block, R764, R765", {
            let mut c = CompConfig::default();
            c.check.optimise_3_blocks = true;
            c.check.optimise_4_blocks = true;
            c.exit.optimise = true;
            c.position.report = true;
            c
        }),
    ];
    println!("radius compensation, {} programmed blocks", blocks.len());
    println!(
        "{:<28} {:>10} {:>8} {:>10} {:>14} {:>10} {:>14}",
        "mode", "out blocks", "errors", "best ms", "blocks/s", "cpu ms", "blocks/cpu-s"
    );
    for (name, cfg) in modes {
        let mut best = f64::MAX;
        let mut best_cpu = f64::MAX;
        let mut res = (0, 0);
        for _ in 0..7 {
            let (t, c0) = (Instant::now(), cpu_ns());
            res = run(&blocks, cfg);
            best = best.min(t.elapsed().as_secs_f64());
            if let (Some(a), Some(b)) = (c0, cpu_ns()) {
                best_cpu = best_cpu.min((b - a) as f64 * 1e-9);
            }
        }
        println!(
            "{:<28} {:>10} {:>8} {:>10.2} {:>14.0} {:>10.2} {:>14.0}",
            name,
            res.0,
            res.1,
            best * 1e3,
            blocks.len() as f64 / best,
            best_cpu * 1e3,
            blocks.len() as f64 / best_cpu
        );
    }
}
