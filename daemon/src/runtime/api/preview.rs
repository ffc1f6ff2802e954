//! Service `cnc.v1.Preview`: programmed path, compensated path and junction classification of
//! a program, read from the outputs of the one kernel pipeline a run uses
//! (`kernel::pipeline`, with the machine setup a job started now would take).

use std::sync::Arc;

use proto::v1 as pb;
use proto::v1::preview_server::Preview;
use tonic::{Request, Response, Status};

use kernel::Diagnostic;
use kernel::block::{ArcDir, Block, BlockKind, Path};
use kernel::comp::CompBlock;
use kernel::pipeline::{self, Flow, Options};
use kernel::plan::{Junction, Segment};
use kernel::program::Modal;

use super::auth::require;
use super::{ApiState, blocking, diagnostic_to_pb, invalid_with_diagnostics, plane_code};
use crate::runtime::config::Role::Observer;
use crate::runtime::controller::Controller;

/// Most junctions listed by the preview service (larger programs: paths only after these).
const PREVIEW_MAX_JUNCTIONS: usize = 1_000_000;

#[derive(Clone)]
pub struct PreviewSvc(pub Arc<ApiState>);

fn element(b: &Block, axes: usize) -> Option<pb::PathElement> {
    let BlockKind::Motion { start, end, path } = b.kind else {
        return None;
    };
    let (kind, center, plane) = match path {
        Path::Rapid => (pb::PathKind::Rapid, Vec::new(), String::new()),
        Path::Line | Path::Probe(_) => (pb::PathKind::Line, Vec::new(), String::new()),
        Path::Arc { dir, center, plane } => (
            match dir {
                ArcDir::Cw => pb::PathKind::ArcCw,
                ArcDir::Ccw => pb::PathKind::ArcCcw,
            },
            center.0[..axes].to_vec(),
            plane_code(plane).to_string(),
        ),
    };
    Some(pb::PathElement {
        seq: b.seq,
        block: b.n,
        line: b.line,
        kind: kind as i32,
        start_mm: start.0[..axes].to_vec(),
        end_mm: end.0[..axes].to_vec(),
        center_mm: center,
        plane,
    })
}

/// The API's name of a junction class.
pub fn junction_class(j: Junction) -> pb::JunctionClass {
    match j {
        Junction::Stop => pb::JunctionClass::Stop,
        Junction::Smooth => pb::JunctionClass::Smooth,
        Junction::SpeedDrop => pb::JunctionClass::SpeedDrop,
    }
}

/// Most bytes of stage outputs (programmed and compensated blocks, segments: 544 bytes each,
/// about 1.6 KiB a block) `LoadProgram` keeps of its pass for the previews of the selected
/// program, so programs up to about 2,500 blocks; a larger program's previews make their own
/// pass (with the same setup). The recording is held as long as the program is selected, and
/// while it grows within the pass: 100,000 outputs were 54 MB held and a 71 MB buffer at the
/// peak of every large load.
pub(super) const RECORD_MAX_BYTES: usize = 4 << 20;

/// What the preview data collects from the pipeline's pass (or from a recorded one).
struct Collect {
    axes: usize,
    junctions: bool,
    data: pb::PreviewData,
}

impl Collect {
    fn new(ctl: &Controller, junctions: bool) -> Self {
        Collect {
            axes: ctl.config().axes.len(),
            junctions,
            data: pb::PreviewData {
                axes: ctl
                    .config()
                    .axis_names()
                    .iter()
                    .map(|c| c.to_string())
                    .collect(),
                ..Default::default()
            },
        }
    }

    fn finish(mut self, diagnostics: &[Diagnostic]) -> pb::PreviewData {
        self.data.diagnostics = diagnostics.iter().map(diagnostic_to_pb).collect();
        self.data
    }
}

impl ::preview::pipeline::Sink for Collect {
    fn programmed(&mut self, b: &Block) {
        self.data.programmed.extend(element(b, self.axes));
    }
    fn compensated(&mut self, c: &CompBlock) {
        self.data.compensated.extend(element(&c.block, self.axes));
    }
    fn segment(&mut self, s: &Segment) {
        if self.junctions && self.data.junctions.len() < PREVIEW_MAX_JUNCTIONS {
            self.data.junctions.push(pb::Junction {
                seq: s.seq,
                block: s.n,
                line: s.line,
                class: junction_class(s.junction) as i32,
                position_mm: s.path.end().0[..self.axes].to_vec(),
                speed_mm_s: s.v_end_mm_s,
            });
        }
    }
}

impl pipeline::Observer for Collect {
    fn programmed(&mut self, b: &Block, _modal: &Modal) {
        ::preview::pipeline::Sink::programmed(self, b);
    }
    fn compensated(&mut self, c: &CompBlock) {
        ::preview::pipeline::Sink::compensated(self, c);
    }
    fn segment(&mut self, s: &Segment) -> Flow {
        ::preview::pipeline::Sink::segment(self, s);
        Flow::Go
    }
}

/// The pass `LoadProgram` (or `SelectProgram`) recorded of the selected program, if the
/// program is still validated as a job started now would be (same constants, offsets and
/// start position: that pass is the next start's).
pub fn recorded_pass(st: &ApiState) -> Option<Arc<::preview::pipeline::Recording>> {
    let program = st.ctl.program()?;
    if !st.ctl.validated_as_now(&program, &st.ctl.snapshot()) {
        return None;
    }
    let info = st.job.plan_info.lock().unwrap();
    let info = info.as_ref()?;
    if info.program != Arc::as_ptr(&program) as *const () as usize {
        return None;
    }
    info.pass.clone()
}

/// Whether a request for the selected program with `dialect` asks for the language it was
/// selected in (so the selection's recorded pass is the one asked for).
fn own_dialect(st: &ApiState, dialect: &str) -> Result<bool, Status> {
    let asked = super::dialect_field(dialect)?;
    Ok(match (asked, st.ctl.program()) {
        (Some(d), Some(p)) => d == p.dialect,
        _ => true,
    })
}

/// The preview data of the selected program from its load's pass (see [`recorded_pass`]).
pub fn recorded_preview(st: &ApiState, with_junctions: bool) -> Option<pb::PreviewData> {
    let pass = recorded_pass(st)?;
    let mut c = Collect::new(&st.ctl, with_junctions);
    let outcome = pass.replay(&mut c);
    Some(c.finish(&outcome.notes))
}

/// Preview data of `text` (or of the selected program when `text` is empty) in the dialect
/// `dialect` asks for (see `requested_program`): one pass of the pipeline, whose verdict and
/// diagnostics are those of validate and load.
pub fn preview_data(
    ctl: &Controller,
    text: &str,
    dialect: &str,
    with_junctions: bool,
) -> Result<pb::PreviewData, Status> {
    // The selected program streams from its file (a library program of any size).
    let (text, dialect) = super::requested_program(ctl, text, dialect)?;
    let mut c = Collect::new(ctl, with_junctions);
    let (v, _, _) = ctl
        .validate_program_with(&text, dialect, Options::default(), &mut c)
        .map_err(super::status_of)?;
    if v.has_errors() {
        return Err(invalid_with_diagnostics("program", &v.diagnostics));
    }
    Ok(c.finish(&v.diagnostics))
}

/// The approach legs of a restart from block `from_block` of `text` (empty: the selected
/// program, its blocks before `from_block` from where its last run started, as `Start`
/// does): a pass of their own, refused as validation refuses (`restart_block_not_found`).
pub(super) fn approach_legs(
    ctl: &Controller,
    text: &str,
    dialect: &str,
    from_block: u32,
) -> Result<Vec<Block>, Status> {
    let origin = super::restart_origin(ctl, text, Some(from_block));
    let (text, dialect) = super::requested_program(ctl, text, dialect)?;
    let (v, legs) = ctl
        .restart_approach(&text, dialect, from_block, origin)
        .map_err(super::status_of)?;
    if v.has_errors() {
        return Err(invalid_with_diagnostics("program", &v.diagnostics));
    }
    Ok(legs)
}

#[tonic::async_trait]
impl Preview for PreviewSvc {
    async fn get_preview_data(
        &self,
        req: Request<pb::PreviewDataRequest>,
    ) -> Result<Response<pb::PreviewData>, Status> {
        require(&req, Observer, "GetPreviewData")?;
        let r = req.into_inner();
        let st = self.0.clone();
        let data = blocking(move || {
            // The selected program: what its load's pass recorded, if that is still the
            // pass of the next start (no second pass of the same program with the same
            // setup).
            let recorded = (r.text.is_empty() && own_dialect(&st, &r.dialect)?)
                .then(|| recorded_preview(&st, r.junctions))
                .flatten();
            let mut data = match recorded {
                Some(d) => d,
                None => preview_data(&st.ctl, &r.text, &r.dialect, r.junctions)?,
            };
            if let Some(n) = r.from_block {
                let axes = st.ctl.config().axes.len();
                let legs = approach_legs(&st.ctl, &r.text, &r.dialect, n)?;
                data.approach = legs.iter().filter_map(|b| element(b, axes)).collect();
            }
            Ok::<_, Status>(data)
        })
        .await??;
        Ok(Response::new(data))
    }

    async fn get_preview_outline(
        &self,
        req: Request<pb::PreviewOutlineRequest>,
    ) -> Result<Response<pb::PreviewOutline>, Status> {
        require(&req, Observer, "GetPreviewOutline")?;
        let r = req.into_inner();
        let st = self.0.clone();
        let reply = blocking(move || super::preview_outline::outline_reply(&st, &r)).await??;
        Ok(Response::new(reply))
    }

    async fn get_preview(
        &self,
        req: Request<pb::GetPreviewRequest>,
    ) -> Result<Response<pb::GetPreviewReply>, Status> {
        require(&req, Observer, "GetPreview")?;
        let r = req.into_inner();
        let st = self.0.clone();
        let turn = match r.velocity {
            true => Some(self.0.velocity_plots.turn().await?),
            false => None,
        };
        let reply = blocking(move || {
            let _turn = turn;
            render_preview(&st, &r)
        })
        .await??;
        Ok(Response::new(reply))
    }
}

fn no_page(page: u32, pages: u32) -> Status {
    Status::invalid_argument(format!(
        "page {page} does not exist: the program has {pages} page(s) (R387 blocks each)"
    ))
}

/// Renders the picture of `GetPreview` with the preview crate, with the machine's settings:
/// of the selected program from its load's pass while that is the next start's
/// ([`recorded_pass`]), else from a pass with the setup in force.
pub fn render_preview(
    st: &ApiState,
    r: &pb::GetPreviewRequest,
) -> Result<pb::GetPreviewReply, Status> {
    let ctl = &st.ctl;
    let recorded = if r.text.is_empty() && own_dialect(st, &r.dialect)? {
        recorded_pass(st)
    } else {
        None
    };
    let (text, dialect) = super::text_or_selected(ctl, r.text.clone(), &r.dialect)?;
    let source = match &recorded {
        Some(pass) => ::preview::pipeline::Source::Recorded(pass),
        None => {
            ctl.count_validation_pass();
            ::preview::pipeline::Source::Text(&text)
        }
    };
    let setup = ctl.machine_setup_in(dialect).map_err(super::status_of)?;
    let mut opts = preview_options(&setup, r)?;
    opts.plot_max_ticks = st.velocity_plots.max_ticks();
    let png = r.format == pb::ImageFormat::Png as i32;
    if r.velocity {
        velocity_reply(source, &opts, png)
    } else {
        picture_reply(source, &opts, png)
    }
}

/// The machine's preview options with the request's plane, page and size.
fn preview_options(
    setup: &kernel::machine::MachineSetup,
    r: &pb::GetPreviewRequest,
) -> Result<::preview::PreviewOptions, Status> {
    let mut opts = ::preview::PreviewOptions::from_machine(setup);
    opts.plane = if r.plane.is_empty() {
        ::preview::ViewPlane::Xy
    } else {
        ::preview::ViewPlane::parse(&r.plane).ok_or_else(|| {
            Status::invalid_argument(format!("plane {:?}: use xy, xz or yz", r.plane))
        })?
    };
    opts.page = r.page.max(1);
    if r.width_px > 0 {
        opts.width_px = r.width_px.clamp(200, 8000);
    }
    if r.height_px > 0 {
        opts.height_px = r.height_px.clamp(200, 8000);
    }
    Ok(opts)
}

/// The image bytes (PNG or SVG) and their format code.
fn encode_image(
    png: bool,
    to_svg: impl FnOnce() -> String,
    to_png: impl FnOnce() -> Result<Vec<u8>, ::preview::RenderError>,
) -> Result<(Vec<u8>, i32), Status> {
    if png {
        let bytes = to_png().map_err(|e| Status::internal(format!("PNG: {e}")))?;
        Ok((bytes, pb::ImageFormat::Png as i32))
    } else {
        Ok((to_svg().into_bytes(), pb::ImageFormat::Svg as i32))
    }
}

fn refuse(d: Vec<Diagnostic>) -> Status {
    invalid_with_diagnostics("program", &d)
}

/// The velocity plot page asked for.
fn velocity_reply(
    source: ::preview::pipeline::Source<'_>,
    opts: &::preview::PreviewOptions,
    png: bool,
) -> Result<pb::GetPreviewReply, Status> {
    let v = ::preview::velocity_plot_source(source, opts, true).map_err(refuse)?;
    if opts.page > v.pages {
        return Err(no_page(opts.page, v.pages));
    }
    let (image, format) = encode_image(png, || v.to_svg(), || v.to_png())?;
    Ok(pb::GetPreviewReply {
        image,
        format,
        page: v.page,
        pages: v.pages,
        red: Vec::new(),
        red_junctions: 0,
        smooth_junctions: 0,
        diagnostics: v.warnings.iter().map(diagnostic_to_pb).collect(),
    })
}

/// The picture page asked for, with the junctions that slow the path down (red).
fn picture_reply(
    source: ::preview::pipeline::Source<'_>,
    opts: &::preview::PreviewOptions,
    png: bool,
) -> Result<pb::GetPreviewReply, Status> {
    let p = ::preview::render_source(source, opts).map_err(refuse)?;
    if opts.page > p.pages {
        return Err(no_page(opts.page, p.pages));
    }
    let (image, format) = encode_image(png, || p.to_svg(), || p.to_png())?;
    Ok(pb::GetPreviewReply {
        image,
        format,
        page: p.page,
        pages: p.pages,
        red: p
            .red
            .iter()
            .map(|j| pb::RedBlock {
                seq: j.seq,
                block: j.n,
                line: j.line,
                class: match j.kind {
                    ::preview::RedKind::Stop => pb::JunctionClass::Stop,
                    ::preview::RedKind::SpeedDrop => pb::JunctionClass::SpeedDrop,
                } as i32,
                speed_mm_s: j.v_mm_s,
                feed_mm_s: j.feed_mm_s,
            })
            .collect(),
        red_junctions: p.red_junctions,
        smooth_junctions: p.smooth_junctions,
        diagnostics: p.warnings.iter().map(diagnostic_to_pb).collect(),
    })
}
