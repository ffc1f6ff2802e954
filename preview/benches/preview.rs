//! Preview figures (issue #10): time and peak heap of the program preview and the velocity
//! plot for programs of 10,000 to 1,000,000 blocks. Prints a table; asserts nothing.
//!
//! Run: `cargo bench -p preview --bench preview` (`PREVIEW_BENCH=outline`: the outline only)
//!
//! Peak heap is counted by a global allocator above the level before each call (the program
//! text itself is not counted: the caller holds it anyway).

use std::fmt::Write;
use std::time::Instant;

use preview::PreviewOptions;

#[global_allocator]
static ALLOC: alloc_count::Counting = alloc_count::Counting;

/// Runs `f`, returns its result, seconds and peak heap above the level before, MiB.
fn measure<T>(f: impl FnOnce() -> T) -> (T, f64, f64) {
    let base = alloc_count::mark_peak();
    let t = Instant::now();
    let out = f();
    let s = t.elapsed().as_secs_f64();
    let peak = alloc_count::peak_bytes().saturating_sub(base);
    (out, s, peak as f64 / (1024.0 * 1024.0))
}

/// A pocket of `n` blocks: concentric rings of 0.2 mm chords under G23 with a step-over line
/// between rings, an arc every 50 blocks, and a rapid retract every 20,000 blocks.
fn program(n: usize) -> String {
    let mut t = String::with_capacity(n * 24);
    t.push_str("N1 G0 X0 Y0 Z1\nG1 Z-1 F500\nG23 G1 X5 F3000\n");
    let mut blocks = 3;
    let mut r = 5.0f64;
    let mut a = 0.0f64;
    // The position is on the circle of radius `r` (not just after a step-over).
    let mut on_circle = true;
    while blocks < n {
        if blocks % 20_000 == 0 {
            let _ = writeln!(
                t,
                "G0 Z1\nG1 Z-1 F500\nG1 X{:.4} Y{:.4} F3000",
                r * a.cos(),
                r * a.sin()
            );
            blocks += 3;
            continue;
        }
        if blocks % 50 == 0 && on_circle {
            // A tangent arc of 0.5 rad on the same circle (I, J relative to the start).
            let (x0, y0) = (r * a.cos(), r * a.sin());
            a += 0.5;
            let _ = writeln!(
                t,
                "G3 X{:.4} Y{:.4} I{:.4} J{:.4}",
                r * a.cos(),
                r * a.sin(),
                -x0,
                -y0
            );
        } else {
            a += 0.2 / r;
            let _ = writeln!(t, "G1 X{:.4} Y{:.4}", r * a.cos(), r * a.sin());
        }
        on_circle = true;
        blocks += 1;
        if a > std::f64::consts::TAU {
            a -= std::f64::consts::TAU;
            r += 0.5;
            if r > 60.0 {
                r = 5.0;
            }
            on_circle = false;
        }
    }
    t
}

/// The first error of a program that should have none.
fn first(e: Vec<kernel::Diagnostic>) -> String {
    format!("{} errors, first: {}", e.len(), e[0])
}

/// A sink that keeps nothing (the pass alone).
struct Nothing;
impl preview::pipeline::Sink for Nothing {
    fn segment(&mut self, _s: &kernel::plan::Segment) {}
}

/// The outline the daemon collects in the selection's pass (`GetPreviewOutline`): the pass
/// alone, the pass with the outline, and one view of the whole program at 1280 x 800.
fn outline_figures(opts: &PreviewOptions) {
    use preview::outline::{Outline, Plane};
    println!("## Outline (GetPreviewOutline): its cost in the pass, and one view\n");
    println!(
        "| blocks | pass s | pass + outline s | outline peak heap MiB | view s | view points | dots |"
    );
    println!("|---:|---:|---:|---:|---:|---:|---:|");
    for n in [100_000usize, 1_000_000] {
        let text = program(n);
        let (_, bare_s, _) = measure(|| {
            preview::pipeline::run(&text, opts, &mut Nothing)
                .map_err(first)
                .unwrap()
        });
        let (o, s, peak) = measure(|| {
            let mut o = Outline::new(&opts.setup.axis_names);
            preview::pipeline::run(&text, opts, &mut o)
                .map_err(first)
                .unwrap();
            o
        });
        let (v, view_s, _) = measure(|| o.view(Plane::parse("xy").unwrap(), None, 1280, 800));
        let points = (v.feed.xy.len() + v.rapid.xy.len() + v.comp.xy.len()) / 2;
        println!(
            "| {n} | {bare_s:.2} | {s:.2} | {peak:.1} | {view_s:.3} | {points} | {} |",
            (v.smooth.len() + v.red.len()) / 2
        );
    }
    println!();
}

fn main() {
    let mut opts = PreviewOptions::default();
    opts.setup.constants.set(384, 200.008);
    opts.planner = opts.planner.clone().with_constants(&opts.setup.constants);
    // PREVIEW_BENCH=outline: the outline figures alone.
    if std::env::var("PREVIEW_BENCH").as_deref() == Ok("outline") {
        outline_figures(&opts);
        return;
    }
    outline_figures(&opts);
    println!("## Program preview (release build, one thread)\n");
    println!(
        "| blocks | text MiB | render s | blocks/s | peak heap MiB | SVG KiB | SVG s | PNG KiB | PNG s | red | yellow |"
    );
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for n in [10_000usize, 100_000, 1_000_000] {
        let text = program(n);
        let (p, s, peak) =
            measure(|| preview::render(&text, &opts).unwrap_or_else(|e| panic!("{}", first(e))));
        let (svg, svg_s, _) = measure(|| p.to_svg());
        let (png, png_s, _) = measure(|| p.to_png().expect("png"));
        // To look at the pictures: PREVIEW_BENCH_OUT=/tmp/dir (nothing written otherwise).
        if let Ok(dir) = std::env::var("PREVIEW_BENCH_OUT") {
            std::fs::write(format!("{dir}/preview_{n}.png"), &png).expect("writable");
        }
        println!(
            "| {} | {:.1} | {s:.2} | {:.0} | {peak:.1} | {} | {svg_s:.3} | {} | {png_s:.3} | {} | {} |",
            p.total_blocks,
            text.len() as f64 / (1024.0 * 1024.0),
            f64::from(p.total_blocks) / s,
            svg.len() / 1024,
            png.len() / 1024,
            p.red_junctions,
            p.smooth_junctions
        );
    }
    println!();
    println!("## Velocity plot (planner + 4 ms interpolator over the whole run)\n");
    println!("| blocks | machining s | plot s | peak heap MiB | SVG KiB |");
    println!("|---:|---:|---:|---:|---:|");
    for n in [10_000usize, 100_000, 1_000_000] {
        let text = program(n);
        let (v, s, peak) = measure(|| {
            preview::velocity_plot(&text, &opts, true).unwrap_or_else(|e| panic!("{}", first(e)))
        });
        println!(
            "| {n} | {:.0} | {s:.2} | {peak:.1} | {} |",
            v.end_s,
            v.to_svg().len() / 1024
        );
    }
    println!();
    println!("## One R387 page of 50,000 blocks out of 1,000,000\n");
    println!("| page | render s | peak heap MiB |");
    println!("|---:|---:|---:|");
    let text = program(1_000_000);
    for page in [1u32, 10, 20] {
        let mut o = opts.clone();
        o.page_blocks = Some(50_000);
        o.page = page;
        let (_, s, peak) =
            measure(|| preview::render(&text, &o).unwrap_or_else(|e| panic!("{}", first(e))));
        println!("| {page} | {s:.2} | {peak:.1} |");
    }
}
