//! Parse + interpret a generated 1,000,000-block program, in the CNC836 dialect and the same
//! program in the ISO dialect (issue #3 goals: ≥ 1,000,000 blocks/s
//! on one core, < 100 bytes of memory per block).
//!
//! Memory is measured with a counting global allocator: peak bytes allocated while a pass
//! runs, divided by the number of blocks. The program text itself is reported separately (the
//! daemon holds it once, e.g. memory-mapped or read in full) and is also included in a
//! "total" column so nothing is hidden.
//!
//! Run: `cargo bench -p kernel --bench parse` (release profile).

use std::hint::black_box;
use std::time::Instant;

use kernel::program::{Setup, compile, stream, validate};

#[global_allocator]
static ALLOC: alloc_count::Counting = alloc_count::Counting;

/// Resets the peak to the current level and returns that level.
fn mark() -> usize {
    alloc_count::mark_peak()
}

const BLOCKS: usize = 1_000_000;

/// A CAM-like program: lines with three axes, half circles, rapids, feed changes, comments,
/// continuity and a parameter now and then. Every block is valid.
fn generate() -> String {
    let mut s = String::with_capacity(BLOCKS * 32);
    s.push_str("; generated benchmark program\nN1 G17 G90 G23 I1 M3 S1200 F2000\n");
    let mut x = 0.0f64;
    let mut n = 2u32;
    while (n as usize) < BLOCKS {
        let k = n % 10;
        let line = match k {
            0 => format!("N{n} G0 X{x:.3} Y0 Z5"),
            1 => format!("N{n} G1 Z-1.5 F800"),
            2..=5 => {
                x += 0.25;
                format!(
                    "N{n} G1 X{x:.3} Y{:.3} F{}",
                    (n % 7) as f64 * 0.5,
                    1500 + k * 100
                )
            }
            6 => {
                // Half circle from (x, y) about (x + 1, y); y is 3.0 after k = 5 (n % 7 varies):
                let y = ((n - 1) % 7) as f64 * 0.5;
                x += 2.0;
                format!("N{n} G2 X{x:.3} Y{y:.3} I1 J0")
            }
            7 => {
                let y = ((n - 2) % 7) as f64 * 0.5;
                x += 2.0;
                format!("N{n} G3 X{x:.3} Y{y:.3} I1.0 J0.0 ; back")
            }
            8 => format!("N{n} R7={x:.1} G1 Z-2"),
            _ => format!("N{n} G1 XR7 M8"),
        };
        s.push_str(&line);
        s.push('\n');
        n += 1;
    }
    s
}

fn main() {
    let text = generate();
    let setup = Setup::new(&['X', 'Y', 'Z']);
    let blocks = text.lines().filter(|l| !l.starts_with(';')).count();
    let text_per_block = text.len() as f64 / blocks as f64;

    // Sanity: the generated program is valid (an invalid one would measure error paths).
    let head: String = text.lines().take(20_000).collect::<Vec<_>>().join("\n");
    let c = compile(&head, &setup);
    assert!(
        !c.has_errors(),
        "{:?}",
        &c.diagnostics[..c.diagnostics.len().min(3)]
    );

    println!(
        "parse + interpret, {blocks} blocks, program text {:.1} MB ({text_per_block:.1} bytes/block)",
        text.len() as f64 / 1e6
    );
    println!(
        "{:<30} {:>9} {:>12} {:>12} {:>13} {:>16}",
        "pass", "time ms", "blocks/s", "peak bytes", "peak B/block", "incl. text B/bl"
    );

    // 1. validate: messages only (the daemon's check before running).
    let (best, peak) = best_of_3(|| {
        let d = validate(black_box(&text), &setup);
        assert!(d.is_empty(), "{:?}", &d[..d.len().min(3)]);
    });
    row(
        "validate (diagnostics only)",
        best,
        blocks,
        peak,
        text.len(),
    );

    // 2. stream: blocks one at a time (execution).
    let (best, peak) = best_of_3(|| {
        let mut count = 0usize;
        let mut sum = 0.0;
        for b in stream(black_box(&text), &setup) {
            let b = b.expect("valid program");
            if let Some((_, end, _)) = b.motion() {
                sum += end[0];
            }
            count += 1;
        }
        black_box(sum);
        assert_eq!(count, blocks);
    });
    row(
        "stream (one block at a time)",
        best,
        blocks,
        peak,
        text.len(),
    );

    // 2b. the same program in the ISO dialect (RS274-NGC): G64 for G23, #7 for R7.
    let iso_text = text
        .replace("G23 I1", "G64")
        .replace("R7=", "#7=")
        .replace("XR7", "X#7")
        .replace("N1 G17", "N1 G1 G17");
    let iso = Setup {
        dialect: kernel::program::Dialect::Iso,
        ..setup.clone()
    };
    let (best, peak) = best_of_3(|| {
        let d = validate(black_box(&iso_text), &iso);
        assert!(
            !d.iter().any(|d| d.is_error()),
            "{:?}",
            &d[..d.len().min(3)]
        );
    });
    row("validate, ISO dialect", best, blocks, peak, iso_text.len());

    // 3. compile: all blocks held (for comparison only; not how the daemon runs a program).
    let base = mark();
    let t = Instant::now();
    let c = compile(black_box(&text), &setup);
    let dt = t.elapsed().as_secs_f64();
    let peak = alloc_count::peak_bytes() - base;
    assert_eq!(c.blocks.len(), blocks);
    drop(c);
    row("compile (all blocks held)", dt, blocks, peak, text.len());
    println!(
        "size_of::<Block>() = {} bytes; one core, best of 3 for the streaming passes",
        std::mem::size_of::<kernel::block::Block>()
    );
    // Figures on a shared machine depend on its load: print it next to them.
    if let Ok(l) = std::fs::read_to_string("/proc/loadavg") {
        println!("load average while measuring: {}", l.trim());
    }
}

/// Runs `pass` three times: the best time in seconds and the highest peak of bytes allocated
/// above the level before each run (what the pass holds, its results included until dropped).
fn best_of_3(mut pass: impl FnMut()) -> (f64, usize) {
    let mut best = f64::MAX;
    let mut peak = 0;
    for _ in 0..3 {
        let base = mark();
        let t = Instant::now();
        pass();
        let dt = t.elapsed().as_secs_f64();
        peak = peak.max(alloc_count::peak_bytes() - base);
        best = best.min(dt);
    }
    (best, peak)
}

fn row(name: &str, secs: f64, blocks: usize, peak: usize, text: usize) {
    println!(
        "{name:<30} {:>9.1} {:>12.0} {peak:>12} {:>13.3} {:>16.1}",
        secs * 1e3,
        blocks as f64 / secs,
        peak as f64 / blocks as f64,
        (peak + text) as f64 / blocks as f64
    );
}
