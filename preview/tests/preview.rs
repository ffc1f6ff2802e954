//! The preview against the planner's own classification (issue #10 acceptance): number and
//! position of red and yellow dots, the red block list, the compensated path when G41/G42 is
//! used, paging, planes, PNG rendering, and the velocity plot against the interpolator.

use kernel::DiagCode;
use kernel::comp::compensate_all;
use kernel::interp::{InterpState, Interpolator};
use kernel::plan::{Planner, Segment};
use kernel::program::{Setup, compile};
use preview::{PreviewOptions, ViewPlane};

/// A contour under G41 with arcs, G23 continuity, sharp and soft corners, rapids and a plunge.
const CONTOUR: &str = "\
N10 G92 D1 R0=4.0
N20 G17 D1 M3 S2000
N30 G0 X-20 Y-20 Z5
N40 G1 Z-2 F300
N50 G41 G1 X0 Y0 F1500
N60 G23 G1 Y30
N70 G2 X10 Y40 I10 J0
N80 G1 X50
N90 G1 X60 Y30
N100 G1 Y10
N110 G2 X50 Y0 I-10 J0
N120 G1 X20
N130 G1 X10 Y3
N140 G1 X0 Y0
N150 G40 G1 X-20 Y-10
N160 G0 Z5
";

fn setup() -> Setup {
    let mut s = Setup::new(&['X', 'Y', 'Z']);
    // R384: accuracy 8 µm, speed-drop percentage 20 (d5..6), SPEC §7.2.
    s.constants.set(384, 200.008);
    s
}

fn opts() -> PreviewOptions {
    PreviewOptions::new(setup())
}

/// The reference: the whole program compiled, compensated and planned in one go (not the
/// preview's streaming code), segments in order.
fn planned(text: &str, o: &PreviewOptions) -> Vec<Segment> {
    let c = compile(text, &o.setup);
    assert!(!c.has_errors(), "{:?}", c.diagnostics);
    let (blocks, diags) = compensate_all(&c.blocks, &o.comp);
    assert!(diags.iter().all(|d| !d.is_error()), "{diags:?}");
    let mut p = Planner::new(o.planner.clone(), 1);
    let mut out = Vec::new();
    for b in &blocks {
        p.push(b).expect("plannable");
        while let Some(s) = p.poll() {
            out.push(s);
        }
    }
    p.finish();
    while let Some(s) = p.poll() {
        out.push(s);
    }
    out
}

/// Junction dots of the reference: (x, y, red) in the plane, program end excluded.
fn reference_dots(segs: &[Segment], h: usize, v: usize) -> Vec<(f64, f64, bool, Segment)> {
    segs.iter()
        .filter(|s| !s.last)
        .map(|s| {
            let e = s.path.end();
            (e[h], e[v], s.junction.is_red(), *s)
        })
        .collect()
}

#[derive(Debug)]
struct SvgDot {
    x: f64,
    y: f64,
    red: bool,
    count: u64,
    block: Option<String>,
}

fn num(n: roxmltree::Node, a: &str) -> f64 {
    n.attribute(a).expect(a).parse().expect("number")
}

fn svg_dots(svg: &str) -> Vec<SvgDot> {
    let doc = roxmltree::Document::parse(svg).expect("well-formed SVG");
    doc.descendants()
        .filter(|n| n.has_tag_name("circle") && n.attribute("data-count").is_some())
        .map(|n| SvgDot {
            x: num(n, "cx"),
            y: num(n, "cy"),
            red: n.attribute("class") == Some("red"),
            count: num(n, "data-count") as u64,
            block: n.attribute("data-block").map(str::to_owned),
        })
        .collect()
}

/// Points of the SVG path with the given class (world coordinates).
fn svg_path_points(svg: &str, class: &str) -> Option<Vec<[f64; 2]>> {
    let doc = roxmltree::Document::parse(svg).expect("well-formed SVG");
    let d = doc
        .descendants()
        .find(|n| n.has_tag_name("path") && n.attribute("class") == Some(class))?
        .attribute("d")?
        .to_owned();
    let nums: Vec<f64> = d
        .split(|c: char| c == 'M' || c == 'L' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().expect("coordinate"))
        .collect();
    Some(nums.chunks(2).map(|c| [c[0], c[1]]).collect())
}

fn check_dots_match(svg: &str, reference: &[(f64, f64, bool, Segment)]) {
    let dots = svg_dots(svg);
    let count = |red: bool| -> u64 { dots.iter().filter(|d| d.red == red).map(|d| d.count).sum() };
    let want_red = reference.iter().filter(|r| r.2).count() as u64;
    let want_smooth = reference.len() as u64 - want_red;
    assert_eq!(count(true), want_red, "red dots");
    assert_eq!(count(false), want_smooth, "yellow dots");
    // One circle per distinct position and colour (junctions that project onto the same
    // point, like a plunge seen from above, share a circle and its count).
    let mut distinct: Vec<(i64, i64, bool)> = reference
        .iter()
        .map(|r| ((r.0 * 1e3).round() as i64, (r.1 * 1e3).round() as i64, r.2))
        .collect();
    distinct.sort();
    distinct.dedup();
    assert_eq!(dots.len(), distinct.len());
    for (x, y, red, seg) in reference {
        let d = dots
            .iter()
            .find(|d| (d.x - x).abs() < 2e-3 && (d.y - y).abs() < 2e-3 && d.red == *red)
            .unwrap_or_else(|| {
                panic!(
                    "no {} dot at ({x}, {y}) for {seg:?}",
                    if *red { "red" } else { "yellow" }
                )
            });
        if *red && d.count == 1 {
            let want = match seg.n {
                Some(n) => format!("N{n}"),
                None => format!("line {}", seg.line),
            };
            assert_eq!(d.block.as_deref(), Some(want.as_str()));
        }
    }
}

#[test]
fn dots_follow_the_planners_classification() {
    let o = opts();
    let p = preview::render(CONTOUR, &o).expect("preview");
    let segs = planned(CONTOUR, &o);
    let reference = reference_dots(&segs, 0, 1);
    // The program has both kinds (otherwise the test would prove little).
    let reds = reference.iter().filter(|r| r.2).count();
    assert!(reds >= 3 && reference.len() - reds >= 3, "{reference:?}");
    // Some red dots are speed drops at smooth G23 junctions, not only stops.
    assert!(
        segs.iter()
            .any(|s| s.junction == kernel::plan::Junction::SpeedDrop)
    );
    check_dots_match(&p.to_svg(), &reference);
    assert_eq!(p.red_junctions as usize, reds);
    assert_eq!(p.smooth_junctions as usize, reference.len() - reds);
    let want: Vec<String> = reference
        .iter()
        .filter(|r| r.2)
        .map(|r| format!("N{}", r.3.n.unwrap()))
        .collect();
    assert_eq!(p.red_blocks(), want);
    // The list is in the picture too.
    let svg = p.to_svg();
    for label in &want {
        assert!(svg.contains(&format!(">{label}  ")), "{label} listed");
    }
}

#[test]
fn compensated_path_is_drawn_when_g41_is_used() {
    let o = opts();
    let p = preview::render(CONTOUR, &o).expect("preview");
    assert!(p.compensated);
    let svg = p.to_svg();
    let comp = svg_path_points(&svg, "compensated").expect("compensated path");
    // The top edge Y40 from X10 to X50 lies 4 mm outside (tool radius, G41 on a clockwise
    // contour): the compensated path runs along Y44 there.
    assert!(
        comp.iter()
            .any(|p| (p[1] - 44.0).abs() < 1e-3 && (10.0..=50.0).contains(&p[0])),
        "{comp:?}"
    );
    // The compensated path never touches the programmed edge Y40 between X10 and X50.
    assert!(
        !comp
            .iter()
            .any(|p| (p[1] - 40.0).abs() < 0.5 && (15.0..=45.0).contains(&p[0]))
    );
    let prog = svg_path_points(&svg, "programmed").expect("programmed path");
    assert!(prog.contains(&[10.0, 40.0]) && prog.contains(&[50.0, 40.0]));

    // The same contour without G41: no compensated path at all.
    let plain = CONTOUR.replace("G41 ", "").replace("G40 ", "");
    let q = preview::render(&plain, &o).expect("preview");
    assert!(!q.compensated);
    assert!(svg_path_points(&q.to_svg(), "compensated").is_none());
}

#[test]
fn pages_hold_r387_blocks_each() {
    let mut o = opts();
    o.setup.constants.set(387, 0.006); // 6 blocks per page (digit reading, SPEC §7.5)
    o.planner = o.planner.clone().with_constants(&o.setup.constants);
    let segs = planned(CONTOUR, &o);
    let all = reference_dots(&segs, 0, 1);
    let mut seen = 0;
    for page in 1..=3 {
        o.page = page;
        let p = preview::render(CONTOUR, &o).expect("page");
        assert_eq!(p.pages, 3);
        assert_eq!(p.blocks, (page - 1) * 6..(page * 6).min(16));
        let on_page: Vec<_> = all
            .iter()
            .filter(|r| p.blocks.contains(&r.3.seq))
            .cloned()
            .collect();
        check_dots_match(&p.to_svg(), &on_page);
        seen += on_page.len();
    }
    assert_eq!(seen, all.len(), "every junction is on exactly one page");
    o.page = 4;
    let e = preview::render(CONTOUR, &o).expect_err("no page 4");
    assert_eq!(
        e[0].code,
        kernel::DiagCode::PreviewNoSuchPage,
        "{}",
        e[0].message
    );
}

#[test]
fn other_planes_project_the_same_junctions() {
    let mut o = opts();
    o.plane = ViewPlane::Xz;
    let p = preview::render(CONTOUR, &o).expect("preview");
    let reference = reference_dots(&planned(CONTOUR, &o), 0, 2);
    check_dots_match(&p.to_svg(), &reference);
    assert!(p.to_svg().contains("data-plane=\"XZ\""));
    let lathe = PreviewOptions::new(Setup::new(&['X', 'Z']));
    let mut l = lathe.clone();
    l.plane = ViewPlane::Yz;
    let e = preview::render("G1 X1 F100", &l).expect_err("no Y on a lathe");
    assert_eq!(
        e[0].code,
        kernel::DiagCode::PreviewAxisMissing,
        "{}",
        e[0].message
    );
}

#[test]
fn programs_with_errors_give_their_errors() {
    let e = preview::render("N10 G1 X10 F100\nN20 Q5\n", &opts()).expect_err("error");
    assert_eq!(e[0].block, Some(20));
    // Compensation errors too (G41 without a tool).
    let e = preview::render("N10 G41 G1 X10 F100\nN20 Y10\n", &opts()).expect_err("no tool");
    assert!(!e.is_empty());
}

#[test]
fn png_shows_the_same_picture() {
    let o = opts();
    let p = preview::render(CONTOUR, &o).expect("preview");
    let png = p.to_png().expect("png");
    let img = tiny_skia::Pixmap::decode_png(&png).expect("valid PNG");
    assert_eq!((img.width(), img.height()), (o.width_px, o.height_px));
    // Find the plot's world-to-pixel map in the SVG and look at a red dot's centre pixel.
    let svg = p.to_svg();
    let doc = roxmltree::Document::parse(&svg).unwrap();
    let g = doc
        .descendants()
        .find(|n| n.attribute("id") == Some("path"))
        .unwrap();
    let m: Vec<f64> = g
        .attribute("transform")
        .unwrap()
        .trim_start_matches("matrix(")
        .trim_end_matches(')')
        .split(' ')
        .map(|s| s.parse().unwrap())
        .collect();
    let pixel = |x: f64, y: f64| {
        let (px, py) = (
            (m[0] * x + m[4]).round() as u32,
            (m[3] * y + m[5]).round() as u32,
        );
        let c = img.pixel(px, py).unwrap();
        (c.red(), c.green(), c.blue())
    };
    // The bluest pixel within one pixel of a point (a thin line is anti-aliased).
    let bluest = |x: f64, y: f64| {
        let (px, py) = (
            (m[0] * x + m[4]).round() as u32,
            (m[3] * y + m[5]).round() as u32,
        );
        (px - 1..=px + 1)
            .flat_map(|i| (py - 1..=py + 1).map(move |j| (i, j)))
            .map(|(i, j)| img.pixel(i, j).unwrap())
            .map(|c| (c.red(), c.green(), c.blue()))
            .min_by_key(|c| c.0)
            .unwrap()
    };
    let dots = svg_dots(&svg);
    let red = dots.iter().find(|d| d.red).unwrap();
    let (r, g_, b) = pixel(red.x, red.y);
    assert!(
        r > 180 && g_ < 60 && b < 60,
        "red dot pixel {:?}",
        (r, g_, b)
    );
    let yellow = dots.iter().find(|d| !d.red).unwrap();
    let (r, g_, b) = pixel(yellow.x, yellow.y);
    assert!(
        r > 200 && g_ > 160 && b < 80,
        "yellow dot pixel {:?}",
        (r, g_, b)
    );
    // The compensated path is blue: the middle of the top edge, Y44 X30.
    let (r, g_, b) = bluest(30.0, 44.0);
    assert!(
        b > 150 && r < 120,
        "compensated path pixel {:?}",
        (r, g_, b)
    );
}

#[test]
fn long_programs_stay_within_the_pictures_resolution() {
    // 200,000 short blocks of a zig-zag: the SVG stays small (decimated), counts stay exact.
    let mut text = String::from("G23 G1 X0 Y0 F3000\n");
    for i in 1..=200_000u32 {
        let x = f64::from(i) * 0.01;
        let y = if i % 2 == 0 { 0.0 } else { 5.0 };
        text.push_str(&format!("X{x:.2} Y{y}\n"));
    }
    let o = opts();
    let p = preview::render(&text, &o).expect("preview");
    assert_eq!(p.total_blocks, 200_001);
    // The first block has no length (it goes where the tool is): 200,000 segments, 199,999
    // junctions between them.
    assert_eq!(p.smooth_junctions + p.red_junctions, 199_999);
    let svg = p.to_svg();
    assert!(svg.len() < 4_000_000, "SVG of {} bytes", svg.len());
    let dots = svg_dots(&svg);
    assert!(dots.len() < 20_000, "{} dots", dots.len());
    assert_eq!(
        dots.iter().map(|d| d.count).sum::<u64>(),
        p.smooth_junctions + p.red_junctions
    );
    let prog = svg_path_points(&svg, "programmed").unwrap();
    assert!(prog.len() < 100_000, "{} points", prog.len());
    assert_eq!(prog[0], [0.0, 0.0]);
}

/// Reference run of the interpolator over the planned segments: (block changes, top speed
/// mm/min, ticks).
fn reference_run(segs: &[Segment]) -> (u64, f64, u64) {
    let mut it = Interpolator::new(3, kernel::AxesMm::ZERO);
    let mut k = 0;
    let (mut changes, mut top, mut ticks) = (0u64, 0.0f64, 0u64);
    let mut last = None;
    loop {
        while k < segs.len() && it.has_room() {
            it.push(segs[k]).unwrap();
            k += 1;
        }
        if k == segs.len() && it.state() == InterpState::Idle {
            break;
        }
        let out = it.tick();
        ticks += 1;
        if last.is_some_and(|q| q != out.seq) {
            changes += 1;
        }
        last = Some(out.seq);
        top = top.max(out.path_v_mm_s * 60.0);
    }
    (changes, top, ticks)
}

#[test]
fn velocity_plot_follows_the_interpolator() {
    let o = opts();
    let v = preview::velocity_plot(CONTOUR, &o, true).expect("plot");
    let (changes, top, ticks) = reference_run(&planned(CONTOUR, &o));
    assert_eq!(v.boundaries, changes);
    assert!(
        (v.max_speed_mm_min - top).abs() < 1e-6,
        "{} vs {top}",
        v.max_speed_mm_min
    );
    assert!((v.end_s - ticks as f64 * kernel::TS_S).abs() <= 2.0 * kernel::TS_S);
    let svg = v.to_svg();
    // The velocity plot is written in pixels with its world-to-pixel map in `data-map`.
    let doc = roxmltree::Document::parse(&svg).unwrap();
    let map: Vec<f64> = doc
        .descendants()
        .find(|n| n.attribute("id") == Some("speed"))
        .and_then(|n| n.attribute("data-map"))
        .expect("data-map")
        .split(' ')
        .map(|s| s.parse().unwrap())
        .collect();
    let speed: Vec<[f64; 2]> = svg_path_points(&svg, "speed")
        .expect("speed trace")
        .iter()
        .map(|p| [(p[0] - map[2]) / map[0], (p[1] - map[3]) / map[1]])
        .collect();
    // (coordinates are written to 1/100 px)
    let tol = 0.01 / map[1].abs();
    assert!(speed.iter().all(|p| p[1] <= top + tol), "{tol}");
    assert!(speed.iter().any(|p| p[1] >= top - tol));
    assert!(
        speed
            .iter()
            .all(|p| p[0] >= -1e-9 && p[0] <= v.end_s + 0.01)
    );
    let grey =
        svg.matches("class=\"boundary\"").count() + svg.matches("class=\"boundary-red\"").count();
    assert!(grey >= 1);
    let lines = svg_path_points(&svg, "boundary").map_or(0, |p| p.len() / 2)
        + svg_path_points(&svg, "boundary-red").map_or(0, |p| p.len() / 2);
    assert_eq!(
        lines as u64, changes,
        "one vertical line per block boundary"
    );
    assert!(svg.contains("class=\"accel\""));
    assert!(v.to_png().expect("png").starts_with(b"\x89PNG"));
}

/// A program stop (M0, a CNC836 tool change) does not hold the plot's run: it ends, and the
/// plot spans the motion after the stop too.
#[test]
fn velocity_plot_runs_through_program_stops() {
    let o = opts();
    let text = "N10 G1 X20 F3000\nN20 M0\nN30 G1 Y20\nN40 T2 M6\nN50 G1 X0\n";
    let v = preview::velocity_plot(text, &o, false).expect("plot");
    // Three moves of 20 mm at 50 mm/s, each at least 0.4 s.
    assert!(v.end_s >= 1.2, "{}", v.end_s);
}

/// The plot stops at `plot_max_ticks` with a `preview_plot_cut` note on the block then
/// running, and counts the pages after it (the rest is parsed); a plot within the bound has
/// no note. `G0 Y8888888` would otherwise interpolate for hours of machining.
#[test]
fn velocity_plot_stops_at_its_bound() {
    let mut o = opts();
    o.plot_max_ticks = 2500;
    let text = "N10 G0 Y8888888\nN20 G1 X1 F100\n";
    let v = preview::velocity_plot(text, &o, false).expect("plot");
    assert!((v.end_s - 10.0).abs() < 0.01, "{}", v.end_s);
    let cut: Vec<_> = v
        .warnings
        .iter()
        .filter(|d| d.code == DiagCode::PreviewPlotCut)
        .collect();
    assert_eq!(cut.len(), 1, "{:?}", v.warnings);
    assert_eq!((cut[0].block, cut[0].line), (Some(10), 1));
    assert_eq!(v.pages, 1);
    let short = preview::velocity_plot("N10 G1 X10 F600\n", &o, false).expect("plot");
    assert!(
        short
            .warnings
            .iter()
            .all(|d| d.code != DiagCode::PreviewPlotCut)
    );
}

#[test]
fn velocity_pages_split_the_run() {
    let mut o = opts();
    let whole = preview::velocity_plot(CONTOUR, &o, false).expect("plot");
    o.page_blocks = Some(8);
    let mut boundaries = 0;
    let mut last_end = 0.0;
    for page in 1..=2 {
        o.page = page;
        let v = preview::velocity_plot(CONTOUR, &o, false).expect("page");
        assert_eq!(v.pages, 2);
        assert!(v.start_s >= last_end, "pages follow each other in time");
        last_end = v.end_s;
        boundaries += v.boundaries;
    }
    assert_eq!(boundaries, whole.boundaries);
    assert!((last_end - whole.end_s).abs() < 1e-9);
}

#[test]
fn degenerate_programs_still_render() {
    for text in [
        "",
        "N10 M3 S1000\n",
        "N10 G0 Z5\nN20 G1 Z-1 F100\n",
        "G0 X10 Y10\n",
    ] {
        let p = preview::render(text, &opts()).expect("preview");
        assert!(p.to_svg().ends_with("</svg>\n"));
        assert!(p.to_png().is_ok());
        let v = preview::velocity_plot(text, &opts(), true).expect("plot");
        assert!(v.to_png().is_ok());
    }
}
