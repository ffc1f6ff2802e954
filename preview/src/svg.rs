//! SVG text of a [`Scene`]. Plots keep world coordinates (mm, or s and mm/min) inside a group
//! whose `transform` maps them to pixels, with non-scaling strokes, so the numbers in the file
//! are the machine's.

use std::fmt::Write;

use crate::scene::{Anchor, Dot, Item, Map, Plot, Rgb, Scene, Stroke, WorldItem};

fn color(c: Rgb) -> String {
    format!("#{:02x}{:02x}{:02x}", c.0, c.1, c.2)
}

/// A number with at most `decimals` decimals, trailing zeros trimmed.
fn num(v: f64, decimals: usize) -> String {
    let mut s = format!("{v:.decimals$}");
    if s.contains('.') {
        while s.ends_with('0') {
            s.pop();
        }
        if s.ends_with('.') {
            s.pop();
        }
    }
    if s == "-0" { "0".to_owned() } else { s }
}

pub fn escape(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for ch in s.chars() {
        match ch {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            _ => o.push(ch),
        }
    }
    o
}

fn stroke_attrs(s: &Stroke) -> String {
    stroke_attrs_scaled(s, 1.0)
}

/// Stroke attributes for a group whose user unit is `px_per_unit` pixels (widths and dashes
/// are given in pixels; `vector-effect` is not used: several SVG renderers ignore it).
fn stroke_attrs_scaled(s: &Stroke, px_per_unit: f64) -> String {
    let k = 1.0 / px_per_unit;
    let d = decimals_for(px_per_unit) + 1;
    let mut a = format!(
        "fill=\"none\" stroke=\"{}\" stroke-width=\"{}\"",
        color(s.color),
        num(f64::from(s.width_px) * k, d)
    );
    if let Some([dash, gap]) = s.dash_px {
        let _ = write!(
            a,
            " stroke-dasharray=\"{} {}\"",
            num(f64::from(dash) * k, d),
            num(f64::from(gap) * k, d)
        );
    }
    a
}

/// Decimals that keep world coordinates to about a hundredth of a pixel.
fn decimals_for(scale: f64) -> usize {
    let d = (scale.abs() * 100.0).log10().ceil();
    d.clamp(0.0, 9.0) as usize
}

pub fn to_svg(scene: &Scene) -> String {
    let mut o = String::new();
    let (w, h) = (scene.width_px, scene.height_px);
    let _ = writeln!(
        o,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" font-family=\"DejaVu Sans, Arial, sans-serif\">"
    );
    for item in &scene.items {
        item_svg(&mut o, item);
    }
    o.push_str("</svg>\n");
    o
}

fn item_svg(o: &mut String, item: &Item) {
    match item {
        Item::Line { from, to, stroke } => {
            let _ = writeln!(
                o,
                "<line x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" {}/>",
                num(from[0], 2),
                num(from[1], 2),
                num(to[0], 2),
                num(to[1], 2),
                stroke_attrs(stroke)
            );
        }
        Item::Rect {
            at,
            size,
            fill,
            stroke,
        } => {
            let fill = fill.map_or("none".to_owned(), color);
            let st = stroke.as_ref().map(stroke_attrs).unwrap_or_default();
            let st = st.replace("fill=\"none\" ", "");
            let _ = writeln!(
                o,
                "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"{fill}\" {st}/>",
                num(at[0], 2),
                num(at[1], 2),
                num(size[0], 2),
                num(size[1], 2)
            );
        }
        Item::Circle {
            at,
            r_px,
            fill,
            outline,
        } => {
            let _ = writeln!(
                o,
                "<circle cx=\"{}\" cy=\"{}\" r=\"{}\" fill=\"{}\" stroke=\"{}\"/>",
                num(at[0], 2),
                num(at[1], 2),
                num(f64::from(*r_px), 2),
                color(*fill),
                color(*outline)
            );
        }
        Item::Text {
            at,
            size_px,
            anchor,
            color: c,
            class,
            text,
        } => {
            let anchor = match anchor {
                Anchor::Start => "start",
                Anchor::Middle => "middle",
                Anchor::End => "end",
            };
            let _ = writeln!(
                o,
                "<text class=\"{class}\" x=\"{}\" y=\"{}\" font-size=\"{}\" text-anchor=\"{anchor}\" fill=\"{}\">{}</text>",
                num(at[0], 2),
                num(at[1], 2),
                num(f64::from(*size_px), 1),
                color(*c),
                escape(text)
            );
        }
        Item::Plot(p) => plot_svg(o, p),
    }
}

fn plot_svg(o: &mut String, p: &Plot) {
    let [x, y, w, h] = p.rect_px;
    let Map { sx, sy, tx, ty } = p.map;
    let _ = writeln!(
        o,
        "<clipPath id=\"clip-{id}\"><rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\"/></clipPath>",
        num(x, 2),
        num(y, 2),
        num(w, 2),
        num(h, 2),
        id = p.id
    );
    let mut attrs = String::new();
    for (k, v) in &p.attrs {
        let _ = write!(attrs, " {k}=\"{v}\"");
    }
    // Equal scales (the path preview): machine coordinates under a transform, so the file
    // holds millimetres. Unequal scales (velocity plot): pixel coordinates, since a stroke in
    // an anisotropic user space would be distorted; `data-map` gives the world-to-pixel map.
    let uniform = (sx.abs() - sy.abs()).abs() <= 1e-9 * sx.abs();
    let frame = if uniform {
        format!(
            "transform=\"matrix({} 0 0 {} {} {})\"",
            num(sx, 9),
            num(sy, 9),
            num(tx, 4),
            num(ty, 4)
        )
    } else {
        format!(
            "data-map=\"{} {} {} {}\"",
            num(sx, 9),
            num(sy, 9),
            num(tx, 4),
            num(ty, 4)
        )
    };
    let _ = writeln!(
        o,
        "<g clip-path=\"url(#clip-{id})\"><g id=\"{id}\" {frame}{attrs}>",
        id = p.id
    );
    let style = Style {
        at: &|q: [f64; 2]| if uniform { q } else { p.map.apply(q) },
        px_per_unit: if uniform { sx.abs() } else { 1.0 },
        dx: if uniform { decimals_for(sx) } else { 2 },
        dy: if uniform { decimals_for(sy) } else { 2 },
    };
    for item in &p.items {
        match item {
            WorldItem::Path {
                class,
                stroke,
                runs,
            } => path_svg(o, &style, class, stroke, runs),
            WorldItem::Dots { class, dots } => dots_svg(o, &style, class, dots),
        }
    }
    o.push_str("</g></g>\n");
}

/// How a plot's world points are written: the map to the file's coordinates, pixels per
/// unit there, and decimals per coordinate.
struct Style<'a> {
    at: &'a dyn Fn([f64; 2]) -> [f64; 2],
    px_per_unit: f64,
    dx: usize,
    dy: usize,
}

fn path_svg(o: &mut String, st: &Style, class: &str, stroke: &Stroke, runs: &[Vec<[f64; 2]>]) {
    if runs.is_empty() {
        return;
    }
    let _ = write!(
        o,
        "<path class=\"{class}\" stroke-linejoin=\"round\" {} d=\"",
        stroke_attrs_scaled(stroke, st.px_per_unit)
    );
    for run in runs {
        for (k, q) in run.iter().enumerate() {
            let q = (st.at)(*q);
            let _ = write!(
                o,
                "{}{} {} ",
                if k == 0 { 'M' } else { 'L' },
                num(q[0], st.dx),
                num(q[1], st.dy)
            );
        }
    }
    o.pop();
    o.push_str("\"/>\n");
}

fn dots_svg(o: &mut String, st: &Style, class: &str, dots: &[Dot]) {
    let _ = writeln!(o, "<g class=\"{class}\">");
    let (dx, px_per_unit) = (st.dx, st.px_per_unit);
    for d in dots {
        // Radius and outline in user units so they are r_px and 1 px on the picture.
        let r = f64::from(d.r_px) / px_per_unit;
        let c = (st.at)(d.at);
        let label = d
            .label
            .as_ref()
            .map(|l| format!(" data-block=\"{}\"", escape(l)))
            .unwrap_or_default();
        let _ = writeln!(
            o,
            "<circle class=\"{}\" cx=\"{}\" cy=\"{}\" r=\"{}\" fill=\"{}\" stroke=\"{}\" stroke-width=\"{}\" data-count=\"{}\"{label}/>",
            d.class,
            num(c[0], dx),
            num(c[1], st.dy),
            num(r, dx + 1),
            color(d.fill),
            color(d.outline),
            num(1.0 / px_per_unit, dx + 1),
            d.count
        );
    }
    o.push_str("</g>\n");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_short_and_exact_enough() {
        assert_eq!(num(1.5000, 3), "1.5");
        assert_eq!(num(-0.0001, 2), "0");
        assert_eq!(num(20.0, 3), "20");
        assert_eq!(decimals_for(10.0), 3);
        assert_eq!(escape("a<b&\"c\""), "a&lt;b&amp;&quot;c&quot;");
    }
}
