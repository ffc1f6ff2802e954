//! Program preview and continuity diagnostics as pictures (SPEC §7.5, issue #10).
//!
//! Pure like the kernel: text and settings in, SVG text or PNG bytes out; no files, sockets or
//! clocks (the CLI and the API write and send them).
//!
//! # Use
//! ```
//! use preview::{PreviewOptions, ViewPlane};
//! let text = "N10 G0 X0 Y0\nN20 G23 G1 X10 F600\nN30 Y10\nN40 G2 X20 Y20 I10 J0\n";
//! let mut opts = PreviewOptions::default();
//! opts.plane = ViewPlane::Xy;
//! let p = preview::render(text, &opts).expect("no errors");
//! let svg: String = p.to_svg();
//! let png: Vec<u8> = p.to_png().expect("png");
//! assert!(svg.starts_with("<svg") && png.starts_with(b"\x89PNG"));
//! for r in &p.red {
//!     println!("{}: speed {:.0} of {:.0} mm/min", r.label(), r.v_mm_s * 60.0, r.feed_mm_s * 60.0);
//! }
//! let v = preview::velocity_plot(text, &opts, true).expect("no errors");
//! assert!(v.to_svg().contains("class=\"speed\""));
//! ```
//!
//! - [`render`]: the program preview of one page: programmed path (black, rapids dashed grey),
//!   compensated tool-centre path (blue, when G41/G42 is used), a dot at every junction the
//!   planner classified, yellow = smooth, red = speed below the R384 d5..6 percentage of the
//!   programmed feed or a stop (kernel `plan::Junction`), the list of red block numbers, scales
//!   and a legend. Plane XY, XZ or YZ; R387 blocks per page (SPEC §7.5).
//! - [`velocity_plot`]: path speed and programmed feed over time, from the planned segments run
//!   through the real 4 ms interpolator at 100 % override, with a vertical line at every block
//!   boundary (red after a red junction), optionally per-axis accelerations.
//!
//! Both stream the program through parse → compensate → plan (the daemon's stages, see
//! [`pipeline`]) and keep geometry decimated to the picture's resolution
//! ([`decimate`], [`series`]), so a program of millions of blocks previews in bounded memory.
//! A program with errors gives all its errors instead of a picture, like `cncctl run`.
//!
//! Modules: [`pipeline`] (the stages), [`paging`] (R387), [`plane`] (projection), [`collect`]
//! (what the preview gathers), [`decimate`], [`layout`] (preview picture), [`velocity`] and
//! [`series`] (speed plot), [`scale`] (axis ticks), [`scene`] (drawing items), [`svg`] and
//! [`raster`] (the two output formats).

pub mod collect;
pub mod decimate;
pub mod layout;
pub mod outline;
pub mod paging;
pub mod pipeline;
pub mod plane;
pub mod raster;
pub mod scale;
pub mod scene;
pub mod series;
pub mod svg;
pub mod velocity;

use std::ops::Range;

use kernel::comp::CompConfig;
use kernel::plan::PlannerConfig;
use kernel::program::Setup;
use kernel::{DiagCode, Diagnostic};

pub use paging::{Page, blocks_per_page};
pub use plane::ViewPlane;
pub use raster::RenderError;

/// Default path speed and acceleration limits of [`PreviewOptions::new`]: the daemon's example
/// configuration (12000 mm/min, 800 mm/s² per axis).
pub const DEFAULT_V_MAX_MM_S: f64 = 200.0;
pub const DEFAULT_A_MAX_MM_S2: f64 = 800.0;

/// Machining time the velocity plot covers at most, in 4 ms ticks: 8 h (a shift). Its work
/// grows with the motion's duration (every tick is interpolated from the program's start), so
/// a few bytes of text (`G0 Y8888888`) could otherwise keep a core busy for minutes.
pub const DEFAULT_PLOT_MAX_TICKS: u64 = 8 * 3600 * 250;

/// What to preview and with which machine settings.
#[derive(Clone, Debug)]
pub struct PreviewOptions {
    /// Axes, constants (R384, R387 ...), offset table, start position: as for running.
    pub setup: Setup,
    /// The planner the machine runs (per-axis limits and the SPEC §7 constants).
    pub planner: PlannerConfig,
    /// The radius compensation settings (SPEC §4).
    pub comp: CompConfig,
    pub plane: ViewPlane,
    /// 1-based page (R387 blocks each).
    pub page: u32,
    /// Blocks per page; `None` reads R387 from `setup.constants` (0 = all).
    pub page_blocks: Option<u32>,
    pub width_px: u32,
    pub height_px: u32,
    /// Most red junctions listed in [`Preview::red`] (all are counted).
    pub max_listed: usize,
    /// Ticks the velocity plot interpolates at most ([`DEFAULT_PLOT_MAX_TICKS`]); past them
    /// it stops with a `preview_plot_cut` note.
    pub plot_max_ticks: u64,
    /// The machine's whole setup when there is one ([`PreviewOptions::from_machine`]): the
    /// pass then reads it (not `setup`, `planner`, `comp`, which are its copies) and checks
    /// what only the machine knows (its gear ranges) as validation does.
    pub machine: Option<kernel::machine::MachineSetup>,
}

impl PreviewOptions {
    /// Options for `setup` with the default axis limits ([`DEFAULT_V_MAX_MM_S`],
    /// [`DEFAULT_A_MAX_MM_S2`]) and planner and compensation settings read from its constants.
    /// Callers with a machine configuration replace `planner` by the daemon's.
    pub fn new(setup: Setup) -> Self {
        let axes = setup.axis_names.len().clamp(1, kernel::MAX_AXES);
        let planner = PlannerConfig::uniform(axes, DEFAULT_V_MAX_MM_S, DEFAULT_A_MAX_MM_S2)
            .with_constants(&setup.constants);
        let comp = CompConfig::from_constants(&setup.constants);
        PreviewOptions {
            setup,
            planner,
            comp,
            plane: ViewPlane::Xy,
            page: 1,
            page_blocks: None,
            width_px: 1200,
            height_px: 800,
            max_listed: 10_000,
            plot_max_ticks: DEFAULT_PLOT_MAX_TICKS,
            machine: None,
        }
    }

    /// Options with the settings of a machine setup (the daemon's: what a job started now
    /// would run with).
    pub fn from_machine(m: &kernel::machine::MachineSetup) -> Self {
        PreviewOptions {
            planner: m.planner().clone(),
            comp: m.comp(),
            page_blocks: Some(m.preview_page_blocks()),
            machine: Some(m.clone()),
            ..Self::new(m.program().clone())
        }
    }

    fn page(&self) -> (Page, u32) {
        let per = self
            .page_blocks
            .unwrap_or_else(|| blocks_per_page(&self.setup.constants));
        (Page::new(self.page, per), per)
    }
}

impl Default for PreviewOptions {
    /// A 3-axis mill X, Y, Z with default constants.
    fn default() -> Self {
        Self::new(Setup::new(&['X', 'Y', 'Z']))
    }
}

/// Why a junction is red (SPEC §7.5).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RedKind {
    /// Not a smooth junction: the machine stops (G98/G24, rapid, angle, M function ...).
    Stop,
    /// Smooth, but the planned speed drops below the R384 d5..6 percentage of the feed.
    SpeedDrop,
}

/// A red junction: at the end of the block it names.
#[derive(Clone, Debug, PartialEq)]
pub struct RedJunction {
    /// Program index of the block that ends here (0-based).
    pub seq: u32,
    pub n: Option<u32>,
    pub line: u32,
    /// Position in the preview plane, mm (horizontal, vertical).
    pub at: [f64; 2],
    pub kind: RedKind,
    /// Planned speed at the junction, mm/s.
    pub v_mm_s: f64,
    /// Programmed feed of the block, mm/s.
    pub feed_mm_s: f64,
}

impl RedJunction {
    /// `N40`, or `line 12` for a block without a number.
    pub fn label(&self) -> String {
        collect::block_label(self.n, self.line)
    }
}

/// A rendered program preview (one page).
#[derive(Clone, Debug)]
pub struct Preview {
    scene: scene::Scene,
    /// This page (1-based) and how many there are.
    pub page: u32,
    pub pages: u32,
    /// Program blocks on this page (0-based program indices).
    pub blocks: Range<u32>,
    /// Programmed blocks in the whole program.
    pub total_blocks: u32,
    /// Junctions on this page by class.
    pub smooth_junctions: u64,
    pub red_junctions: u64,
    /// Red junctions in program order (at most `max_listed`).
    pub red: Vec<RedJunction>,
    /// A compensated path (G41/G42) is drawn.
    pub compensated: bool,
    /// Warnings and information about the program (compensation checks ...).
    pub warnings: Vec<Diagnostic>,
}

impl Preview {
    pub fn to_svg(&self) -> String {
        svg::to_svg(&self.scene)
    }

    pub fn to_png(&self) -> Result<Vec<u8>, RenderError> {
        raster::to_png(&self.scene)
    }

    /// Labels of the red junctions' blocks (`N40`, `line 12`), in program order.
    pub fn red_blocks(&self) -> Vec<String> {
        self.red.iter().map(RedJunction::label).collect()
    }
}

fn page_error(page: u32, pages: u32) -> Vec<Diagnostic> {
    vec![Diagnostic::error(
        DiagCode::PreviewNoSuchPage,
        None,
        0,
        0,
        format!("page {page} does not exist: the program has {pages} page(s)"),
    )]
}

/// Renders page `opts.page` of the program preview (SPEC §7.5).
pub fn render(text: &str, opts: &PreviewOptions) -> Result<Preview, Vec<Diagnostic>> {
    render_source(pipeline::Source::Text(text), opts)
}

/// [`render`] of a text or of a recorded pass (the daemon's selected program).
pub fn render_source(
    source: pipeline::Source<'_>,
    opts: &PreviewOptions,
) -> Result<Preview, Vec<Diagnostic>> {
    let proj = plane::Projection::new(opts.plane, &opts.setup.axis_names).map_err(|d| vec![d])?;
    let (page, per) = opts.page();
    let mut c = collect::Collector::new(proj, page, opts.max_listed);
    let outcome = pipeline::run_source(source, opts, &mut c)?;
    let pages = Page::count(outcome.blocks, per);
    if page.number > pages {
        return Err(page_error(page.number, pages));
    }
    let blocks = page.first..page.end.min(outcome.blocks);
    let drop_percent = opts.planner.envelope.sets[0].drop_percent;
    let (h, v) = opts.plane.letters();
    let title = format!(
        "Program preview  plane {}  page {} of {}  blocks {}..{} of {}",
        opts.plane.name(),
        page.number,
        pages,
        blocks.start + 1,
        blocks.end,
        outcome.blocks
    );
    let subtitle = format!(
        "junctions: {} smooth (yellow), {} red (speed below {:.0} % of F by R384 d5..6, or stop)",
        c.smooth, c.red, drop_percent
    );
    let text_ = layout::PreviewText {
        header: layout::Header { title, subtitle },
        plane: (h, v),
        drop_percent,
        red_list: &c.red_list,
        red_total: c.red,
    };
    let scene = layout::preview(&c, &text_, opts.width_px, opts.height_px);
    Ok(Preview {
        scene,
        page: page.number,
        pages,
        blocks,
        total_blocks: outcome.blocks,
        smooth_junctions: c.smooth,
        red_junctions: c.red,
        red: c.red_list,
        compensated: c.compensated,
        warnings: outcome.notes,
    })
}

/// The note of a velocity plot stopped at its bound in block `(n, line)`.
fn plot_cut((n, line): (Option<u32>, u32), max_ticks: u64) -> Diagnostic {
    let hours = max_ticks as f64 * kernel::TS_S / 3600.0;
    Diagnostic::info(
        DiagCode::PreviewPlotCut,
        n,
        line,
        0,
        format!(
            "the velocity plot stops after {hours:.1} h of machining (its bound); the program \
             goes on"
        ),
    )
}

/// A rendered velocity-over-time plot.
#[derive(Clone, Debug)]
pub struct VelocityPlot {
    scene: scene::Scene,
    pub page: u32,
    pub pages: u32,
    /// Time of the first and last tick of the page from program start, s.
    pub start_s: f64,
    pub end_s: f64,
    /// Highest path speed, mm/min.
    pub max_speed_mm_min: f64,
    /// Block boundaries crossed on the page (several in one tick count once).
    pub boundaries: u64,
    pub warnings: Vec<Diagnostic>,
}

impl VelocityPlot {
    pub fn to_svg(&self) -> String {
        svg::to_svg(&self.scene)
    }

    pub fn to_png(&self) -> Result<Vec<u8>, RenderError> {
        raster::to_png(&self.scene)
    }
}

/// Velocity over time of page `opts.page` of the planned run (SPEC §7.5), with per-axis
/// accelerations in a second panel when `with_accel`.
pub fn velocity_plot(
    text: &str,
    opts: &PreviewOptions,
    with_accel: bool,
) -> Result<VelocityPlot, Vec<Diagnostic>> {
    velocity_plot_source(pipeline::Source::Text(text), opts, with_accel)
}

/// [`velocity_plot`] of a text or of a recorded pass (the daemon's selected program).
pub fn velocity_plot_source(
    source: pipeline::Source<'_>,
    opts: &PreviewOptions,
    with_accel: bool,
) -> Result<VelocityPlot, Vec<Diagnostic>> {
    let (page, per) = opts.page();
    let axes = opts.planner.axes;
    let mut r = velocity::Recorder::new(axes, opts.setup.start, page, opts.plot_max_ticks);
    let mut outcome = pipeline::run_source(source, opts, &mut r)?;
    if let Some(cut) = r.cut {
        outcome.notes.push(plot_cut(cut, opts.plot_max_ticks));
    }
    let pages = Page::count(outcome.blocks, per);
    if page.number > pages {
        return Err(page_error(page.number, pages));
    }
    let s = &r.series;
    let start_s = s.first_tick.unwrap_or(0) as f64 * kernel::TS_S;
    let end_s = s.last_tick as f64 * kernel::TS_S;
    let title = format!(
        "Velocity over time  page {} of {}  {:.2} s .. {:.2} s",
        page.number, pages, start_s, end_s
    );
    let scene = velocity::layout(
        &r,
        &title,
        &opts.setup.axis_names,
        with_accel,
        opts.width_px,
        opts.height_px,
    );
    let buckets = s.buckets.iter().filter(|b| b.ticks > 0);
    let max_speed_mm_min = buckets.clone().fold(0.0f64, |m, b| m.max(b.v_max));
    let boundaries = buckets.map(|b| u64::from(b.boundaries)).sum();
    Ok(VelocityPlot {
        scene,
        page: page.number,
        pages,
        start_s,
        end_s,
        max_speed_mm_min,
        boundaries,
        warnings: outcome.notes,
    })
}
