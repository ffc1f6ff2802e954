//! Commands of the Preview service (`preview-data`, `preview --remote`) and the local preview
//! (`preview` without a daemon: the preview crate with default machine settings).

use std::path::Path;

use proto::v1 as pb;
use proto::v1::preview_client::PreviewClient;
use serde_json::{Value, json};

use crate::call::{Reply, call};
use crate::connect::Svc;
use crate::error::CliError;
use crate::render::{Render, block_name, diag_lines, diags_json, read_text, show};

/// What `cncctl preview` draws: file, output, plane, page, velocity plot or path picture.
pub struct PreviewArgs<'a> {
    pub file: &'a Path,
    pub out: &'a Path,
    pub plane: &'a str,
    pub page: u32,
    pub velocity: bool,
    /// `--dialect` (default: by the file's name).
    pub dialect: Option<&'a str>,
}

impl PreviewArgs<'_> {
    fn png(&self) -> bool {
        self.out
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("png"))
    }
}

/// Paths and junctions of a program file, as a summary or JSON.
pub async fn data(
    v: &mut PreviewClient<Svc>,
    file: &Path,
    junctions: bool,
    dialect: Option<&str>,
    j: bool,
) -> Reply {
    let dialect = crate::dialect::for_file(file, dialect)?;
    let text = read_text(file)?;
    call(
        j,
        v.get_preview_data(pb::PreviewDataRequest {
            text,
            junctions,
            from_block: None,
            dialect,
        }),
    )
    .await
}

fn junction_class(class: i32) -> &'static str {
    pb::JunctionClass::try_from(class)
        .map(|k| k.as_str_name())
        .unwrap_or("?")
}

impl Render for pb::PreviewData {
    fn json(&self) -> Value {
        let el = |e: &pb::PathElement| {
            json!({"seq": e.seq, "block": e.block, "line": e.line,
            "kind": pb::PathKind::try_from(e.kind).map(|k| k.as_str_name()).unwrap_or("?"),
            "start_mm": e.start_mm, "end_mm": e.end_mm, "center_mm": e.center_mm, "plane": e.plane})
        };
        json!({"axes": self.axes, "programmed": self.programmed.iter().map(el).collect::<Vec<_>>(),
        "compensated": self.compensated.iter().map(el).collect::<Vec<_>>(),
        "junctions": self.junctions.iter().map(|x| json!({"seq": x.seq, "block": x.block, "line": x.line,
            "class": junction_class(x.class),
            "position_mm": x.position_mm, "speed_mm_s": x.speed_mm_s})).collect::<Vec<_>>(),
        "diagnostics": diags_json(&self.diagnostics)})
    }
    /// A summary, then the first 50 red junctions and every diagnostic.
    fn human(&self) -> String {
        let red: Vec<&pb::Junction> = self
            .junctions
            .iter()
            .filter(|j| j.class != pb::JunctionClass::Smooth as i32)
            .collect();
        let mut s = format!(
            "{} programmed moves, {} compensated moves, {} junctions ({} red: stop or speed drop)",
            self.programmed.len(),
            self.compensated.len(),
            self.junctions.len(),
            red.len()
        );
        for r in red.iter().take(50) {
            let b = block_name(r.block);
            s.push_str(&format!(
                "\n  line {:<5} {b:<6} {}",
                r.line,
                junction_class(r.class)
            ));
        }
        s + &diag_lines(&self.diagnostics)
    }
}

/// A picture written to a file: where, which page, and the red blocks.
struct Written<'a> {
    out: &'a Path,
    /// Page and junction counts for people.
    summary: String,
    red: Vec<String>,
    /// JSON fields beside `out` and `red_blocks`.
    extra: Value,
}

impl Render for Written<'_> {
    fn json(&self) -> Value {
        let mut v = json!({"out": self.out.display().to_string(), "red_blocks": self.red});
        if let (Some(v), Some(extra)) = (v.as_object_mut(), self.extra.as_object()) {
            v.extend(extra.clone());
        }
        v
    }
    fn human(&self) -> String {
        format!(
            "{}: {}{}{}",
            self.out.display(),
            self.summary,
            if self.red.is_empty() { "" } else { ": " },
            self.red.join(" ")
        )
    }
}

/// Renders on the daemon (its axes, limits, constants and offsets) and writes the image.
pub async fn remote(v: &mut PreviewClient<Svc>, a: &PreviewArgs<'_>, j: bool) -> Reply {
    let dialect = crate::dialect::for_file(a.file, a.dialect)?;
    let text = read_text(a.file)?;
    let format = if a.png() {
        pb::ImageFormat::Png
    } else {
        pb::ImageFormat::Svg
    };
    let r = v
        .get_preview(pb::GetPreviewRequest {
            text,
            format: format as i32,
            plane: a.plane.to_string(),
            page: a.page,
            velocity: a.velocity,
            width_px: 0,
            height_px: 0,
            dialect,
        })
        .await?
        .into_inner();
    std::fs::write(a.out, &r.image).map_err(CliError::write(a.out))?;
    let red = r
        .red
        .iter()
        .map(|b| {
            b.block
                .map_or(format!("line {}", b.line), |n| format!("N{n}"))
        })
        .collect();
    // (The notes: a velocity plot cut at its bound says so.)
    let notes: Vec<String> = r
        .diagnostics
        .iter()
        .map(|d| format!("{}: {}", d.code, d.message))
        .collect();
    let mut summary = format!(
        "page {} of {}, {} red junctions",
        r.page, r.pages, r.red_junctions
    );
    for n in &notes {
        summary += &format!("; {n}");
    }
    let written = Written {
        out: a.out,
        summary,
        red,
        extra: json!({"page": r.page, "pages": r.pages, "notes": notes,
            "red_junctions": r.red_junctions, "smooth_junctions": r.smooth_junctions}),
    };
    show(j, &written)
}

/// Renders here with default machine settings and writes the image.
pub fn local(a: &PreviewArgs<'_>, j: bool) -> Reply {
    let text = read_text(a.file)?;
    let plane =
        preview::ViewPlane::parse(a.plane).ok_or_else(|| CliError::Plane(a.plane.to_string()))?;
    let mut opts = preview::PreviewOptions {
        plane,
        page: a.page.max(1),
        ..Default::default()
    };
    opts.setup.dialect = crate::dialect::local(a.file, a.dialect)?;
    let rejected = |d: Vec<kernel::Diagnostic>| CliError::PreviewRejected {
        file: a.file.to_path_buf(),
        lines: d.iter().map(|x| x.to_string()).collect(),
    };
    let png_error = |e: preview::RenderError| CliError::Png(e.to_string());
    let (bytes, summary, red) = if a.velocity {
        let v = preview::velocity_plot(&text, &opts, true).map_err(rejected)?;
        let b = if a.png() {
            v.to_png().map_err(png_error)?
        } else {
            v.to_svg().into_bytes()
        };
        let summary = format!(
            "velocity plot page {} of {}, {:.2} s .. {:.2} s",
            v.page, v.pages, v.start_s, v.end_s
        );
        (b, summary, Vec::new())
    } else {
        let p = preview::render(&text, &opts).map_err(rejected)?;
        let b = if a.png() {
            p.to_png().map_err(png_error)?
        } else {
            p.to_svg().into_bytes()
        };
        let summary = format!(
            "page {} of {}, {} red junctions",
            p.page, p.pages, p.red_junctions
        );
        (b, summary, p.red_blocks())
    };
    std::fs::write(a.out, &bytes).map_err(CliError::write(a.out))?;
    let extra = json!({"summary": summary});
    show(
        j,
        &Written {
            out: a.out,
            summary,
            red,
            extra,
        },
    )
}
