//! The life of a run of compensated elements (SPEC §4.1-4.2): which blocks start one, which
//! continue it, which are bridged, which cancel it; each new element is joined to the one
//! before (the junction closes the previous element). After every step the R397 check
//! (`optimise`) looks at the element before the newest, and `emit` releases what is final.

use std::collections::VecDeque;

use super::corner::{self, Junction, NoIntersection, Resolved};
use super::geom::{EPS_MM, Geo, V2};
use super::{
    CompConfig, Compensator, CornerArc, Elem, ElemKind, FarCorner, MAX_BRIDGED, Role, Run, Shape,
    err, name, side_of, signed_offset,
};
use crate::block::{ArcDir, Block, BlockKind, Comp, Path, Plane};
use crate::diag::{DiagCode, Diagnostic};
use crate::units::AxesMm;

/// Why a run of compensated elements ends.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum RunEnd {
    /// G40, a new side/radius, or program end: the last equidistant ends on the
    /// perpendicular at its programmed end point (SPEC §4.2).
    Cancel,
    /// A rapid: as `Cancel`, plus the R764 exit optimisation.
    Rapid,
}

pub(super) fn all_finite(b: &Block) -> bool {
    let fin = |p: &AxesMm| p.0.iter().all(|v| v.is_finite());
    let comp_ok = side_of(b.comp).is_none_or(|(_, _, r)| r.is_finite());
    comp_ok
        && match b.kind {
            BlockKind::Motion { start, end, path } => {
                fin(&start)
                    && fin(&end)
                    && match path {
                        Path::Arc { center, .. } => fin(&center),
                        _ => true,
                    }
            }
            BlockKind::Dwell { seconds } => seconds.is_finite(),
            BlockKind::TableWrite { values, .. } => values.iter().flatten().all(|v| v.is_finite()),
            BlockKind::Technology | BlockKind::ToolChange { .. } => true,
        }
}

/// What a block is for the compensation in `plane`.
enum Class {
    /// Motion in the plane: a rapid (`rapid`), a line or an arc.
    InPlane { geo: Geo, rapid: bool },
    /// No motion in the plane (technology, dwell, motion of other axes only).
    Other,
}

fn classify(b: &Block, plane: Plane) -> Result<Class, Diagnostic> {
    let BlockKind::Motion { start, end, path } = b.kind else {
        return Ok(Class::Other);
    };
    let a = V2::of(&start, plane);
    let e = V2::of(&end, plane);
    match path {
        Path::Arc {
            dir,
            center,
            plane: arc_plane,
        } => {
            if arc_plane != plane {
                if b.comp == Comp::Off {
                    return Ok(Class::Other);
                }
                return Err(err(
                    DiagCode::CompArcOtherPlane,
                    b,
                    "arc in another plane than the radius compensation plane",
                ));
            }
            let c = V2::of(&center, plane);
            if a.dist(c) <= EPS_MM {
                return Err(err(DiagCode::ArcRadiusZero, b, "arc with zero radius"));
            }
            Ok(Class::InPlane {
                geo: Geo::arc(a, e, c, dir == ArcDir::Ccw),
                rapid: false,
            })
        }
        Path::Line | Path::Rapid if a.dist(e) > EPS_MM => Ok(Class::InPlane {
            geo: Geo::Line { a, b: e },
            rapid: path == Path::Rapid,
        }),
        _ => Ok(Class::Other),
    }
}

impl Compensator {
    /// A block while no compensation runs: a G41/G42 line starts a run; anything else passes.
    pub(super) fn push_idle(&mut self, b: &Block) -> Result<(), Diagnostic> {
        let class = classify(b, b.plane)?;
        let reconcile = self.needs_reconcile(b);
        match class {
            Class::InPlane { geo, rapid } if b.comp != Comp::Off => {
                // SPEC §4.2: start only in a block with linear interpolation.
                if geo.is_arc() {
                    return Err(err(
                        DiagCode::CompChangeOnArc,
                        b,
                        "radius compensation can only start in a linear block (G0/G1), not on an arc",
                    ));
                }
                self.start_run(b, geo, rapid);
                Ok(())
            }
            Class::InPlane { geo, .. } if geo.is_arc() && reconcile => Err(err(
                DiagCode::CompChangeOnArc,
                b,
                "after G40 without motion the first motion in the plane must be linear",
            )),
            _ => {
                self.pass(b, Role::Passthrough, 0.0);
                Ok(())
            }
        }
    }

    /// After G40 without motion (7.R339 = 1) the tool centre is still off the programmed path.
    fn needs_reconcile(&self, b: &Block) -> bool {
        let (Some(tool), Some((start, _, _))) = (self.tool, b.motion()) else {
            return false;
        };
        V2::of(&tool, self.last_plane).dist(V2::of(&start, self.last_plane)) > 1e-6
    }

    /// A block while compensation runs in `plane` with `comp`.
    pub(super) fn push_running(
        &mut self,
        b: &Block,
        plane: Plane,
        comp: Comp,
    ) -> Result<(), Diagnostic> {
        if b.comp != Comp::Off && b.plane != plane {
            return Err(err(
                DiagCode::PlaneChangeUnderComp,
                b,
                "the plane (G17/G18/G19) must not change while radius compensation is active",
            ));
        }
        match classify(b, plane)? {
            Class::Other => self.push_other(b),
            Class::InPlane { geo, rapid: true } => {
                // SPEC §4.2: G0 cancels; the rapid itself restarts if compensation stays on.
                self.end_run(RunEnd::Rapid);
                if b.comp != Comp::Off {
                    self.start_run(b, geo, true);
                } else {
                    self.pass(b, Role::Passthrough, 0.0);
                }
                Ok(())
            }
            Class::InPlane { geo, rapid: false } if b.comp == Comp::Off => {
                if geo.is_arc() {
                    return Err(err(
                        DiagCode::CompChangeOnArc,
                        b,
                        "G40 can only be programmed in a linear block, not on an arc",
                    ));
                }
                self.end_run(RunEnd::Cancel);
                self.pass(b, Role::Passthrough, 0.0);
                Ok(())
            }
            Class::InPlane { geo, rapid: false } if b.comp != comp => self.restart(b, geo, comp),
            Class::InPlane { geo, rapid: false } => self.add_regular(b, geo),
        }
    }

    /// A block without motion in the plane while compensation runs: G40 without motion
    /// (7.R339 = 1) cancels; anything else is bridged (SPEC §4.1).
    fn push_other(&mut self, b: &Block) -> Result<(), Diagnostic> {
        if b.comp == Comp::Off {
            // SPEC §4.2: G40 without motion in the plane only with 7.R339 = 1.
            if !self.cfg.g40_without_motion {
                return Err(err(
                    DiagCode::G40WithoutMotion,
                    b,
                    "G40 must be programmed in a block with motion in the compensation plane (or set 7.R339 = 1)",
                ));
            }
            self.end_run(RunEnd::Cancel);
            self.pass(b, Role::Passthrough, 0.0);
            return Ok(());
        }
        let run = self.run.as_mut().expect("running");
        let back = run.elems.back_mut().expect("a run has an element");
        if back.trailer.len() >= MAX_BRIDGED {
            return Err(err(
                DiagCode::CompTooManyBridged,
                b,
                format!("more than {MAX_BRIDGED} blocks without motion in the compensation plane"),
            ));
        }
        back.trailer.push(*b);
        Ok(())
    }

    /// A line with another side or radius than the running `comp`: cancel and start again.
    fn restart(&mut self, b: &Block, geo: Geo, comp: Comp) -> Result<(), Diagnostic> {
        let side_changed = side_of(b.comp).map(|s| s.0) != side_of(comp).map(|s| s.0);
        if side_changed && !self.cfg.check.allow_side_change {
            return Err(err(
                DiagCode::CompSideSwitch,
                b,
                "direct change between G41 and G42 is not allowed (program G40 first, or set 6.R397 = 1)",
            ));
        }
        if geo.is_arc() {
            return Err(err(
                DiagCode::CompChangeOnArc,
                b,
                "radius compensation can only change in a linear block, not on an arc",
            ));
        }
        self.end_run(RunEnd::Cancel);
        self.start_run(b, geo, false);
        Ok(())
    }

    fn start_run(&mut self, b: &Block, geo: Geo, rapid: bool) {
        self.last_plane = b.plane;
        let r = signed_offset(b.comp).abs();
        self.gouge.begin(b.plane, r, self.cfg.gouge_tolerance_mm(r));
        let start = self.tool.map_or(geo.start(), |t| V2::of(&t, b.plane));
        let kind = ElemKind::Transition { rapid };
        self.run = Some(Run {
            comp: b.comp,
            offset_mm: signed_offset(b.comp),
            plane: b.plane,
            elems: VecDeque::from([Elem::new(b, geo, Shape::AsProgrammed, kind, start)]),
        });
    }

    /// A compensated line or arc continuing the run: joined to the previous element, then
    /// the R397 check of the element before it, then whatever is final is emitted.
    fn add_regular(&mut self, b: &Block, geo: Geo) -> Result<(), Diagnostic> {
        let s = self.run.as_ref().expect("running").offset_mm;
        let (geo, shape, d7) = self.arc_off_circle_to_line(b, geo);
        if let Some(r) = geo.offset_radius(s)
            && r < -EPS_MM
        {
            return Err(err(
                DiagCode::ToolLargerThanArc,
                b,
                format!(
                    "tool radius {:.3} mm is larger than the inside arc radius {:.3} mm",
                    s.abs(),
                    r + s.abs()
                ),
            ));
        }
        let elem = Elem::new(b, geo, shape, ElemKind::Regular, geo.start());
        let d8 = self.append(elem)?;
        for d in d7.into_iter().chain(d8) {
            self.notes.push(d);
        }
        let n = self.run.as_ref().expect("running").elems.len();
        if n >= 2 {
            self.check_middle(n - 2);
        }
        self.emit_ready();
        Ok(())
    }

    /// R397 d7: an arc whose end point is off its circle becomes a line (with its warning).
    fn arc_off_circle_to_line(&self, b: &Block, geo: Geo) -> (Geo, Shape, Option<Diagnostic>) {
        let Geo::Arc { a, b: e, c, .. } = geo else {
            return (geo, Shape::AsProgrammed, None);
        };
        if !self.cfg.check.arc_off_circle_to_line
            || (a.dist(c) - e.dist(c)).abs() <= self.cfg.arc_end_tolerance_mm
        {
            return (geo, Shape::AsProgrammed, None);
        }
        let warning = Diagnostic::warning(
            DiagCode::ArcReplacedByLine,
            b.n,
            b.line,
            0,
            "arc end point is not on the circle; replaced by a line (R397 d7)",
        );
        (geo.chord(), Shape::Chord, Some(warning))
    }

    /// Appends `elem` to the run, joined to the last element. Where the equidistants do not
    /// meet, R397 d8 replaces an arc by its chord (the new one first, then the previous) and
    /// the warnings for that are returned; without a fix the run is left as it was.
    fn append(&mut self, elem: Elem) -> Result<Vec<Diagnostic>, Diagnostic> {
        let cfg = self.cfg;
        let run = self.run.as_mut().expect("running");
        let s = run.offset_mm;
        let back = run.elems.back().expect("a run has an element");
        match join(back, &elem, s, &cfg) {
            Ok(res) => {
                run.elems.push_back(elem);
                let n = run.elems.len();
                apply_join(&mut run.elems, n - 1, res);
                Ok(Vec::new())
            }
            Err(NoIntersection) => {
                let src = elem.src;
                let shapes_before = [back.shape, elem.shape];
                let mut elems = run.elems.clone();
                elems.push_back(elem);
                let n = elems.len();
                let fixed = cfg.check.arc_without_intersection_to_line
                    && [n - 1, n - 2]
                        .into_iter()
                        .any(|i| super::optimise::try_chord(&mut elems, i, s, &cfg));
                if !fixed {
                    return Err(err(
                        DiagCode::NoIntersection,
                        &src,
                        format!(
                            "intersection of equidistants not found (NENALEZEN PRUSEČÍK EKVIDISTANT) between blocks {} and {}",
                            name(&back.src),
                            name(&src)
                        ),
                    ));
                }
                let notes = [n - 2, n - 1]
                    .into_iter()
                    .zip(shapes_before)
                    .filter(|&(i, before)| elems[i].shape == Shape::Chord && before != Shape::Chord)
                    .map(|(i, _)| {
                        Diagnostic::warning(
                            DiagCode::NoIntersection,
                            elems[i].src.n,
                            elems[i].src.line,
                            0,
                            "no intersection of equidistants; arc replaced by a line (R397 d8)",
                        )
                    })
                    .collect();
                run.elems = elems;
                Ok(notes)
            }
        }
    }

    /// Closes the run: the last element ends on the perpendicular at its programmed end
    /// (a rapid start ends at its programmed end), then everything is released.
    pub(super) fn end_run(&mut self, why: RunEnd) {
        let Some(mut run) = self.run.take() else {
            return;
        };
        let s = run.offset_mm;
        if let Some(last) = run.elems.back_mut() {
            last.end = match last.kind {
                ElemKind::Transition { rapid: true } => last.geo.end(),
                _ => last.geo.offset_end(s),
            };
            last.close();
        }
        let n = run.elems.len();
        if why == RunEnd::Rapid && n >= 2 && run.elems[n - 1].is_regular() {
            self.exit_optimisation(&mut run.elems[n - 1], s);
        }
        self.last_plane = run.plane;
        for e in run.elems {
            self.emit_elem(e, s, run.plane);
        }
        self.report_gouges();
    }
}

/// The junction in front of `next`: a start block ends on the perpendicular to `next` at its
/// start (SPEC §4.2); otherwise the corner rules.
pub(super) fn join(
    prev: &Elem,
    next: &Elem,
    s: f64,
    cfg: &CompConfig,
) -> Result<Resolved, NoIntersection> {
    match prev.kind {
        ElemKind::Transition { .. } => Ok(Resolved {
            junction: Junction::Point {
                at: next.geo.offset_start(s),
                intersection: false,
            },
            far_mm: None,
            position_optimised: false,
        }),
        ElemKind::Regular => corner::resolve(&prev.geo, &next.geo, s, cfg),
    }
}

/// Puts the junction `res` between elements `i - 1` and `i`: it closes `i - 1`.
pub(super) fn apply_join(elems: &mut VecDeque<Elem>, i: usize, res: Resolved) {
    let (from, to, corner) = match res.junction {
        Junction::Point { at, .. } => (at, at, None),
        Junction::Arc {
            corner,
            from,
            to,
            sweep_rad,
        } => (
            from,
            to,
            Some(CornerArc {
                corner,
                to,
                sweep_rad,
            }),
        ),
    };
    let prev = &mut elems[i - 1];
    prev.end = from;
    prev.close();
    let next = &mut elems[i];
    next.start = to;
    next.corner = corner;
    next.far = res.far_mm.map(|distance_mm| {
        if res.position_optimised {
            FarCorner::ArcInserted { distance_mm }
        } else {
            FarCorner::Intersection { distance_mm }
        }
    });
}
