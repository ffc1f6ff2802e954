//! Emission: elements that no optimisation can move any more become tool-centre blocks
//! (start moves, inserted corner arcs, equidistants, collapsed elements, bridged blocks), each
//! with its [`Role`]; messages that depend on what is finally emitted (R765, R339 `-`, the
//! gouge check) are given here.

use std::f64::consts::PI;

use super::geom::{EPS_MM, Geo, V2};
use super::optimise::arc_piece_sweep;
use super::{
    CompBlock, Compensator, CornerArc, Elem, ElemKind, FarCorner, Role, Shape, WINDOW, gouge,
    source_name, with_plane,
};
use crate::block::{ArcDir, Block, BlockKind, Path, Plane};
use crate::diag::{DiagCode, Diagnostic};
use crate::units::AxesMm;

impl Compensator {
    /// Emits elements that no optimisation can change any more.
    pub(super) fn emit_ready(&mut self) {
        loop {
            let Some(run) = self.run.as_mut() else { return };
            if run.elems.len() <= WINDOW || !run.elems[0].is_closed() {
                return;
            }
            let e = run.elems.pop_front().expect("non-empty");
            let (s, plane) = (run.offset_mm, run.plane);
            self.emit_elem(e, s, plane);
        }
    }

    /// The whole-run gouge check (docs/compensation.md decision 19): one message per tool
    /// block that cuts into the contour, naming both blocks and the depth.
    pub(super) fn report_gouges(&mut self) {
        let (found, skipped) = self.gouge.finish();
        for g in found {
            let (t, c) = (g.tool, g.contour);
            let msg = format!(
                "{} the tool centre of block {} comes {:.3} mm closer than the tool radius to the contour of block {}: the tool cuts into the part",
                gouge::MESSAGE_PREFIX,
                source_name(t.n, t.line),
                g.depth_mm,
                source_name(c.n, c.line)
            );
            self.notes.push(if self.cfg.refuse_gouges {
                Diagnostic::error(DiagCode::Gouge, t.n, t.line, 0, msg)
            } else {
                Diagnostic::warning(DiagCode::Gouge, t.n, t.line, 0, msg)
            });
        }
        if let Some(t) = skipped {
            self.notes.push(Diagnostic::info( DiagCode::GougeCheckLimited,
                t.n,
                t.line,
                0,
                format!(
                    "the gouge check covers the first {} elements of a compensated contour; from here on it is not checked",
                    gouge::MAX_CHECKED_ELEMENTS
                ),
            ));
        }
    }

    fn tool_or(&self, p: AxesMm) -> AxesMm {
        self.tool.unwrap_or(p)
    }

    fn put(&mut self, block: Block, role: Role, offset_mm: f64) {
        match role {
            Role::Equidistant | Role::EquidistantChord | Role::CornerArc | Role::Collapsed => {
                self.gouge.tool(&block)
            }
            _ => {}
        }
        if let Some((_, end, _)) = block.motion() {
            self.tool = Some(end);
        }
        self.out.push_back(CompBlock {
            block,
            role,
            offset_mm,
        });
    }

    /// A motion from where the tool is to `end`; without any axis moving it is kept as a
    /// block without motion (its M functions and feed still count).
    fn put_motion(&mut self, src: &Block, end: AxesMm, path: Path, role: Role, s: f64) {
        let start = self.tool_or(match src.kind {
            BlockKind::Motion { start, .. } => start,
            _ => end,
        });
        let mut b = *src;
        let moves = (end - start).max_abs(end.0.len()) > EPS_MM;
        b.kind = if moves || matches!(path, Path::Arc { .. }) {
            BlockKind::Motion { start, end, path }
        } else {
            BlockKind::Technology
        };
        self.put(b, role, s);
    }

    /// A block outside any run, or bridged inside one: motions start where the tool is, and
    /// a motion without displacement in `plane` keeps the tool's plane position.
    pub(super) fn pass(&mut self, b: &Block, role: Role, s: f64) {
        let plane = if role == Role::Bridged {
            self.last_plane
        } else {
            b.plane
        };
        match b.kind {
            BlockKind::Motion {
                start: pstart,
                end,
                path,
            } => {
                let start = self.tool_or(pstart);
                let mut end = end;
                let moves_in_plane = matches!(path, Path::Arc { .. })
                    || V2::of(&pstart, plane).dist(V2::of(&end, plane)) > EPS_MM;
                if !moves_in_plane || role == Role::Bridged {
                    V2::of(&start, plane).put(&mut end, plane);
                }
                let mut out = *b;
                out.kind = BlockKind::Motion { start, end, path };
                self.put(out, role, s);
            }
            _ => self.put(*b, role, s),
        }
    }

    /// One closed element: its start move, or its R765 report, corner arc and equidistant;
    /// then the blocks bridged after it.
    pub(super) fn emit_elem(&mut self, e: Elem, s: f64, plane: Plane) {
        let (pstart, pend) = match e.src.kind {
            BlockKind::Motion { start, end, .. } => (start, end),
            _ => (AxesMm::ZERO, AxesMm::ZERO),
        };
        match e.kind {
            ElemKind::Transition { rapid } => {
                let path = if rapid { Path::Rapid } else { Path::Line };
                // A rapid not followed by a cut stays uncompensated (SPEC §4.2).
                let (role, s) = if rapid && e.end == e.geo.end() {
                    (Role::Passthrough, 0.0)
                } else {
                    (Role::StartMove, s)
                };
                self.put_motion(&e.src, with_plane(pend, e.end, plane), path, role, s);
            }
            ElemKind::Regular => {
                self.gouge.contour(&e.programmed, &e.src);
                if let Some(far) = e.far {
                    self.report_far_corner(&e.src, far);
                }
                if let Some(c) = e.corner {
                    self.emit_corner_arc(&e.src, c, pstart, s, plane);
                }
                self.emit_equidistant(&e, pstart, pend, s, plane);
            }
        }
        self.last_plane = plane;
        for t in &e.trailer {
            self.pass(t, Role::Bridged, s);
        }
    }

    /// R765: the junction in front of `src` lies far from the programmed corner.
    fn report_far_corner(&mut self, src: &Block, far: FarCorner) {
        if !self.cfg.position.report {
            return;
        }
        let (d, what) = match far {
            FarCorner::ArcInserted { distance_mm } => {
                (distance_mm, "an arc was inserted instead (R765)")
            }
            FarCorner::Intersection { distance_mm } => (distance_mm, "check the corner (R765)"),
        };
        let pct = self.cfg.position.percent;
        self.notes.push(Diagnostic::warning( DiagCode::CornerFarFromEquidistant,
            src.n,
            src.line,
            0,
            format!(
                "the equidistant lies {d:.3} mm from the programmed corner, more than {pct:.0} % of the tool radius; {what}"
            ),
        ));
    }

    /// The arc of tool radius inserted at the corner in front of `src` (R339).
    fn emit_corner_arc(&mut self, src: &Block, c: CornerArc, pstart: AxesMm, s: f64, plane: Plane) {
        let here = self.tool_or(pstart);
        if c.sweep_rad.abs() * s.abs() <= EPS_MM {
            return;
        }
        let dir = if c.sweep_rad > 0.0 {
            ArcDir::Ccw
        } else {
            ArcDir::Cw
        };
        let path = Path::Arc {
            dir,
            center: with_plane(here, c.corner, plane),
            plane,
        };
        self.put_motion(src, with_plane(here, c.to, plane), path, Role::CornerArc, s);
        // SPEC §4.3: R339 sign `-`, an information message per inserted arc.
        if self.cfg.report_inserted_arcs {
            self.notes.push(Diagnostic::info(
                DiagCode::CornerArcInserted,
                src.n,
                src.line,
                0,
                "arc of tool radius inserted at the corner (R339)",
            ));
        }
    }

    /// The element's equidistant (line, arc, or collapsed to a block without plane motion).
    fn emit_equidistant(&mut self, e: &Elem, pstart: AxesMm, pend: AxesMm, s: f64, plane: Plane) {
        let role = match e.shape {
            Shape::Chord => Role::EquidistantChord,
            Shape::AsProgrammed => Role::Equidistant,
        };
        let end = with_plane(pend, e.end, plane);
        let degenerate_arc = e.geo.offset_radius(s).is_some_and(|r| r <= EPS_MM);
        if e.is_collapsed() || degenerate_arc {
            self.put_motion(&e.src, end, Path::Line, Role::Collapsed, s);
            return;
        }
        let Geo::Arc { c, .. } = e.geo else {
            self.put_motion(&e.src, end, Path::Line, role, s);
            return;
        };
        let rho = e.geo.offset_radius(s).unwrap_or(0.0);
        let sweep = arc_piece_sweep(&e.geo, e.start, e.end);
        if sweep.abs() * rho <= EPS_MM {
            self.put_motion(&e.src, end, Path::Line, role, s);
            return;
        }
        let dir = if sweep > 0.0 { ArcDir::Ccw } else { ArcDir::Cw };
        let path = Path::Arc {
            dir,
            center: with_plane(pstart, c, plane),
            plane,
        };
        // Halves above 180°, so neither end coincides with its start and the planner reads
        // the sweep unambiguously.
        if sweep.abs() > PI {
            let start_angle = (e.start - c).angle();
            let mid = c + V2::from_angle(start_angle + sweep / 2.0) * rho;
            let start = self.tool_or(pstart);
            let mid_axes = with_plane(start.lerp(&end, 0.5), mid, plane);
            self.put_motion(&e.src, mid_axes, path, role, s);
        }
        self.put_motion(&e.src, end, path, role, s);
    }
}
