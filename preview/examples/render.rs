//! Writes a preview or a velocity plot of a program file (the README pictures are made with
//! it, see `docs/preview.md`). The library itself does no IO; this example does.
//!
//! `cargo run -p preview --example render -- FILE OUT.svg|OUT.png [--plane xy|xz|yz]
//! [--page N] [--page-blocks N] [--velocity] [--accel] [--const R=VALUE]... [--axes XZ]
//! [--diameter X] [--offset D:R:X:Z]... [--gear M:P]...`
//!
//! `--axes` sets the machine's axis letters (default XYZ), `--diameter` the axis programmed as
//! a diameter (a lathe's X, docs/lathe.md: the picture shows the true profile, X as a radius),
//! `--offset` fills an offset table entry (radius, X length as a diameter, Z length), `--gear`
//! adds a spindle gear range selected by M code M with top speed P rpm (feed per revolution
//! under KŘR is planned at the gear's top speed).

use preview::{PreviewOptions, ViewPlane};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        eprintln!(
            "usage: render FILE OUT.svg|OUT.png [--plane xy|xz|yz] [--page N] [--page-blocks N] [--velocity] [--accel] [--const R=VALUE]... [--axes XZ] [--diameter X] [--offset D:R:X:Z]... [--gear M:P]..."
        );
        std::process::exit(2);
    }
    let text = std::fs::read_to_string(&args[0]).expect("readable program");
    let mut setup = kernel::program::Setup::new(&['X', 'Y', 'Z']);
    let (mut plane, mut page, mut per, mut velocity, mut accel) =
        (ViewPlane::Xy, 1, None, false, false);
    let mut i = 2;
    while i < args.len() {
        match args[i].as_str() {
            "--plane" => {
                i += 1;
                plane = ViewPlane::parse(&args[i]).expect("xy, xz or yz");
            }
            "--page" => {
                i += 1;
                page = args[i].parse().expect("page number");
            }
            "--page-blocks" => {
                i += 1;
                per = Some(args[i].parse().expect("blocks per page"));
            }
            "--velocity" => velocity = true,
            "--accel" => accel = true,
            "--const" => {
                i += 1;
                let (r, v) = args[i]
                    .trim_start_matches('R')
                    .split_once('=')
                    .expect("R=VALUE");
                setup.constants.set(
                    r.parse().expect("constant number"),
                    v.parse().expect("value"),
                );
            }
            "--axes" => {
                i += 1;
                setup.axis_names = args[i].to_ascii_uppercase().chars().collect();
            }
            "--diameter" => {
                i += 1;
                let letter = args[i].to_ascii_uppercase().chars().next();
                setup.diameter_axis = setup.axis_names.iter().position(|&a| Some(a) == letter);
                assert!(setup.diameter_axis.is_some(), "--diameter: not an axis");
            }
            "--offset" => {
                i += 1;
                let v: Vec<f64> = args[i]
                    .split(':')
                    .map(|x| x.parse().expect("number"))
                    .collect();
                let mut values = [None; 5];
                for (k, x) in v.iter().skip(1).take(5).enumerate() {
                    values[k] = Some(*x);
                }
                let edit = kernel::offsets::TableEdit {
                    entry: v[0] as u8,
                    values,
                };
                setup.offsets.apply(&edit).expect("offset entry 1..99");
            }
            "--gear" => {
                i += 1;
                let (m, p) = args[i].split_once(':').expect("M:P");
                setup.gears.push(kernel::kr::Gear {
                    max_rpm: p.parse().expect("rpm"),
                    output_range: 0x7FFF,
                    m_code: Some(m.parse().expect("M code")),
                });
            }
            other => panic!("unknown option {other}"),
        }
        i += 1;
    }
    let mut opts = PreviewOptions::new(setup);
    opts.plane = plane;
    opts.page = page;
    opts.page_blocks = per;
    let out = &args[1];
    let png = out.ends_with(".png");
    let bytes = if velocity {
        opts.height_px = if accel { 700 } else { 500 };
        let v = preview::velocity_plot(&text, &opts, accel).unwrap_or_else(|e| fail(e));
        eprintln!(
            "{:.2} s .. {:.2} s, {} block boundaries, top speed {:.0} mm/min",
            v.start_s, v.end_s, v.boundaries, v.max_speed_mm_min
        );
        if png {
            v.to_png().expect("png")
        } else {
            v.to_svg().into_bytes()
        }
    } else {
        let p = preview::render(&text, &opts).unwrap_or_else(|e| fail(e));
        eprintln!(
            "page {} of {}: {} smooth, {} red junctions: {}",
            p.page,
            p.pages,
            p.smooth_junctions,
            p.red_junctions,
            p.red_blocks().join(" ")
        );
        for w in &p.warnings {
            eprintln!("{w}");
        }
        if png {
            p.to_png().expect("png")
        } else {
            p.to_svg().into_bytes()
        }
    };
    std::fs::write(out, bytes).expect("writable output");
}

fn fail(errors: Vec<kernel::Diagnostic>) -> ! {
    for e in errors {
        eprintln!("{e}");
    }
    std::process::exit(1);
}
