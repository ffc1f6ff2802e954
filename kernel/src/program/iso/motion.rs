//! G0, G1, G2, G3 (helical too; centre as I J K or radius R) and G53, as LinuxCNC 2.9 reads
//! them: a word names the axis's end in program coordinates (G90) or its distance (G91); the
//! block's end is in machine coordinates (program + work offset + G92 + tool length).

use super::Fail;
use super::exec::Exec;
use super::state::MotionMode;
use super::words::{NonModal, Words};
use crate::block::{ArcDir, BlockKind, Feed, Path, Plane};
use crate::diag::DiagCode;
use crate::units::AxesMm;

/// The axis perpendicular to a plane.
pub fn third_axis(p: Plane) -> usize {
    match p {
        Plane::G17 => 2,
        Plane::G18 => 1,
        Plane::G19 => 0,
    }
}

impl Exec<'_> {
    /// A straight move or an arc in the motion mode `mode`.
    pub fn straight_or_arc(&mut self, w: &Words, mode: MotionMode) -> Result<(), Fail> {
        let g53 = matches!(w.non_modal, Some((NonModal::MachineCoords, _)));
        if g53 && !matches!(mode, MotionMode::Rapid | MotionMode::Line) {
            return Err(Fail::new(
                w.first,
                DiagCode::IsoModalConflict,
                "G53 moves only with G0 or G1",
            ));
        }
        if g53 && !self.st.absolute {
            return Err(Fail::new(
                w.first,
                DiagCode::IsoModalConflict,
                "G53 needs G90 (absolute distances)",
            ));
        }
        let start = self.st.machine;
        let end = self.end_point(w, g53);
        match mode {
            MotionMode::Rapid => {
                self.emit(
                    BlockKind::Motion {
                        start,
                        end,
                        path: Path::Rapid,
                    },
                    Feed::default(),
                    [None; 4],
                );
            }
            MotionMode::Line => {
                let feed = self.feed_for(w.first, (end - start).norm(self.m.n_axes))?;
                self.emit(
                    BlockKind::Motion {
                        start,
                        end,
                        path: Path::Line,
                    },
                    feed,
                    [None; 4],
                );
            }
            _ => self.arc(w, mode, start, end)?,
        }
        Ok(())
    }

    /// Where the line's axis words put the tool, machine coordinates. Axes without a word
    /// stay where they are.
    pub fn end_point(&self, w: &Words, g53: bool) -> AxesMm {
        let off = self.st.offset();
        let prog = self.st.program_pos();
        let mut end = self.st.machine;
        for k in 0..self.m.n_axes {
            if let Some((v, _)) = w.axes[k] {
                let v = self.st.mm(v);
                end[k] = if g53 {
                    v
                } else if self.st.absolute {
                    v + off[k]
                } else {
                    prog[k] + v + off[k]
                };
            }
        }
        end
    }

    fn arc(&mut self, w: &Words, mode: MotionMode, start: AxesMm, end: AxesMm) -> Result<(), Fail> {
        if let Some((p, at)) = w.p
            && (p - 1.0).abs() > 1e-9
        {
            return Err(Fail::new(
                at,
                DiagCode::ArcRadiusForm,
                format!("P{p}: cncd runs arcs of one turn at most (P1)"),
            ));
        }
        let plane = self.st.plane;
        let (a, b) = plane.axes();
        let off = self.st.offset();
        let s2 = (start[a] - off[a], start[b] - off[b]);
        let e2 = (end[a] - off[a], end[b] - off[b]);
        let cw = mode == MotionMode::Cw;
        let c2 = match w.r {
            Some((r, at)) => {
                if [w.i, w.j, w.k].iter().any(Option::is_some) {
                    return Err(Fail::new(
                        at,
                        DiagCode::ArcRadiusForm,
                        "an arc is written with R or with I J K, not both",
                    ));
                }
                radius_form_centre(s2, e2, self.st.mm(r), cw)
                    .map_err(|m| Fail::new(at, DiagCode::ArcRadiusForm, m))?
            }
            None => self.centre_words(w, s2, (a, b))?,
        };
        let (rs, re) = super::super::arc::radii(s2, e2, c2);
        if rs < 1e-9 || re < 1e-9 {
            return Err(Fail::new(
                w.first,
                DiagCode::ArcRadiusZero,
                "the arc radius is zero",
            ));
        }
        let tol = self.m.arc_tolerance_mm.max(1e-6);
        if (rs - re).abs() > tol {
            return Err(Fail::new(
                w.first,
                DiagCode::ArcEndOffCircle,
                format!(
                    "the arc end point is not on the circle: start radius {rs:.4} mm, end radius {re:.4} mm, more than R55 = {tol:.4} mm apart"
                ),
            ));
        }
        let mut center = start;
        center[a] = c2.0 + off[a];
        center[b] = c2.1 + off[b];
        let length = helix_length_mm(
            s2,
            e2,
            c2,
            cw,
            end[third_axis(plane)] - start[third_axis(plane)],
        );
        let feed = self.feed_for(w.first, length)?;
        let dir = if cw { ArcDir::Cw } else { ArcDir::Ccw };
        self.emit(
            BlockKind::Motion {
                start,
                end,
                path: Path::Arc { dir, center, plane },
            },
            feed,
            [None; 4],
        );
        Ok(())
    }

    /// The centre from I J K (the words of the plane's two axes; a missing one is 0).
    fn centre_words(
        &self,
        w: &Words,
        s2: (f64, f64),
        (a, b): (usize, usize),
    ) -> Result<(f64, f64), Fail> {
        let words = [w.i, w.j, w.k];
        let (wa, wb) = (words[a], words[b]);
        if wa.is_none() && wb.is_none() {
            return Err(Fail::new(
                w.first,
                DiagCode::ArcNeedsCentre,
                "an arc needs its centre (I J K of the plane's axes) or R",
            ));
        }
        let (i, j) = (
            self.st.mm(wa.map_or(0.0, |x| x.0)),
            self.st.mm(wb.map_or(0.0, |x| x.0)),
        );
        Ok(if self.st.arc_absolute {
            (i, j)
        } else {
            (s2.0 + i, s2.1 + j)
        })
    }
}

/// The centre of an arc written with its radius (LinuxCNC: negative R, more than a half
/// circle; an end farther than 2·|R| is an error).
pub fn radius_form_centre(
    s: (f64, f64),
    e: (f64, f64),
    r: f64,
    cw: bool,
) -> Result<(f64, f64), String> {
    if s == e {
        return Err("an arc written with R cannot end where it starts".into());
    }
    let abs_r = r.abs();
    let mid = ((e.0 + s.0) / 2.0, (e.1 + s.1) / 2.0);
    let mut half = (mid.0 - e.0).hypot(mid.1 - e.1);
    if half - abs_r > 1e-6 || abs_r == 0.0 {
        return Err(format!(
            "R{r}: the radius is too small to reach the end point"
        ));
    }
    if half / abs_r > 1.0 - 1e-12 {
        half = abs_r;
    }
    let chord = (e.1 - s.1).atan2(e.0 - s.0);
    let theta = if cw == (r > 0.0) {
        chord - std::f64::consts::FRAC_PI_2
    } else {
        chord + std::f64::consts::FRAC_PI_2
    };
    let offset = abs_r * (half / abs_r).asin().cos();
    Ok((mid.0 + offset * theta.cos(), mid.1 + offset * theta.sin()))
}

/// Length of a helix: the arc from `s` to `e` about `c` (full circle when they meet) and a
/// linear part `dz`.
pub fn helix_length_mm(s: (f64, f64), e: (f64, f64), c: (f64, f64), cw: bool, dz: f64) -> f64 {
    let a0 = (s.1 - c.1).atan2(s.0 - c.0);
    let a1 = (e.1 - c.1).atan2(e.0 - c.0);
    let tau = std::f64::consts::TAU;
    let mut sweep = if cw { a0 - a1 } else { a1 - a0 };
    sweep = sweep.rem_euclid(tau);
    if sweep < 1e-12 {
        sweep = tau;
    }
    let r = (s.0 - c.0).hypot(s.1 - c.1);
    (r * sweep).hypot(dz)
}
