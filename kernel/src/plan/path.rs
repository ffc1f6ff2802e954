//! Geometry of planned segments: lines and arcs (helices) evaluated by path fraction.

use crate::block::{ArcDir, Plane};
use crate::units::AxesMm;

/// Geometry of a planned segment, evaluated by arc length.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SegPath {
    Line {
        start: AxesMm,
        end: AxesMm,
    },
    /// Circular arc in `plane` (helix when other axes move).
    Arc {
        start: AxesMm,
        end: AxesMm,
        center: AxesMm,
        plane: Plane,
        radius_mm: f64,
        /// Angle of `start` about `center`, radians.
        start_angle_rad: f64,
        /// Signed sweep, radians (positive counter-clockwise).
        sweep_rad: f64,
    },
}

impl Default for SegPath {
    fn default() -> Self {
        SegPath::Line {
            start: AxesMm::ZERO,
            end: AxesMm::ZERO,
        }
    }
}

impl SegPath {
    /// Builds an arc from start, end and centre. The sweep is taken in `dir`; a full circle
    /// when start and end coincide.
    pub fn arc(start: AxesMm, end: AxesMm, center: AxesMm, plane: Plane, dir: ArcDir) -> SegPath {
        let (a, b) = plane.axes();
        let a0 = (start[b] - center[b]).atan2(start[a] - center[a]);
        let a1 = (end[b] - center[b]).atan2(end[a] - center[a]);
        let radius_mm = (start[a] - center[a]).hypot(start[b] - center[b]);
        let tau = std::f64::consts::TAU;
        let mut sweep = a1 - a0;
        match dir {
            ArcDir::Ccw => {
                while sweep <= 1e-12 {
                    sweep += tau;
                }
            }
            ArcDir::Cw => {
                while sweep >= -1e-12 {
                    sweep -= tau;
                }
            }
        }
        SegPath::Arc {
            start,
            end,
            center,
            plane,
            radius_mm,
            start_angle_rad: a0,
            sweep_rad: sweep,
        }
    }

    pub fn start(&self) -> AxesMm {
        match *self {
            SegPath::Line { start, .. } | SegPath::Arc { start, .. } => start,
        }
    }

    pub fn end(&self) -> AxesMm {
        match *self {
            SegPath::Line { end, .. } | SegPath::Arc { end, .. } => end,
        }
    }

    /// Path length over the first `axes` axes.
    pub fn length(&self, axes: usize) -> f64 {
        match *self {
            SegPath::Line { start, end } => (end - start).norm(axes),
            SegPath::Arc {
                start,
                end,
                plane,
                radius_mm,
                sweep_rad,
                ..
            } => {
                let (a, b) = plane.axes();
                let mut off = end - start;
                off[a] = 0.0;
                off[b] = 0.0;
                (radius_mm * sweep_rad).hypot(off.norm(axes))
            }
        }
    }

    /// Point at fraction `t` in 0..=1 of the path. `t = 1` gives the end point exactly.
    pub fn point_at(&self, t: f64) -> AxesMm {
        if t >= 1.0 {
            return self.end();
        }
        match *self {
            SegPath::Line { start, end } => start.lerp(&end, t),
            SegPath::Arc {
                start,
                end,
                center,
                plane,
                radius_mm,
                start_angle_rad,
                sweep_rad,
            } => {
                let (a, b) = plane.axes();
                let mut p = start.lerp(&end, t);
                let ang = start_angle_rad + sweep_rad * t;
                p[a] = center[a] + radius_mm * ang.cos();
                p[b] = center[b] + radius_mm * ang.sin();
                p
            }
        }
    }

    /// Unit tangent (per axis) at fraction `t`, over the first `axes` axes.
    pub fn tangent_at(&self, t: f64, axes: usize) -> AxesMm {
        let d = match *self {
            SegPath::Line { start, end } => end - start,
            SegPath::Arc {
                start,
                end,
                plane,
                radius_mm,
                start_angle_rad,
                sweep_rad,
                ..
            } => {
                let (a, b) = plane.axes();
                let mut d = end - start;
                let ang = start_angle_rad + sweep_rad * t;
                d[a] = -radius_mm * sweep_rad * ang.sin();
                d[b] = radius_mm * sweep_rad * ang.cos();
                d
            }
        };
        let n = d.norm(axes);
        if n > 0.0 { d * (1.0 / n) } else { d }
    }
}

impl SegPath {
    /// Curvature of the path in its plane, 1/mm (0 for lines).
    pub fn curvature_per_mm(&self) -> f64 {
        match *self {
            SegPath::Line { .. } => 0.0,
            SegPath::Arc { radius_mm, .. } => {
                if radius_mm > 0.0 {
                    1.0 / radius_mm
                } else {
                    0.0
                }
            }
        }
    }
}
