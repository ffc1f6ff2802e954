//! Service `cnc.v1.Preview`: programmed path, compensated path and junction classification of
//! a program, computed with the same kernel stages a run uses (interpret → compensate → plan).

use std::sync::Arc;

use proto::v1 as pb;
use proto::v1::preview_server::Preview;
use tonic::{Request, Response, Status};

use kernel::Diagnostic;
use kernel::block::{ArcDir, Block, BlockKind, Path};
use kernel::comp::compensate_all;
use kernel::plan::{Junction, Planner};

use super::auth::require;
use super::{ApiState, blocking, diagnostic_to_pb, invalid_with_diagnostics, plane_code};
use crate::runtime::config::Role::Observer;
use crate::runtime::controller::Controller;

/// Largest program the preview service plans, blocks (larger ones: paths only).
const PREVIEW_MAX_BLOCKS: usize = 1_000_000;

#[derive(Clone)]
pub struct PreviewSvc(pub Arc<ApiState>);

fn element(b: &Block, axes: usize) -> Option<pb::PathElement> {
    let BlockKind::Motion { start, end, path } = b.kind else {
        return None;
    };
    let (kind, center, plane) = match path {
        Path::Rapid => (pb::PathKind::Rapid, Vec::new(), String::new()),
        Path::Line => (pb::PathKind::Line, Vec::new(), String::new()),
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

/// Plans `blocks` (compensated first) and classifies the junction at the end of every
/// segment (SPEC §7.5).
pub fn junctions(ctl: &Controller, blocks: &[Block]) -> Result<Vec<pb::Junction>, Diagnostic> {
    let (comp_cfg, plan_cfg) = ctl.run_configs();
    let (comp, _) = compensate_all(blocks, &comp_cfg);
    plan_junctions(ctl, &comp, plan_cfg)
}

fn plan_junctions(
    ctl: &Controller,
    comp: &[Block],
    plan_cfg: kernel::plan::PlannerConfig,
) -> Result<Vec<pb::Junction>, Diagnostic> {
    let axes = ctl.config().axes.len();
    let mut planner = Planner::new(plan_cfg, 0);
    let mut out = Vec::new();
    let take = |planner: &mut Planner, out: &mut Vec<pb::Junction>| {
        while let Some(s) = planner.poll() {
            out.push(pb::Junction {
                seq: s.seq,
                block: s.n,
                line: s.line,
                class: match s.junction {
                    Junction::Stop => pb::JunctionClass::Stop,
                    Junction::Smooth => pb::JunctionClass::Smooth,
                    Junction::SpeedDrop => pb::JunctionClass::SpeedDrop,
                } as i32,
                position_mm: s.path.end().0[..axes].to_vec(),
                speed_mm_s: s.v_end_mm_s,
            });
        }
    };
    for b in comp {
        planner.push(b)?;
        take(&mut planner, &mut out);
    }
    planner.finish();
    take(&mut planner, &mut out);
    Ok(out)
}

/// Preview data of `text` (or of the selected program when `text` is empty).
pub fn preview_data(
    ctl: &Controller,
    text: &str,
    with_junctions: bool,
) -> Result<pb::PreviewData, Status> {
    let (blocks, mut diags): (Vec<Block>, Vec<Diagnostic>) = if text.is_empty() {
        let p = ctl.program().ok_or_else(|| {
            Status::failed_precondition("no program is selected and no text was given")
        })?;
        (p.blocks(), p.warnings.clone())
    } else {
        let c = ctl.compile_text(text);
        if c.has_errors() {
            return Err(invalid_with_diagnostics("program", &c.diagnostics));
        }
        (c.blocks, c.diagnostics)
    };
    let axes = ctl.config().axes.len();
    let (comp_cfg, plan_cfg) = ctl.run_configs();
    let (comp, comp_diags) = compensate_all(&blocks, &comp_cfg);
    diags.extend(comp_diags);
    let junctions = if with_junctions && comp.len() <= PREVIEW_MAX_BLOCKS {
        plan_junctions(ctl, &comp, plan_cfg)
            .map_err(|d| invalid_with_diagnostics("program", &[d]))?
    } else {
        Vec::new()
    };
    Ok(pb::PreviewData {
        axes: ctl
            .config()
            .axis_names()
            .iter()
            .map(|c| c.to_string())
            .collect(),
        programmed: blocks.iter().filter_map(|b| element(b, axes)).collect(),
        compensated: comp.iter().filter_map(|b| element(b, axes)).collect(),
        junctions,
        diagnostics: diags.iter().map(diagnostic_to_pb).collect(),
    })
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
        let data = blocking(move || preview_data(&st.ctl, &r.text, r.junctions)).await??;
        Ok(Response::new(data))
    }

    async fn get_preview(
        &self,
        req: Request<pb::GetPreviewRequest>,
    ) -> Result<Response<pb::GetPreviewReply>, Status> {
        require(&req, Observer, "GetPreview")?;
        let r = req.into_inner();
        let st = self.0.clone();
        let reply = blocking(move || render_preview(&st.ctl, &r)).await??;
        Ok(Response::new(reply))
    }
}

fn no_page(page: u32, pages: u32) -> Status {
    Status::invalid_argument(format!(
        "page {page} does not exist: the program has {pages} page(s) (R387 blocks each)"
    ))
}

/// Renders the picture of `GetPreview` with the preview crate, with the machine's settings.
pub fn render_preview(
    ctl: &Controller,
    r: &pb::GetPreviewRequest,
) -> Result<pb::GetPreviewReply, Status> {
    let text = if r.text.is_empty() {
        ctl.program()
            .ok_or_else(|| {
                Status::failed_precondition("no program is selected and no text was given")
            })?
            .text
            .to_string()
    } else {
        r.text.clone()
    };
    let mut opts = ::preview::PreviewOptions::new(ctl.current_setup());
    let (comp, planner) = ctl.run_configs();
    opts.comp = comp;
    opts.planner = planner;
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
    let png = r.format == pb::ImageFormat::Png as i32;
    let encode =
        |svg: String, png_bytes: Option<Result<Vec<u8>, ::preview::RenderError>>| match png_bytes {
            Some(b) => b.map_err(|e| Status::internal(format!("PNG: {e}"))),
            None => Ok(svg.into_bytes()),
        };
    let fmt = if png {
        pb::ImageFormat::Png
    } else {
        pb::ImageFormat::Svg
    };
    let refuse = |d: Vec<Diagnostic>| invalid_with_diagnostics("program", &d);
    if r.velocity {
        let v = ::preview::velocity_plot(&text, &opts, true).map_err(refuse)?;
        if opts.page > v.pages {
            return Err(no_page(opts.page, v.pages));
        }
        let image = if png {
            encode(String::new(), Some(v.to_png()))?
        } else {
            encode(v.to_svg(), None)?
        };
        return Ok(pb::GetPreviewReply {
            image,
            format: fmt as i32,
            page: v.page,
            pages: v.pages,
            red: Vec::new(),
            red_junctions: 0,
            smooth_junctions: 0,
            diagnostics: v.warnings.iter().map(diagnostic_to_pb).collect(),
        });
    }
    let p = ::preview::render(&text, &opts).map_err(refuse)?;
    if opts.page > p.pages {
        return Err(no_page(opts.page, p.pages));
    }
    let image = if png {
        encode(String::new(), Some(p.to_png()))?
    } else {
        encode(p.to_svg(), None)?
    };
    Ok(pb::GetPreviewReply {
        image,
        format: fmt as i32,
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
