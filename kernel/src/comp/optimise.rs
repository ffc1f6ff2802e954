//! The R397 check and the optimisations that remove a backward loop of the tool centre
//! (SPEC §4.5, docs/compensation.md): the arc-to-chord replacements (R397 d5, d8), the 3- and
//! 4-block optimisations (R397 d3, d4), the trim at an inserted corner arc (decision 18) and
//! the exit optimisation before a rapid (R764). Each works on the window of held elements and
//! either changes it consistently or leaves it as it was.

use std::collections::VecDeque;
use std::f64::consts::PI;

use super::corner::NoIntersection;
use super::geom::{self, EPS_MM, Geo, V2, intersect, wrap_pi};
use super::lifecycle::{apply_join, join};
use super::{CompConfig, Compensator, CornerArc, Elem, Equidistant, Shape, name};
use crate::block::Block;
use crate::diag::{DiagCode, Diagnostic};

/// Signed sweep of the equidistant of an arc element between tool-centre points `start` and
/// `end`: the programmed sweep corrected by how far the junctions moved each end. A result
/// with the opposite sign is an equidistant that runs backwards.
pub(super) fn arc_piece_sweep(geo: &Geo, start: V2, end: V2) -> f64 {
    let Geo::Arc {
        a, c, sweep_rad, ..
    } = *geo
    else {
        return 0.0;
    };
    let a0 = (a - c).angle();
    let ds = wrap_pi((start - c).angle() - a0);
    let de = wrap_pi((end - c).angle() - (a0 + sweep_rad));
    sweep_rad - ds + de
}

/// Whether the equidistant piece of `e` (between its tool-centre start and end) runs against
/// the programmed direction: the loop R397 looks for.
fn runs_backwards(e: &Elem, offset_mm: f64) -> bool {
    if e.is_collapsed() {
        return false;
    }
    match e.geo {
        Geo::Line { a, b } => (e.end - e.start).dot(b - a) < -EPS_MM,
        Geo::Arc { sweep_rad, .. } => {
            if e.geo.offset_radius(offset_mm).unwrap_or(0.0) <= EPS_MM {
                return false;
            }
            let s = arc_piece_sweep(&e.geo, e.start, e.end);
            s * sweep_rad < 0.0 && s.abs() > 1e-12
        }
    }
}

impl Compensator {
    /// R397 check of the middle of three consecutive compensated elements, and the
    /// optimisations that remove the loop (SPEC §4.5). See `docs/compensation.md`.
    pub(super) fn check_middle(&mut self, m: usize) {
        let cfg = self.cfg;
        let run = self.run.as_mut().expect("running");
        let s = run.offset_mm;
        let elems = &mut run.elems;
        if m == 0 || m + 1 >= elems.len() {
            return;
        }
        // Only between compensated blocks (no start).
        if !elems[m - 1].is_regular() || !elems[m].is_regular() {
            return;
        }
        if !runs_backwards(&elems[m], s) {
            return;
        }
        let src = elems[m].src;
        // Next to an inserted arc SPEC §4.5 does no R397 check; the loop is resolved
        // geometrically instead (docs/compensation.md, decision 18).
        if elems[m].corner.is_some() || elems[m + 1].corner.is_some() {
            if trim_at_corner_arc(elems, m, s) {
                return;
            }
            elems[m].state = Equidistant::Backward;
            if cfg.check.check && cfg.check.warn {
                self.notes.push(backward_warning(&src));
            }
            return;
        }
        if elems[m].geo.is_arc() && cfg.check.complementary_arc_to_line {
            let mut trial = elems.clone();
            if try_chord(&mut trial, m, s, &cfg) && !runs_backwards(&trial[m], s) {
                *elems = trial;
                self.notes.push(Diagnostic::warning(
                    DiagCode::EquidistantArcBackward,
                    src.n,
                    src.line,
                    0,
                    "the equidistant of the arc runs backwards; arc replaced by a line (R397 d5)",
                ));
                return;
            }
        }
        if !cfg.check.check {
            return;
        }
        if cfg.check.warn {
            self.notes.push(backward_warning(&src));
        }
        self.remove_loop(m);
    }

    /// Element `m` runs backwards and no arc could fix it: the 4-block optimisation (this and
    /// the previous element both loop: join `m - 2` and `m + 1` directly), else the 3-block
    /// one (join `m - 1` and `m + 1`), else it stays backward (R397 d3, d4).
    fn remove_loop(&mut self, m: usize) {
        let cfg = self.cfg;
        let run = self.run.as_mut().expect("running");
        let s = run.offset_mm;
        let elems = &mut run.elems;
        let src = elems[m].src;
        if cfg.check.optimise_4_blocks
            && m >= 2
            && elems[m - 1].state == Equidistant::Backward
            && elems[m - 2].is_regular()
            && !elems[m - 2].is_collapsed()
            && elems[m - 1].corner.is_none()
            && bypass(elems, m - 2, m + 1, s)
        {
            let msg = format!(
                "blocks {} and {}: equidistant loop removed by the 4-block optimisation (R397 d4)",
                name(&elems[m - 1].src),
                name(&src)
            );
            self.notes.push(Diagnostic::info(
                DiagCode::LoopRemoved4Blocks,
                src.n,
                src.line,
                0,
                msg,
            ));
            return;
        }
        if cfg.check.optimise_3_blocks
            && !elems[m - 1].is_collapsed()
            && bypass(elems, m - 1, m + 1, s)
        {
            self.notes.push(Diagnostic::info(
                DiagCode::LoopRemoved3Blocks,
                src.n,
                src.line,
                0,
                "equidistant loop removed by the 3-block optimisation (R397 d3)",
            ));
            return;
        }
        elems[m].state = Equidistant::Backward;
    }

    /// R764: the last working block before a rapid, shorter than the limit, whose
    /// equidistant would run backwards, ends where it starts (SPEC §4.5).
    pub(super) fn exit_optimisation(&mut self, e: &mut Elem, s: f64) {
        let rule = self.cfg.exit;
        if !(rule.report || rule.optimise) {
            return;
        }
        if e.geo.length_mm() >= rule.percent / 100.0 * s.abs() || !runs_backwards(e, s) {
            return;
        }
        let b = e.src;
        if rule.optimise {
            e.end = e.start;
            e.state = Equidistant::Collapsed;
            if rule.report {
                self.notes.push(Diagnostic::info(
                    DiagCode::ExitOptimised,
                    b.n,
                    b.line,
                    0,
                    "exit from the contour optimised, the backward move is left out (R764)",
                ));
            }
        } else {
            self.notes.push(Diagnostic::warning(
                DiagCode::ExitBackward,
                b.n,
                b.line,
                0,
                "on the exit from the contour the tool centre moves backwards (R764)",
            ));
        }
    }
}

/// Replaces the arc at `i` by its chord and resolves its junctions again (R397 d5, d8).
/// On failure `elems` may be partly changed: callers work on a copy.
pub(super) fn try_chord(elems: &mut VecDeque<Elem>, i: usize, s: f64, cfg: &CompConfig) -> bool {
    if i >= elems.len() || !elems[i].geo.is_arc() || !elems[i].is_regular() {
        return false;
    }
    // A full circle has no chord.
    if elems[i].geo.start().dist(elems[i].geo.end()) <= EPS_MM {
        return false;
    }
    elems[i].geo = elems[i].geo.chord();
    elems[i].shape = Shape::Chord;
    for j in [i, i + 1] {
        if j == 0 || j >= elems.len() {
            continue;
        }
        match join(&elems[j - 1], &elems[j], s, cfg) {
            Ok(res) => apply_join(elems, j, res),
            Err(NoIntersection) => return false,
        }
    }
    true
}

/// The R397 warning: the equidistant of `src` runs backwards (SPEC §4.5).
fn backward_warning(src: &Block) -> Diagnostic {
    Diagnostic::warning(
        DiagCode::EquidistantBackward,
        src.n,
        src.line,
        0,
        format!(
            "Chyba v zadání ekvidistanty pro poloměrové korekce v bloku {}: error in the equidistant of block {}: the tool centre would run backwards (the tool is too large for this detail)",
            name(src),
            name(src)
        ),
    )
}

/// Sweep from angle `from` to angle `to` (rad) in the direction of `like` (its sign), in
/// (0, 2π] for a positive direction.
fn sweep_like(from: f64, to: f64, like: f64) -> f64 {
    let mut sw = wrap_pi(to - from);
    if like > 0.0 && sw < 0.0 {
        sw += 2.0 * PI;
    } else if like < 0.0 && sw > 0.0 {
        sw -= 2.0 * PI;
    }
    sw
}

/// Element `m` runs backwards and an arc is inserted at one of its ends (a short step between
/// an inside and an outside corner). Its equidistant is dropped and the inserted arc is cut
/// against the equidistant on the other side of the step: the previous element when the arc
/// is at `m`'s end, the next one when it is at `m`'s start. The tool centre then goes straight
/// from that equidistant onto the arc, which stays at the tool radius from the corner, instead
/// of running back along the step (docs/compensation.md, decision 18). `false` (nothing
/// changed) when the arc and the equidistant do not meet within the arc, or the trimmed
/// neighbour would run backwards itself.
fn trim_at_corner_arc(elems: &mut VecDeque<Elem>, m: usize, s: f64) -> bool {
    match (elems[m].corner, elems[m + 1].corner) {
        (None, Some(c)) if !elems[m - 1].is_collapsed() => trim_before_arc(elems, m, c, s),
        (Some(c), None) => trim_after_arc(elems, m, c, s),
        _ => false,
    }
}

/// The arc `c` at the end of `m`: the previous equidistant is trimmed against it.
fn trim_before_arc(elems: &mut VecDeque<Elem>, m: usize, c: CornerArc, s: f64) -> bool {
    let circle = geom::Support::Circle {
        c: c.corner,
        r: s.abs(),
    };
    let Some(x) = intersect(&elems[m - 1].geo.support(s), &circle, elems[m].start) else {
        return false;
    };
    let sw = sweep_like(
        (x - c.corner).angle(),
        (c.to - c.corner).angle(),
        c.sweep_rad,
    );
    let mut trial = elems[m - 1].clone();
    trial.end = x;
    if sw.abs() > c.sweep_rad.abs() + 1e-9 || runs_backwards(&trial, s) {
        return false;
    }
    elems[m - 1].end = x;
    elems[m].collapse_at(x);
    if let Some(cc) = elems[m + 1].corner.as_mut() {
        cc.sweep_rad = sw;
    }
    true
}

/// The arc `c` at the start of `m`: it now ends on the next equidistant.
fn trim_after_arc(elems: &mut VecDeque<Elem>, m: usize, c: CornerArc, s: f64) -> bool {
    let circle = geom::Support::Circle {
        c: c.corner,
        r: s.abs(),
    };
    let Some(x) = intersect(&circle, &elems[m + 1].geo.support(s), elems[m].end) else {
        return false;
    };
    let from = (elems[m - 1].end - c.corner).angle();
    let sw = sweep_like(from, (x - c.corner).angle(), c.sweep_rad);
    let mut trial = elems[m + 1].clone();
    trial.start = x;
    if !trial.is_closed() {
        trial.end = trial.geo.offset_end(s);
    }
    if sw.abs() > c.sweep_rad.abs() + 1e-9 || runs_backwards(&trial, s) {
        return false;
    }
    elems[m].collapse_at(x);
    elems[m].corner = Some(CornerArc {
        to: x,
        sweep_rad: sw,
        ..c
    });
    elems[m + 1].start = x;
    true
}

/// The 3-block (`first + 2 == last`) and 4-block (`first + 3 == last`) optimisation: the
/// equidistants of `first` and `last` are intersected directly and the elements between them
/// collapse onto that point, which removes their backward loop. Applied only when the point
/// exists and the shortened `first` still runs forwards.
fn bypass(elems: &mut VecDeque<Elem>, first: usize, last: usize, s: f64) -> bool {
    let near = (elems[first + 1].start + elems[last - 1].end) * 0.5;
    let Some(x) = intersect(
        &elems[first].geo.support(s),
        &elems[last].geo.support(s),
        near,
    ) else {
        return false;
    };
    let mut trial = elems[first].clone();
    trial.end = x;
    if runs_backwards(&trial, s) || elems[last].corner.is_some() {
        return false;
    }
    elems[first].end = x;
    for e in elems.range_mut(first + 1..last) {
        e.collapse_at(x);
    }
    elems[last].start = x;
    elems[last].far = None;
    true
}
