//! The simulated machine's probe and what it touches (docs/setup.md, "Probing"): a
//! workpiece (a box with a bore through it) and a tool setter beside it, in machine
//! coordinates. The probe reads 1 while its ball, at the tool tip, touches one of them.
//!
//! The tool tip is the carriage's position with the simulated tool's length taken off Z; the
//! ball's centre sits a ball radius above the tip, so a tool coming down touches a top face
//! with its tip. Touching is sampled when the inputs are read, once per bus period, as a real
//! probe wired to an input is.

/// An axis-aligned box, machine coordinates, mm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimBox {
    pub min_mm: [f64; 3],
    pub max_mm: [f64; 3],
}

/// A vertical cylinder: a bore cut through the workpiece, or the tool setter's body (its top
/// face at `top_mm`, going down without end).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimCylinder {
    pub x_mm: f64,
    pub y_mm: f64,
    pub radius_mm: f64,
    pub top_mm: f64,
}

/// The simulated probe and the solids it can touch.
#[derive(Clone, Debug, PartialEq)]
pub struct SimProbe {
    /// Indices of the X, Y and Z axes (none: the machine lacks that axis; it stays at 0).
    pub axes: [Option<usize>; 3],
    /// The tool's length below the carriage's Z, mm.
    pub tool_length_mm: f64,
    /// The probe ball's radius, mm (0: a point, a tool's tip).
    pub ball_radius_mm: f64,
    pub workpiece: Option<SimBox>,
    /// Bores through the workpiece.
    pub bores: Vec<SimCylinder>,
    pub setter: Option<SimCylinder>,
}

impl SimProbe {
    /// Whether the ball touches a solid with the axes at `positions_mm`.
    pub fn touches(&self, positions_mm: &[f64]) -> bool {
        let at = |k: usize| {
            self.axes[k]
                .and_then(|a| positions_mm.get(a))
                .copied()
                .unwrap_or(0.0)
        };
        let r = self.ball_radius_mm;
        // The ball's centre: a radius above the tool's tip.
        let c = [at(0), at(1), at(2) - self.tool_length_mm + r];
        self.workpiece
            .is_some_and(|b| self.touches_workpiece(&b, c, r))
            || self.setter.is_some_and(|s| touches_cylinder(&s, c, r))
    }

    fn touches_workpiece(&self, b: &SimBox, c: [f64; 3], r: f64) -> bool {
        if distance_to_box(b, c) > r {
            return false;
        }
        // Within a bore (through the workpiece) clear of its wall the ball touches nothing;
        // near the rim the top face counts as touched (the rim's edge is not modelled).
        !self
            .bores
            .iter()
            .any(|h| (c[0] - h.x_mm).hypot(c[1] - h.y_mm) < h.radius_mm - r)
    }
}

fn distance_to_box(b: &SimBox, c: [f64; 3]) -> f64 {
    let d2: f64 = (0..3)
        .map(|k| (c[k] - c[k].clamp(b.min_mm[k], b.max_mm[k])).powi(2))
        .sum();
    d2.sqrt()
}

fn touches_cylinder(s: &SimCylinder, c: [f64; 3], r: f64) -> bool {
    let d_xy = ((c[0] - s.x_mm).hypot(c[1] - s.y_mm) - s.radius_mm).max(0.0);
    let d_z = (c[2] - s.top_mm).max(0.0);
    d_xy.hypot(d_z) <= r
}

#[cfg(test)]
mod tests {
    use super::*;

    fn probe(tool_length_mm: f64, ball_radius_mm: f64) -> SimProbe {
        SimProbe {
            axes: [Some(0), Some(1), Some(2)],
            tool_length_mm,
            ball_radius_mm,
            workpiece: Some(SimBox {
                min_mm: [0.0, 0.0, -60.0],
                max_mm: [100.0, 100.0, -10.0],
            }),
            bores: vec![SimCylinder {
                x_mm: 50.0,
                y_mm: 50.0,
                radius_mm: 10.0,
                top_mm: -10.0,
            }],
            setter: Some(SimCylinder {
                x_mm: -40.0,
                y_mm: 50.0,
                radius_mm: 10.0,
                top_mm: -20.0,
            }),
        }
    }

    #[test]
    fn the_tip_touches_the_top_face() {
        let p = probe(30.0, 2.0);
        assert!(!p.touches(&[20.0, 20.0, 20.001]));
        assert!(p.touches(&[20.0, 20.0, 20.0]));
        // The setter's top at -20: a tip 30 below the carriage.
        assert!(!p.touches(&[-40.0, 50.0, 10.001]));
        assert!(p.touches(&[-40.0, 50.0, 10.0]));
    }

    #[test]
    fn the_ball_touches_a_side_face_at_its_radius() {
        let p = probe(0.0, 2.0);
        assert!(!p.touches(&[-2.001, 50.0, -20.0]));
        assert!(p.touches(&[-2.0, 50.0, -20.0]));
    }

    #[test]
    fn inside_the_bore_the_wall_is_touched_at_its_radius_less_the_ball() {
        let p = probe(0.0, 2.0);
        assert!(!p.touches(&[50.0, 50.0, -20.0]));
        assert!(!p.touches(&[57.999, 50.0, -20.0]));
        assert!(p.touches(&[58.0, 50.0, -20.0]));
        assert!(p.touches(&[50.0, 41.9, -20.0]));
        // Over the bore's opening nothing is touched.
        assert!(!p.touches(&[50.0, 50.0, -10.0]));
    }
}
