//! PNG of a [`Scene`] with tiny-skia (anti-aliased lines and dots) and an 8×8 bitmap font for
//! text (no font files, no text shaping: the labels are ASCII and Latin-1).

use font8x8::UnicodeFonts;
use tiny_skia::{
    FillRule, Mask, Paint, PathBuilder, Pixmap, PremultipliedColorU8, Rect, StrokeDash, Transform,
};

use crate::scene::{Anchor, Item, Plot, Rgb, Scene, Stroke, WorldItem};

/// Why a PNG could not be made.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RenderError(pub String);

impl std::fmt::Display for RenderError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "cannot render the PNG: {}", self.0)
    }
}

impl std::error::Error for RenderError {}

fn paint(c: Rgb) -> Paint<'static> {
    let mut p = Paint::default();
    p.set_color_rgba8(c.0, c.1, c.2, 255);
    p.anti_alias = true;
    p
}

fn ts_stroke(s: &Stroke) -> tiny_skia::Stroke {
    tiny_skia::Stroke {
        width: s.width_px,
        line_join: tiny_skia::LineJoin::Round,
        dash: s
            .dash_px
            .and_then(|[d, g]| StrokeDash::new(vec![d, g], 0.0)),
        ..tiny_skia::Stroke::default()
    }
}

pub fn to_png(scene: &Scene) -> Result<Vec<u8>, RenderError> {
    let mut pm = Pixmap::new(scene.width_px.max(1), scene.height_px.max(1))
        .ok_or_else(|| RenderError(format!("bad size {}x{}", scene.width_px, scene.height_px)))?;
    pm.fill(tiny_skia::Color::WHITE);
    for item in &scene.items {
        draw(&mut pm, item);
    }
    pm.encode_png().map_err(|e| RenderError(e.to_string()))
}

fn line(pm: &mut Pixmap, pts: &[[f64; 2]], s: &Stroke, mask: Option<&Mask>) {
    if pts.len() < 2 {
        return;
    }
    let mut pb = PathBuilder::new();
    pb.move_to(pts[0][0] as f32, pts[0][1] as f32);
    for p in &pts[1..] {
        pb.line_to(p[0] as f32, p[1] as f32);
    }
    if let Some(path) = pb.finish() {
        pm.stroke_path(
            &path,
            &paint(s.color),
            &ts_stroke(s),
            Transform::identity(),
            mask,
        );
    }
}

fn circle(pm: &mut Pixmap, at: [f64; 2], r: f32, fill: Rgb, outline: Rgb, mask: Option<&Mask>) {
    if let Some(path) = PathBuilder::from_circle(at[0] as f32, at[1] as f32, r) {
        pm.fill_path(
            &path,
            &paint(fill),
            FillRule::Winding,
            Transform::identity(),
            mask,
        );
        let st = tiny_skia::Stroke {
            width: 1.0,
            ..tiny_skia::Stroke::default()
        };
        pm.stroke_path(&path, &paint(outline), &st, Transform::identity(), mask);
    }
}

fn draw(pm: &mut Pixmap, item: &Item) {
    match item {
        Item::Line { from, to, stroke } => line(pm, &[*from, *to], stroke, None),
        Item::Rect {
            at,
            size,
            fill,
            stroke,
        } => {
            let Some(r) =
                Rect::from_xywh(at[0] as f32, at[1] as f32, size[0] as f32, size[1] as f32)
            else {
                return;
            };
            if let Some(f) = fill {
                pm.fill_rect(r, &paint(*f), Transform::identity(), None);
            }
            if let Some(s) = stroke {
                let path = PathBuilder::from_rect(r);
                pm.stroke_path(
                    &path,
                    &paint(s.color),
                    &ts_stroke(s),
                    Transform::identity(),
                    None,
                );
            }
        }
        Item::Circle {
            at,
            r_px,
            fill,
            outline,
        } => circle(pm, *at, *r_px, *fill, *outline, None),
        Item::Text {
            at,
            size_px,
            anchor,
            color,
            text,
            ..
        } => draw_text(pm, *at, *size_px, *anchor, *color, text),
        Item::Plot(p) => draw_plot(pm, p),
    }
}

fn draw_plot(pm: &mut Pixmap, p: &Plot) {
    let [x, y, w, h] = p.rect_px;
    let mut mask = Mask::new(pm.width(), pm.height());
    if let (Some(m), Some(r)) = (
        mask.as_mut(),
        Rect::from_xywh(x as f32, y as f32, w as f32, h as f32),
    ) {
        m.fill_path(
            &PathBuilder::from_rect(r),
            FillRule::Winding,
            false,
            Transform::identity(),
        );
    }
    let mask = mask.as_ref();
    let mut px = Vec::new();
    for item in &p.items {
        match item {
            WorldItem::Path { stroke, runs, .. } => {
                for run in runs {
                    px.clear();
                    px.extend(run.iter().map(|q| p.map.apply(*q)));
                    line(pm, &px, stroke, mask);
                }
            }
            WorldItem::Dots { dots, .. } => {
                for d in dots {
                    circle(pm, p.map.apply(d.at), d.r_px, d.fill, d.outline, mask);
                }
            }
        }
    }
}

/// Glyph of `ch` (8 rows, bit 0 = leftmost pixel); `?` when the font lacks it.
fn glyph(ch: char) -> [u8; 8] {
    font8x8::BASIC_FONTS
        .get(ch)
        .or_else(|| font8x8::LATIN_FONTS.get(ch))
        .or_else(|| font8x8::BASIC_FONTS.get('?'))
        .unwrap_or([0; 8])
}

/// Bitmap text: the 8×8 font scaled by a whole factor, baseline at `at[1]`. Text of 12 px and
/// below is drawn at 1×, larger text at 2×.
fn draw_text(pm: &mut Pixmap, at: [f64; 2], size_px: f32, anchor: Anchor, c: Rgb, text: &str) {
    let k: i64 = if size_px > 13.0 { 2 } else { 1 };
    // The font has no superscript two.
    let text = &text.replace('²', "^2");
    let advance = 8 * k;
    let n = text.chars().count() as i64;
    let width = n * advance;
    let x0 = at[0].round() as i64
        - match anchor {
            Anchor::Start => 0,
            Anchor::Middle => width / 2,
            Anchor::End => width,
        };
    // The font's glyphs sit in rows 0..7 with the baseline at row 7.
    let y0 = at[1].round() as i64 - 7 * k;
    let (w, h) = (i64::from(pm.width()), i64::from(pm.height()));
    let color = PremultipliedColorU8::from_rgba(c.0, c.1, c.2, 255).expect("opaque colour");
    let pixels = pm.pixels_mut();
    for (i, ch) in text.chars().enumerate() {
        let g = glyph(ch);
        let gx = x0 + i as i64 * advance;
        for (row, bits) in g.iter().enumerate() {
            for col in 0..8 {
                if bits & (1 << col) == 0 {
                    continue;
                }
                for dy in 0..k {
                    for dx in 0..k {
                        let px = gx + col * k + dx;
                        let py = y0 + row as i64 * k + dy;
                        if (0..w).contains(&px) && (0..h).contains(&py) {
                            pixels[(py * w + px) as usize] = color;
                        }
                    }
                }
            }
        }
    }
}
