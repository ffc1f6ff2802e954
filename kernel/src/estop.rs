//! Fault reaction of the axes (issue #15): when any axis faults, every other axis stops on its
//! own, as fast as its stop deceleration allows.
//!
//! Braking along the path (the feed-hold reaction) assumes every axis still follows its
//! setpoint. After a fault one axis does not (a faulted drive freezes, coasts or is lost), so
//! the healthy axes braking along the path for the path's (slower) stop time run on alone and
//! pull the tool off the programmed path. Stopping every healthy axis independently at its own
//! stop deceleration ends the motion soonest, which keeps that deviation to the distance the
//! axes need to stop (their following error plus v²/2a).
//!
//! Setpoints stay continuous: each axis starts from its last setpoint with the speed of its
//! last two setpoints and loses at most `decel·Ts` of speed per tick (finite differences of
//! the setpoints are within the limit).
//!
//! Pure and allocation-free: the real-time thread owns one and ticks it.

use crate::plan::SegPath;
use crate::units::{AxesMm, MAX_AXES, TS_S};

/// Independent per-axis braking to rest after a fault, and the deviation it causes.
#[derive(Clone, Copy, Debug)]
pub struct AxisBrake {
    axes: usize,
    decel_mm_s2: [f64; MAX_AXES],
    pos: AxesMm,
    v_mm_s: [f64; MAX_AXES],
    active: bool,
    /// The programmed path the tool was on when the fault came.
    path: Option<SegPath>,
    deviation_mm: f64,
}

impl AxisBrake {
    /// `decel_mm_s2[i]`: stop deceleration of axis `i` (`> 0`).
    pub fn new(axes: usize, decel_mm_s2: [f64; MAX_AXES]) -> Self {
        AxisBrake {
            axes: axes.min(MAX_AXES),
            decel_mm_s2,
            pos: AxesMm::ZERO,
            v_mm_s: [0.0; MAX_AXES],
            active: false,
            path: None,
            deviation_mm: 0.0,
        }
    }

    /// Starts braking from the last two setpoints (`prev` one tick before `now`). `path`: the
    /// programmed path the commanded position was on (for the deviation), if moving.
    pub fn start(&mut self, prev: &AxesMm, now: &AxesMm, path: Option<SegPath>) {
        self.pos = *now;
        for i in 0..self.axes {
            self.v_mm_s[i] = (now[i] - prev[i]) / TS_S;
        }
        self.active = true;
        self.path = path;
        self.deviation_mm = 0.0;
    }

    /// A faulted axis does not follow setpoints: its setpoint stays where it is (`at_mm`, its
    /// actual position), so a later re-enable does not make it jump.
    pub fn hold_axis(&mut self, axis: usize, at_mm: f64) {
        if axis < self.axes {
            self.pos[axis] = at_mm;
            self.v_mm_s[axis] = 0.0;
        }
    }

    /// Braking is under way (or done and holding) since the last [`AxisBrake::start`].
    pub fn active(&self) -> bool {
        self.active
    }

    /// Ends the fault reaction (after a reset).
    pub fn clear(&mut self) {
        self.active = false;
    }

    /// Every axis's setpoint is at rest.
    pub fn at_rest(&self) -> bool {
        self.v_mm_s[..self.axes].iter().all(|&v| v == 0.0)
    }

    /// Setpoints of the next tick: each axis slows down by its own deceleration.
    pub fn tick(&mut self) -> AxesMm {
        for i in 0..self.axes {
            let v = self.v_mm_s[i];
            let dv = self.decel_mm_s2[i] * TS_S;
            let next = if v > 0.0 {
                (v - dv).max(0.0)
            } else {
                (v + dv).min(0.0)
            };
            self.v_mm_s[i] = next;
            self.pos[i] += next * TS_S;
        }
        self.pos
    }

    /// Takes the drives' actual positions of this tick into the deviation measure.
    pub fn observe(&mut self, actual: &AxesMm) {
        if let Some(path) = &self.path {
            let d = distance_to_path(path, actual, self.axes);
            if d > self.deviation_mm {
                self.deviation_mm = d;
            }
        }
    }

    /// Largest distance of the actual tool position from the programmed path since the fault,
    /// mm (0 when the machine was not moving).
    pub fn deviation_mm(&self) -> f64 {
        self.deviation_mm
    }
}

/// Distance of `p` from the programmed path: from the line through a linear segment (the tool
/// lags behind its setpoint, so it may still be on the line before the segment's start), or
/// from the circle of an arc (with the axes outside its plane compared with the straight
/// motion between its end points).
pub fn distance_to_path(path: &SegPath, p: &AxesMm, axes: usize) -> f64 {
    match *path {
        SegPath::Line { start, end } => {
            let d = end - start;
            let len2: f64 = (0..axes).map(|i| d[i] * d[i]).sum();
            let rel = *p - start;
            if len2 <= 0.0 {
                return rel.norm(axes);
            }
            let t: f64 = (0..axes).map(|i| rel[i] * d[i]).sum::<f64>() / len2;
            (0..axes)
                .map(|i| {
                    let e = rel[i] - t * d[i];
                    e * e
                })
                .sum::<f64>()
                .sqrt()
        }
        SegPath::Arc {
            center,
            plane,
            radius_mm,
            ..
        } => {
            let (a, b) = plane.axes();
            ((p[a] - center[a]).hypot(p[b] - center[b]) - radius_mm).abs()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pt(x: f64, y: f64) -> AxesMm {
        let mut v = AxesMm::ZERO;
        v[0] = x;
        v[1] = y;
        v
    }

    #[test]
    fn each_axis_brakes_at_its_own_rate_to_rest() {
        let mut decel = [0.0; MAX_AXES];
        decel[0] = 1000.0;
        decel[1] = 250.0;
        let mut b = AxisBrake::new(2, decel);
        // X at 100 mm/s, Y at -20 mm/s.
        b.start(&pt(0.0, 0.0), &pt(0.4, -0.08), None);
        let mut prev = pt(0.4, -0.08);
        let mut v_prev = [100.0, -20.0];
        let mut ticks = 0;
        while !b.at_rest() {
            let p = b.tick();
            for i in 0..2 {
                let v = (p[i] - prev[i]) / TS_S;
                assert!((v - v_prev[i]).abs() <= decel[i] * TS_S + 1e-9, "axis {i}");
                assert!(v * v_prev[i] >= 0.0, "axis {i} reversed");
                v_prev[i] = v;
            }
            prev = p;
            ticks += 1;
            assert!(ticks < 1000);
        }
        // X needs 0.1 s, Y 0.08 s: the slower one decides, each on its own.
        assert_eq!(ticks, 25);
        // Braking distances v²/2a (discrete: within one tick of travel).
        assert!((prev[0] - 0.4 - 5.0).abs() < 100.0 * TS_S);
        assert!((prev[1] + 0.08 + 0.8).abs() < 20.0 * TS_S);
    }

    #[test]
    fn a_held_axis_stays_and_deviation_is_measured_from_the_line() {
        let mut b = AxisBrake::new(2, [500.0; MAX_AXES]);
        let line = SegPath::Line {
            start: pt(0.0, 0.0),
            end: pt(100.0, 0.0),
        };
        b.start(&pt(9.0, 0.0), &pt(10.0, 0.0), Some(line));
        b.hold_axis(0, 7.5);
        assert_eq!(b.tick()[0], 7.5);
        b.observe(&pt(50.0, 0.0));
        assert_eq!(b.deviation_mm(), 0.0);
        b.observe(&pt(-5.0, 3.0));
        assert_eq!(b.deviation_mm(), 3.0, "the line extends before its start");
        b.observe(&pt(5.0, -1.0));
        assert_eq!(b.deviation_mm(), 3.0, "the largest is kept");
    }
}
