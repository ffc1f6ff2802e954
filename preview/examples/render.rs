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
    let view = view_options(&args[2..], &mut setup);
    let mut opts = PreviewOptions::new(setup);
    opts.plane = view.plane;
    opts.page = view.page;
    opts.page_blocks = view.page_blocks;
    let out = &args[1];
    let png = out.ends_with(".png");
    let bytes = if view.velocity {
        velocity_picture(&text, &mut opts, view.accel, png)
    } else {
        preview_picture(&text, &opts, png)
    };
    std::fs::write(out, bytes).expect("writable output");
}

/// What the picture shows (the options that are not the machine's).
struct View {
    plane: ViewPlane,
    page: u32,
    page_blocks: Option<u32>,
    velocity: bool,
    accel: bool,
}

/// Reads the options: the view's into the result, the machine's into `setup`.
fn view_options(args: &[String], setup: &mut kernel::program::Setup) -> View {
    let mut view = View {
        plane: ViewPlane::Xy,
        page: 1,
        page_blocks: None,
        velocity: false,
        accel: false,
    };
    let mut i = 0;
    while i < args.len() {
        let value = || args.get(i + 1).expect("a value after the option").as_str();
        match args[i].as_str() {
            "--plane" => view.plane = ViewPlane::parse(value()).expect("xy, xz or yz"),
            "--page" => view.page = value().parse().expect("page number"),
            "--page-blocks" => view.page_blocks = Some(value().parse().expect("blocks per page")),
            "--velocity" => view.velocity = true,
            "--accel" => view.accel = true,
            other => machine_option(other, value(), setup),
        }
        i += if matches!(args[i].as_str(), "--velocity" | "--accel") {
            1
        } else {
            2
        };
    }
    view
}

/// One option of the machine (`--const`, `--axes`, `--diameter`, `--offset`, `--gear`).
fn machine_option(name: &str, value: &str, setup: &mut kernel::program::Setup) {
    match name {
        "--const" => {
            let (r, v) = value
                .trim_start_matches('R')
                .split_once('=')
                .expect("R=VALUE");
            setup.constants.set(
                r.parse().expect("constant number"),
                v.parse().expect("value"),
            );
        }
        "--axes" => setup.axis_names = value.to_ascii_uppercase().chars().collect(),
        "--diameter" => {
            let letter = value.to_ascii_uppercase().chars().next();
            setup.diameter_axis = setup.axis_names.iter().position(|&a| Some(a) == letter);
            assert!(setup.diameter_axis.is_some(), "--diameter: not an axis");
        }
        "--offset" => {
            let v: Vec<f64> = value
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
            let (m, p) = value.split_once(':').expect("M:P");
            setup.gears.push(kernel::kr::Gear {
                max_rpm: p.parse().expect("rpm"),
                output_range: 0x7FFF,
                m_code: Some(m.parse().expect("M code")),
            });
        }
        other => panic!("unknown option {other}"),
    }
}

fn velocity_picture(text: &str, opts: &mut PreviewOptions, accel: bool, png: bool) -> Vec<u8> {
    opts.height_px = if accel { 700 } else { 500 };
    let v = preview::velocity_plot(text, opts, accel).unwrap_or_else(|e| fail(e));
    eprintln!(
        "{:.2} s .. {:.2} s, {} block boundaries, top speed {:.0} mm/min",
        v.start_s, v.end_s, v.boundaries, v.max_speed_mm_min
    );
    if png {
        v.to_png().expect("png")
    } else {
        v.to_svg().into_bytes()
    }
}

fn preview_picture(text: &str, opts: &PreviewOptions, png: bool) -> Vec<u8> {
    let p = preview::render(text, opts).unwrap_or_else(|e| fail(e));
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
}

fn fail(errors: Vec<kernel::Diagnostic>) -> ! {
    for e in errors {
        eprintln!("{e}");
    }
    std::process::exit(1);
}
