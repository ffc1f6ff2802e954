//! A picture as a list of drawing items, shared by the SVG writer ([`crate::svg`]) and the PNG
//! rasteriser ([`crate::raster`]) so both formats show exactly the same thing.
//!
//! Page items are in pixels (origin top left). A [`Plot`] holds items in world units (mm, or
//! seconds and mm/min for the velocity plot) with the affine map to pixels, so the SVG keeps
//! real coordinates (a machinist or a test can read them back) and the PNG maps them itself.

/// sRGB colour.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rgb(pub u8, pub u8, pub u8);

impl Rgb {
    pub const BLACK: Rgb = Rgb(0, 0, 0);
    pub const WHITE: Rgb = Rgb(255, 255, 255);
}

/// How a line is drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stroke {
    pub color: Rgb,
    /// Width on the picture, px (never scaled with the world).
    pub width_px: f32,
    /// Dash and gap length, px.
    pub dash_px: Option<[f32; 2]>,
}

impl Stroke {
    pub fn solid(color: Rgb, width_px: f32) -> Self {
        Stroke {
            color,
            width_px,
            dash_px: None,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Anchor {
    Start,
    Middle,
    End,
}

/// Affine map from world to pixels: `x_px = sx·x + tx`, `y_px = sy·y + ty`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Map {
    pub sx: f64,
    pub sy: f64,
    pub tx: f64,
    pub ty: f64,
}

impl Map {
    pub fn apply(&self, p: [f64; 2]) -> [f64; 2] {
        [self.sx * p[0] + self.tx, self.sy * p[1] + self.ty]
    }
}

/// A filled circle at a world point, with the data a reader of the SVG needs.
#[derive(Clone, Debug, PartialEq)]
pub struct Dot {
    pub at: [f64; 2],
    pub r_px: f32,
    pub fill: Rgb,
    pub outline: Rgb,
    /// SVG class (e.g. `smooth`, `red`).
    pub class: &'static str,
    /// How many junctions this dot stands for (dots closer than the picture resolves merge).
    pub count: u64,
    /// Block label (`N40`, or `line 12`), for red dots.
    pub label: Option<String>,
}

/// Items in world units, clipped to the plot rectangle.
#[derive(Clone, Debug, PartialEq)]
pub enum WorldItem {
    /// Open polylines, all with the same stroke.
    Path {
        class: &'static str,
        stroke: Stroke,
        runs: Vec<Vec<[f64; 2]>>,
    },
    Dots {
        class: &'static str,
        dots: Vec<Dot>,
    },
}

/// A plot area: a pixel rectangle and world items mapped into it.
#[derive(Clone, Debug, PartialEq)]
pub struct Plot {
    pub id: &'static str,
    /// x, y, width, height in px.
    pub rect_px: [f64; 4],
    pub map: Map,
    /// Extra SVG attributes on the plot group (e.g. `data-plane="XY"`), already escaped.
    pub attrs: Vec<(&'static str, String)>,
    pub items: Vec<WorldItem>,
}

/// A drawing item in pixels.
#[derive(Clone, Debug, PartialEq)]
pub enum Item {
    Line {
        from: [f64; 2],
        to: [f64; 2],
        stroke: Stroke,
    },
    Rect {
        at: [f64; 2],
        size: [f64; 2],
        fill: Option<Rgb>,
        stroke: Option<Stroke>,
    },
    Circle {
        at: [f64; 2],
        r_px: f32,
        fill: Rgb,
        outline: Rgb,
    },
    Text {
        at: [f64; 2],
        size_px: f32,
        anchor: Anchor,
        color: Rgb,
        /// SVG class (tests and style sheets find texts by it).
        class: &'static str,
        text: String,
    },
    Plot(Plot),
}

/// A whole picture.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    pub width_px: u32,
    pub height_px: u32,
    pub items: Vec<Item>,
}

impl Scene {
    pub fn new(width_px: u32, height_px: u32) -> Self {
        Scene {
            width_px,
            height_px,
            items: Vec::new(),
        }
    }

    /// A white page with its title at the top left: how every picture starts.
    pub fn page(width_px: u32, height_px: u32, title: &str) -> Self {
        let mut scene = Scene::new(width_px, height_px);
        scene.items.push(Item::Rect {
            at: [0.0, 0.0],
            size: [f64::from(width_px), f64::from(height_px)],
            fill: Some(Rgb::WHITE),
            stroke: None,
        });
        scene.text([16.0, 24.0], 16.0, Anchor::Start, "title", title);
        scene
    }

    pub fn text(
        &mut self,
        at: [f64; 2],
        size_px: f32,
        anchor: Anchor,
        class: &'static str,
        text: impl Into<String>,
    ) {
        self.items.push(Item::Text {
            at,
            size_px,
            anchor,
            color: Rgb::BLACK,
            class,
            text: text.into(),
        });
    }

    pub fn line(&mut self, from: [f64; 2], to: [f64; 2], stroke: Stroke) {
        self.items.push(Item::Line { from, to, stroke });
    }
}
