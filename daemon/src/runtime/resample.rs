//! The bus period beside the kernel's 4 ms interpolation period (issue #23).
//!
//! The kernel plans and interpolates on a fixed 4 ms grid ([`kernel::units::TS_NS`]): SPEC
//! rules, jog leases, the fault brake and KŘR count in those ticks. The bus (SYNC, serial
//! exchange, simulated drives) runs at its own `cycle_ms` of 1..10 ms. As in controllers with
//! a coarse trajectory period and a fine servo period, the RT thread ticks at the bus period and
//! [`BusClock`] says, at each bus tick, how many 4 ms interpolator steps are due so that the
//! trajectory is known up to the bus tick's time; [`Resampler`] then gives the position the bus
//! gets at that time.
//!
//! Time here is *trajectory* time: one bus period per executed bus tick. A late tick skips
//! deadlines of the wall-clock grid but not trajectory time, so the setpoints never jump (as
//! before, when the trajectory advanced one Ts per executed tick).
//!
//! At a 4 ms bus the bus gets the interpolator's setpoint of the tick itself, bit for bit as
//! before. At any other period it gets the 4 ms setpoints smoothed by a moving average over one
//! interpolation period, which is the uniform quadratic B-spline with the 4 ms setpoints as
//! control points. Why not the straight line between setpoints: its velocity steps at every
//! 4 ms point, so at a 1 ms bus the drives would see 4× the axis acceleration there. The
//! average instead has
//! - velocity = mean of the 4 ms chord velocities over the last 4 ms, so within the axis limit
//!   whenever the 4 ms setpoints are;
//! - acceleration = (chord velocity now − chord velocity 4 ms ago) / 4 ms, i.e. one second
//!   difference of the 4 ms setpoints over Ts², so within the axis limit whenever they are;
//! - position within |P[j−1] − 2·P[j] + P[j+1]| / 8 ≤ a_max·Ts²/8 of the 4 ms polyline
//!   (0.002 mm at 1000 mm/s²), and exactly on it where the path is straight;
//! - a delay of half an interpolation period (2 ms) behind the 4 ms setpoints.

use kernel::units::{AxesMm, MAX_AXES, TS_NS};

/// Bus periods the daemon accepts, ms.
pub const CYCLE_MS_RANGE: std::ops::RangeInclusive<u32> = 1..=10;

/// Interpolator steps due against bus ticks, in trajectory time.
#[derive(Clone, Copy, Debug)]
pub struct BusClock {
    cycle_ns: u64,
    /// Bus ticks executed so far.
    bus_ticks: u64,
    /// Interpolator steps taken so far.
    steps: u64,
}

impl BusClock {
    pub fn new(cycle_ns: u64) -> BusClock {
        BusClock {
            cycle_ns: cycle_ns.max(1),
            bus_ticks: 0,
            steps: 0,
        }
    }

    /// The bus period, ns.
    pub fn cycle_ns(&self) -> u64 {
        self.cycle_ns
    }

    /// Starts the next bus tick; returns how many interpolator steps are due before its
    /// setpoint can be sampled (the trajectory must be known up to the tick's time).
    pub fn begin_tick(&mut self) -> u64 {
        self.bus_ticks += 1;
        let due = self.time_ns().div_ceil(TS_NS);
        let n = due - self.steps;
        self.steps = due;
        n
    }

    /// Trajectory time of the current bus tick, ns.
    pub fn time_ns(&self) -> u64 {
        self.bus_ticks * self.cycle_ns
    }

    /// Where the current bus tick lies in the last interpolation period: (0, 1], 1 on a 4 ms
    /// point.
    pub fn phase(&self) -> f64 {
        let into_ns = self.time_ns() - (self.steps - 1) * TS_NS;
        into_ns as f64 / TS_NS as f64
    }

    /// Interpolator steps in `ns` of bus time, rounded up (for windows given by the bus in
    /// its own ticks).
    pub fn steps_in(&self, bus_ticks: u64) -> u64 {
        (bus_ticks * self.cycle_ns).div_ceil(TS_NS)
    }
}

/// The bus setpoint at the bus tick time from the last three 4 ms setpoints.
#[derive(Clone, Copy, Debug)]
pub struct Resampler {
    /// Smooth (B-spline) or take the 4 ms setpoint as is (bus period = 4 ms).
    smooth: bool,
    /// P[j−2], P[j−1], P[j]: the last three interpolator setpoints, oldest first.
    points: [AxesMm; 3],
}

impl Resampler {
    pub fn new(cycle_ns: u64, start: AxesMm) -> Resampler {
        Resampler {
            smooth: cycle_ns != TS_NS,
            points: [start; 3],
        }
    }

    /// A new interpolator setpoint (one per 4 ms step).
    pub fn push(&mut self, p: AxesMm) {
        self.points = [self.points[1], self.points[2], p];
    }

    /// The setpoint jumps here on purpose (drives' own positions taken over at enable): no
    /// smoothing from where it was.
    pub fn reset(&mut self, p: AxesMm) {
        self.points = [p; 3];
    }

    /// Axis `axis` was redefined by `shift_mm` (homing: drive and setpoint move together).
    pub fn shift(&mut self, axis: usize, shift_mm: f64) {
        for p in &mut self.points {
            p[axis] += shift_mm;
        }
    }

    /// The bus setpoint has arrived where the interpolator's is (at rest after a move, the
    /// smoothing lags by up to one period): a job ends only then.
    pub fn settled(&self) -> bool {
        !self.smooth || (self.points[0] == self.points[2] && self.points[1] == self.points[2])
    }

    /// The setpoint of `axes` axes at `phase` ∈ (0, 1] of the last interpolation period.
    pub fn sample(&self, axes: usize, phase: f64, out: &mut [f64; MAX_AXES]) {
        let [a, b, c] = &self.points;
        if !self.smooth {
            out[..axes].copy_from_slice(&c.0[..axes]);
            return;
        }
        let u = phase;
        let wa = 0.5 * (1.0 - u) * (1.0 - u);
        let wc = 0.5 * u * u;
        // (As offsets from the middle point: at rest, where all three are equal, the sample
        // is that point exactly; the weighted sum of the three rounded it by an ulp either
        // way from one bus cycle to the next.)
        for i in 0..axes {
            out[i] = b[i] + (wa * (a[i] - b[i]) + wc * (c[i] - b[i]));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn steps(cycle_ms: u64, ticks: usize) -> Vec<(u64, f64)> {
        let mut c = BusClock::new(cycle_ms * 1_000_000);
        (0..ticks).map(|_| (c.begin_tick(), c.phase())).collect()
    }

    #[test]
    fn steps_follow_bus_time() {
        assert_eq!(steps(4, 3), vec![(1, 1.0), (1, 1.0), (1, 1.0)]);
        assert_eq!(
            steps(1, 5),
            vec![(1, 0.25), (0, 0.5), (0, 0.75), (0, 1.0), (1, 0.25)]
        );
        assert_eq!(steps(2, 3), vec![(1, 0.5), (0, 1.0), (1, 0.5)]);
        assert_eq!(steps(10, 3), vec![(3, 0.5), (2, 1.0), (3, 0.5)]);
        assert_eq!(steps(5, 4), vec![(2, 0.25), (1, 0.5), (1, 0.75), (1, 1.0)]);
        // 1000 ticks of any period: as many steps as 4 ms fit, rounded up.
        for ms in 1..=10u64 {
            let total: u64 = steps(ms, 1000).iter().map(|s| s.0).sum();
            assert_eq!(total, (1000 * ms).div_ceil(4), "{ms} ms");
        }
    }

    #[test]
    fn smooth_sample_is_continuous_and_exact_on_straight_lines() {
        let mut r = Resampler::new(1_000_000, AxesMm::ZERO);
        let mut out = [0.0; MAX_AXES];
        let mut last = 0.0;
        // A straight line at 1 mm per 4 ms: after two steps the samples are exact, 2 ms late.
        for j in 1..=6 {
            r.push(AxesMm([j as f64, 0.0, 0.0, 0.0, 0.0, 0.0]));
            for q in 1..=4 {
                let u = q as f64 / 4.0;
                r.sample(1, u, &mut out);
                assert!(out[0] >= last && out[0] - last <= 0.25 + 1e-12);
                if j >= 2 {
                    assert!((out[0] - (j as f64 - 1.5 + u)).abs() < 1e-12);
                }
                last = out[0];
            }
        }
    }

    #[test]
    fn four_ms_bus_takes_the_setpoint_as_is() {
        let mut r = Resampler::new(TS_NS, AxesMm::ZERO);
        r.push(AxesMm([1.0, 2.0, 0.0, 0.0, 0.0, 0.0]));
        let mut out = [0.0; MAX_AXES];
        r.sample(2, 1.0, &mut out);
        assert_eq!(out[..2], [1.0, 2.0]);
    }
}
