//! Units and small geometric value types shared across the kernel.
//!
//! Lengths are millimetres (degrees for rotary axes), times seconds, unless a name says otherwise
//! (`feed_mm_min`, `accel_mm_s2`). Positions of all axes travel together as [`AxesMm`].

use std::ops::{Add, Index, IndexMut, Mul, Sub};

/// Most axes a machine can have (SPEC §3: offsets exist for axes 1..4, the controller knows 6).
pub const MAX_AXES: usize = 6;

/// Interpolation period Ts in seconds (SPEC §7: 4 ms).
pub const TS_S: f64 = 0.004;

/// Interpolation period Ts in nanoseconds.
pub const TS_NS: u64 = 4_000_000;

/// One value per machine axis, in millimetres (degrees for rotary axes), in machine axis order.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AxesMm(pub [f64; MAX_AXES]);

impl AxesMm {
    pub const ZERO: AxesMm = AxesMm([0.0; MAX_AXES]);

    /// Euclidean length over the first `n` axes.
    pub fn norm(&self, n: usize) -> f64 {
        self.0[..n].iter().map(|v| v * v).sum::<f64>().sqrt()
    }

    /// Largest absolute component over the first `n` axes.
    pub fn max_abs(&self, n: usize) -> f64 {
        self.0[..n].iter().fold(0.0, |m, v| m.max(v.abs()))
    }

    /// The absolute value of every component.
    pub fn abs(mut self) -> AxesMm {
        for a in self.0.iter_mut() {
            *a = a.abs();
        }
        self
    }

    /// Linear interpolation `self + (other - self) * t`.
    pub fn lerp(&self, other: &AxesMm, t: f64) -> AxesMm {
        let mut out = *self;
        for (o, (a, b)) in out.0.iter_mut().zip(self.0.iter().zip(other.0.iter())) {
            *o = a + (b - a) * t;
        }
        out
    }
}

impl Index<usize> for AxesMm {
    type Output = f64;
    fn index(&self, i: usize) -> &f64 {
        &self.0[i]
    }
}

impl IndexMut<usize> for AxesMm {
    fn index_mut(&mut self, i: usize) -> &mut f64 {
        &mut self.0[i]
    }
}

impl Add for AxesMm {
    type Output = AxesMm;
    fn add(mut self, rhs: AxesMm) -> AxesMm {
        for (a, b) in self.0.iter_mut().zip(rhs.0) {
            *a += b;
        }
        self
    }
}

impl Sub for AxesMm {
    type Output = AxesMm;
    fn sub(mut self, rhs: AxesMm) -> AxesMm {
        for (a, b) in self.0.iter_mut().zip(rhs.0) {
            *a -= b;
        }
        self
    }
}

impl Mul<f64> for AxesMm {
    type Output = AxesMm;
    fn mul(mut self, k: f64) -> AxesMm {
        for a in self.0.iter_mut() {
            *a *= k;
        }
        self
    }
}

/// Converts a feed in mm/min to mm/s.
pub fn mm_min_to_mm_s(feed_mm_min: f64) -> f64 {
    feed_mm_min / 60.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lerp_and_norm() {
        let a = AxesMm([0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        let b = AxesMm([3.0, 4.0, 0.0, 0.0, 0.0, 0.0]);
        assert_eq!(a.lerp(&b, 0.5).0[..2], [1.5, 2.0]);
        assert_eq!((b - a).norm(3), 5.0);
        assert_eq!((b * 2.0).max_abs(3), 8.0);
    }
}
