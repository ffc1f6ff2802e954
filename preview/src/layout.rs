//! Layout of the program preview (SPEC §7.5): the plot with its scales, the legend and the list
//! of red junctions.

use crate::collect::{Bounds, Collector};
use crate::scale;
use crate::scene::{Anchor, Dot, Item, Map, Plot, Rgb, Scene, Stroke, WorldItem};
use crate::{RedJunction, RedKind};

pub const PROGRAMMED: Rgb = Rgb(40, 40, 40);
pub const RAPID: Rgb = Rgb(150, 150, 150);
pub const COMPENSATED: Rgb = Rgb(0, 90, 230);
pub const SMOOTH_DOT: Rgb = Rgb(255, 205, 0);
pub const RED_DOT: Rgb = Rgb(225, 0, 0);
pub const GRID: Rgb = Rgb(225, 225, 225);
pub const FRAME: Rgb = Rgb(120, 120, 120);

/// Width of the right panel (legend, red list), px.
const PANEL_PX: f64 = 290.0;
/// Dot radius, px; dots closer than about their size merge into one.
const DOT_R_PX: f32 = 3.5;
/// More yellow dots than this are drawn small.
const DENSE_DOTS: usize = 1500;

/// Text lines above the plot.
pub struct Header {
    pub title: String,
    pub subtitle: String,
}

/// Plot rectangle of a picture with the right panel: x, y, w, h (px).
fn plot_rect(w: f64, h: f64, panel: bool) -> [f64; 4] {
    let (left, top, bottom) = (75.0, 76.0, 48.0);
    let right = if panel { PANEL_PX + 20.0 } else { 30.0 };
    [
        left,
        top,
        (w - left - right).max(50.0),
        (h - top - bottom).max(50.0),
    ]
}

/// Equal-scale map of `b` (padded) centred in `rect`.
fn fit(b: &Bounds, rect: [f64; 4]) -> (Map, Bounds) {
    let mut b = if b.is_empty() {
        Bounds {
            min: [0.0, 0.0],
            max: [1.0, 1.0],
        }
    } else {
        *b
    };
    for i in 0..2 {
        let span = (b.max[i] - b.min[i]).max(1e-3);
        let pad = 0.04 * span;
        b.min[i] -= pad;
        b.max[i] += pad;
    }
    let (bw, bh) = (b.max[0] - b.min[0], b.max[1] - b.min[1]);
    let s = (rect[2] / bw).min(rect[3] / bh);
    let tx = rect[0] + (rect[2] - s * bw) / 2.0 - s * b.min[0];
    let ty = rect[1] + rect[3] - (rect[3] - s * bh) / 2.0 + s * b.min[1];
    let map = Map {
        sx: s,
        sy: -s,
        tx,
        ty,
    };
    // The world range actually visible in the rectangle.
    let vis = Bounds {
        min: [(rect[0] - tx) / s, (ty - rect[1] - rect[3]) / s],
        max: [(rect[0] + rect[2] - tx) / s, (ty - rect[1]) / s],
    };
    (map, vis)
}

/// Grid, frame, tick labels and axis titles of a plot (world range `vis`).
pub fn axes(scene: &mut Scene, rect: [f64; 4], map: &Map, vis: &Bounds, titles: (&str, &str)) {
    let [x, y, w, h] = rect;
    let grid = Stroke::solid(GRID, 1.0);
    let xs = scale::nice_step(vis.max[0] - vis.min[0], (w / 90.0).max(2.0) as usize);
    for t in scale::ticks(vis.min[0], vis.max[0], xs) {
        let px = map.apply([t, 0.0])[0];
        scene.line([px, y], [px, y + h], grid);
        scene.line([px, y + h], [px, y + h + 5.0], Stroke::solid(FRAME, 1.0));
        scene.text(
            [px, y + h + 18.0],
            11.0,
            Anchor::Middle,
            "tick",
            scale::label(t, xs),
        );
    }
    let ys = scale::nice_step(vis.max[1] - vis.min[1], (h / 60.0).max(2.0) as usize);
    for t in scale::ticks(vis.min[1], vis.max[1], ys) {
        let py = map.apply([0.0, t])[1];
        scene.line([x, py], [x + w, py], grid);
        scene.line([x - 5.0, py], [x, py], Stroke::solid(FRAME, 1.0));
        scene.text(
            [x - 8.0, py + 4.0],
            11.0,
            Anchor::End,
            "tick",
            scale::label(t, ys),
        );
    }
    scene.items.push(Item::Rect {
        at: [x, y],
        size: [w, h],
        fill: None,
        stroke: Some(Stroke::solid(FRAME, 1.0)),
    });
    scene.text(
        [x + w, y + h + 36.0],
        12.0,
        Anchor::End,
        "axis-title",
        titles.0,
    );
    scene.text(
        [x - 8.0, y - 12.0],
        12.0,
        Anchor::Start,
        "axis-title",
        titles.1,
    );
}

fn legend_line(scene: &mut Scene, x: f64, y: f64, stroke: Stroke, text: &str) {
    scene.line([x, y - 4.0], [x + 28.0, y - 4.0], stroke);
    scene.text([x + 36.0, y], 12.0, Anchor::Start, "legend", text);
}

fn legend_dot(scene: &mut Scene, x: f64, y: f64, fill: Rgb, text: &str) {
    scene.items.push(Item::Circle {
        at: [x + 14.0, y - 4.0],
        r_px: DOT_R_PX + 0.5,
        fill,
        outline: Rgb(90, 90, 90),
    });
    scene.text([x + 36.0, y], 12.0, Anchor::Start, "legend", text);
}

/// What the preview picture shows besides the collected geometry.
pub struct PreviewText<'a> {
    pub header: Header,
    pub plane: (char, char),
    pub drop_percent: f64,
    pub red_list: &'a [RedJunction],
    pub red_total: u64,
}

/// Lays out the preview picture.
pub fn preview(c: &Collector, t: &PreviewText, width_px: u32, height_px: u32) -> Scene {
    let (w, h) = (f64::from(width_px), f64::from(height_px));
    let mut scene = Scene::page(width_px, height_px, &t.header.title);
    scene.text(
        [16.0, 44.0],
        12.0,
        Anchor::Start,
        "subtitle",
        &t.header.subtitle,
    );
    let rect = plot_rect(w, h, true);
    let (map, vis) = fit(&c.bounds, rect);
    axes(
        &mut scene,
        rect,
        &map,
        &vis,
        (&format!("{} mm", t.plane.0), &format!("{} mm", t.plane.1)),
    );
    // Final decimation to the picture: half a pixel for paths, about a dot for dots.
    let px_mm = 1.0 / map.sx;
    let mut items = vec![
        WorldItem::Path {
            class: "rapid",
            stroke: Stroke {
                color: RAPID,
                width_px: 1.0,
                dash_px: Some([5.0, 4.0]),
            },
            runs: c.rapid.runs_at(0.5 * px_mm),
        },
        WorldItem::Path {
            class: "programmed",
            stroke: Stroke::solid(PROGRAMMED, 1.4),
            runs: c.feed.runs_at(0.5 * px_mm),
        },
    ];
    if !c.comp.is_empty() {
        items.push(WorldItem::Path {
            class: "compensated",
            stroke: Stroke::solid(COMPENSATED, 1.6),
            runs: c.comp.runs_at(0.5 * px_mm),
        });
    }
    let merged = c.dots.at(f64::from(DOT_R_PX) * px_mm);
    // Where smooth junctions cover the picture (dense programs), small yellow dots keep the
    // path and the red dots visible.
    let dense = merged.iter().filter(|d| !d.red).count() > DENSE_DOTS;
    let dots = merged
        .into_iter()
        .map(|d| Dot {
            at: d.at,
            r_px: if dense && !d.red { 1.5 } else { DOT_R_PX },
            fill: if d.red { RED_DOT } else { SMOOTH_DOT },
            outline: if d.red {
                Rgb(120, 0, 0)
            } else {
                Rgb(140, 110, 0)
            },
            class: if d.red { "red" } else { "smooth" },
            count: d.count,
            label: d.label,
        })
        .collect();
    items.push(WorldItem::Dots {
        class: "junctions",
        dots,
    });
    scene.items.push(Item::Plot(Plot {
        id: "path",
        rect_px: rect,
        map,
        attrs: vec![("data-plane", format!("{}{}", t.plane.0, t.plane.1))],
        items,
    }));
    panel(&mut scene, t, w, h);
    scene
}

/// Legend and the list of red junctions (block numbers, SPEC §7.5).
fn panel(scene: &mut Scene, t: &PreviewText, w: f64, h: f64) {
    let x = w - PANEL_PX;
    let mut y = 80.0;
    scene.text([x, y], 13.0, Anchor::Start, "legend-title", "Legend");
    y += 22.0;
    legend_line(
        scene,
        x,
        y,
        Stroke::solid(PROGRAMMED, 1.4),
        "programmed path",
    );
    y += 20.0;
    let rapid = Stroke {
        color: RAPID,
        width_px: 1.0,
        dash_px: Some([5.0, 4.0]),
    };
    legend_line(scene, x, y, rapid, "rapid (G0)");
    y += 20.0;
    legend_line(
        scene,
        x,
        y,
        Stroke::solid(COMPENSATED, 1.6),
        "compensated path (G41/G42)",
    );
    y += 20.0;
    legend_dot(scene, x, y, SMOOTH_DOT, "smooth junction");
    y += 20.0;
    legend_dot(
        scene,
        x,
        y,
        RED_DOT,
        &format!("speed below {:.0} % of F, or stop", t.drop_percent),
    );
    y += 34.0;
    scene.text(
        [x, y],
        13.0,
        Anchor::Start,
        "red-title",
        format!("Red junctions: {}", t.red_total),
    );
    y += 20.0;
    let line_h = 15.0;
    let room = (((h - 20.0 - y) / line_h).floor().max(1.0)) as usize;
    let shown = t.red_list.len().min(room.saturating_sub(1).max(1));
    for r in &t.red_list[..shown] {
        let what = match r.kind {
            RedKind::Stop => "stop".to_owned(),
            RedKind::SpeedDrop => {
                format!("{:.0} of {:.0} mm/min", r.v_mm_s * 60.0, r.feed_mm_s * 60.0)
            }
        };
        scene.text(
            [x, y],
            12.0,
            Anchor::Start,
            "red-block",
            format!("{}  {what}", r.label()),
        );
        y += line_h;
    }
    let more = t.red_total - shown as u64;
    if more > 0 {
        scene.text(
            [x, y],
            12.0,
            Anchor::Start,
            "red-more",
            format!("... and {more} more"),
        );
    }
}
