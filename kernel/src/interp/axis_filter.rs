//! Stage 3, axis smoothing filter (parabolic profile only): the setpoints are the on-path
//! positions averaged twice over the last `n` ticks, spreading a turn of direction over 2n ticks.

use super::{AXIS_FILTER_MAX_TICKS, Interpolator};
use crate::units::AxesMm;

impl Interpolator {
    pub(super) fn axis_settled(&self) -> bool {
        if self.axis_window_ticks <= 1 {
            return true;
        }
        let p = self.path_pos;
        (0..self.axis_window_ticks).all(|j| {
            let i = (self.axis_newest + AXIS_FILTER_MAX_TICKS - j) % AXIS_FILTER_MAX_TICKS;
            self.axis_hist_in[i] == p && self.axis_hist_mid[i] == p
        })
    }

    /// Mean of the last `n` entries of `ring` ending at `pos`, as the newest entry plus the
    /// mean offset from it (exact when all entries are equal).
    pub(super) fn ring_mean(ring: &[AxesMm], pos: usize, n: usize, axes: usize) -> AxesMm {
        let newest = ring[pos];
        let mut sum = AxesMm::ZERO;
        for j in 1..n {
            let e = &ring[(pos + AXIS_FILTER_MAX_TICKS - j) % AXIS_FILTER_MAX_TICKS];
            for a in 0..axes {
                sum.0[a] += e.0[a] - newest.0[a];
            }
        }
        let mut out = newest;
        for a in 0..axes {
            out.0[a] += sum.0[a] / n as f64;
        }
        out
    }

    /// Axis filter stage: the setpoint is the double moving average of the path positions.
    pub(super) fn smooth_axes(&mut self) {
        if self.axis_window_ticks <= 1 {
            self.position = self.path_pos;
            return;
        }
        self.axis_newest = (self.axis_newest + 1) % AXIS_FILTER_MAX_TICKS;
        self.axis_hist_in[self.axis_newest] = self.path_pos;
        let mid = Self::ring_mean(
            &self.axis_hist_in,
            self.axis_newest,
            self.axis_window_ticks,
            self.axes,
        );
        self.axis_hist_mid[self.axis_newest] = mid;
        self.position = Self::ring_mean(
            &self.axis_hist_mid,
            self.axis_newest,
            self.axis_window_ticks,
            self.axes,
        );
    }
}
