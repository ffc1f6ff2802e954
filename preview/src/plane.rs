//! The plane of the picture (SPEC §7.5 via the manual's ROVINA: X-Y, X-Z, Y-Z) and the
//! projection of lines and arcs onto it.

use kernel::AxesMm;
use kernel::block::{Block, Path};
use kernel::plan::SegPath;
use kernel::{DiagCode, Diagnostic};

/// Plane of the preview: horizontal axis first.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ViewPlane {
    #[default]
    Xy,
    Xz,
    Yz,
}

impl ViewPlane {
    /// Axis letters (horizontal, vertical).
    pub fn letters(self) -> (char, char) {
        match self {
            ViewPlane::Xy => ('X', 'Y'),
            ViewPlane::Xz => ('X', 'Z'),
            ViewPlane::Yz => ('Y', 'Z'),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            ViewPlane::Xy => "XY",
            ViewPlane::Xz => "XZ",
            ViewPlane::Yz => "YZ",
        }
    }

    /// Parses `xy`, `XZ`, `yz` ... (for the CLI's `--plane`).
    pub fn parse(s: &str) -> Option<ViewPlane> {
        match s.to_ascii_uppercase().as_str() {
            "XY" => Some(ViewPlane::Xy),
            "XZ" => Some(ViewPlane::Xz),
            "YZ" => Some(ViewPlane::Yz),
            _ => None,
        }
    }
}

/// Axis indices of a view plane on a machine with the given axis letters (R0..R5 order).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Projection {
    pub h: usize,
    pub v: usize,
}

impl Projection {
    pub fn new(plane: ViewPlane, axis_names: &[char]) -> Result<Self, Diagnostic> {
        let (h, v) = plane.letters();
        let find = |c: char| {
            axis_names.iter().position(|&a| a == c).ok_or_else(|| {
                Diagnostic::error(
                    DiagCode::PreviewAxisMissing,
                    None,
                    0,
                    0,
                    format!(
                        "preview plane {} needs axis {c}, the machine has {}",
                        plane.name(),
                        axis_names.iter().collect::<String>()
                    ),
                )
            })
        };
        Ok(Projection {
            h: find(h)?,
            v: find(v)?,
        })
    }

    pub fn point(&self, p: &AxesMm) -> [f64; 2] {
        [p[self.h], p[self.v]]
    }

    /// Points after the start of `path` projected on the plane, flattened so that no chord
    /// deviates from an arc by more than `tol_mm` (at most [`MAX_ARC_POINTS`]).
    pub fn flatten(&self, path: &SegPath, tol_mm: f64, out: &mut Vec<[f64; 2]>) {
        out.clear();
        match *path {
            SegPath::Line { end, .. } => out.push(self.point(&end)),
            SegPath::Arc {
                radius_mm,
                sweep_rad,
                end,
                ..
            } => {
                let n = arc_points(radius_mm, sweep_rad, tol_mm);
                for k in 1..n {
                    out.push(self.point(&path.point_at(k as f64 / n as f64)));
                }
                out.push(self.point(&end));
            }
        }
    }
}

/// Most chords per arc (a full circle of 1024 chords deviates by 5 ppm of its radius).
pub const MAX_ARC_POINTS: usize = 1024;

/// Chords needed so each deviates by at most `tol_mm` from the arc.
pub(crate) fn arc_points(radius_mm: f64, sweep_rad: f64, tol_mm: f64) -> usize {
    if radius_mm.is_nan() || radius_mm <= 0.0 || !sweep_rad.is_finite() {
        return 1;
    }
    // Chord of angle φ deviates r·(1 − cos(φ/2)).
    let c = (1.0 - (tol_mm / radius_mm).min(1.0)).clamp(-1.0, 1.0);
    let phi = (2.0 * c.acos()).max(1e-9);
    ((sweep_rad.abs() / phi).ceil() as usize).clamp(4, MAX_ARC_POINTS)
}

/// The path of a programmed motion block (for G0 too), as the planner would build it.
pub fn block_path(b: &Block) -> Option<(SegPath, bool)> {
    let (start, end, path) = b.motion()?;
    Some(match path {
        Path::Rapid => (SegPath::Line { start, end }, true),
        Path::Line | Path::Probe(_) => (SegPath::Line { start, end }, false),
        Path::Arc { dir, center, plane } => (SegPath::arc(start, end, center, plane, dir), false),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arcs_flatten_within_tolerance() {
        let p = Projection::new(ViewPlane::Xy, &['X', 'Y', 'Z']).unwrap();
        let mut a = AxesMm::ZERO;
        a[0] = 10.0;
        let mut e = AxesMm::ZERO;
        e[1] = 10.0;
        let arc = SegPath::arc(
            a,
            e,
            AxesMm::ZERO,
            kernel::block::Plane::G17,
            kernel::block::ArcDir::Ccw,
        );
        let mut out = Vec::new();
        p.flatten(&arc, 0.01, &mut out);
        assert_eq!(*out.last().unwrap(), [0.0, 10.0]);
        // Every chord midpoint is within the tolerance of the circle.
        let mut prev = [10.0, 0.0];
        for q in &out {
            let m = [(prev[0] + q[0]) / 2.0, (prev[1] + q[1]) / 2.0];
            assert!(10.0 - m[0].hypot(m[1]) <= 0.01 + 1e-12);
            prev = *q;
        }
        assert!(Projection::new(ViewPlane::Yz, &['X', 'Z']).is_err());
        assert_eq!(
            Projection::new(ViewPlane::Xz, &['X', 'Z']).unwrap(),
            Projection { h: 0, v: 1 }
        );
    }
}
