//! Jogging one axis by hand (issue #15): continuous (a velocity, kept alive by a lease the
//! client renews) or incremental (a step), within the axis's speed and acceleration and its
//! soft limits.
//!
//! A one-axis motion generator on the 4 ms grid: each tick the speed rises by at most `a·Ts`,
//! never exceeds the jog speed, and stays low enough to stop at rest exactly on the target
//! (a continuous jog aims at the soft limit in its direction, so it decelerates to rest on
//! it). When the lease runs out without a renewal the jog brakes to rest at `a`: a client
//! that goes away can never leave an axis moving.
//!
//! Pure and allocation-free: the real-time thread owns one.

use crate::units::TS_S;

/// Remaining distance under which the target counts as reached.
const ARRIVE_EPS_MM: f64 = 1e-9;
/// How far a continuous jog aims when its direction has no soft limit, mm.
const UNLIMITED_MM: f64 = 1e9;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Mode {
    /// Nothing to do.
    Idle,
    /// Moving toward `target_mm` at up to `speed_mm_s` (continuous or step).
    Moving,
    /// Braking to rest at `accel_mm_s2`.
    Stopping,
}

/// Jog state of one axis.
#[derive(Clone, Copy, Debug)]
pub struct Jog {
    axis: usize,
    pos_mm: f64,
    v_mm_s: f64,
    target_mm: f64,
    speed_mm_s: f64,
    accel_mm_s2: f64,
    mode: Mode,
    /// Ticks left before a continuous jog stops by itself (`u32::MAX`: a step, no lease).
    lease_ticks: u32,
}

/// A jog request, already checked against the machine (axis exists, speed within the axis).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JogRequest {
    pub axis: usize,
    /// Where to go: the soft limit (or far away) for a continuous jog, the step's end.
    pub target_mm: f64,
    /// Highest speed, mm/s (> 0), feed override already applied.
    pub speed_mm_s: f64,
    /// Acceleration and deceleration, mm/s² (> 0).
    pub accel_mm_s2: f64,
    /// Ticks until the jog stops unless renewed (`u32::MAX`: no lease, a step).
    pub lease_ticks: u32,
}

impl Default for Jog {
    fn default() -> Self {
        Jog {
            axis: 0,
            pos_mm: 0.0,
            v_mm_s: 0.0,
            target_mm: 0.0,
            speed_mm_s: 0.0,
            accel_mm_s2: 1.0,
            mode: Mode::Idle,
            lease_ticks: 0,
        }
    }
}

impl Jog {
    /// The target of a continuous jog of an axis at `pos_mm` in direction `dir` (sign):
    /// its soft limit on that side (`min`/`max`, infinite when none), never behind the axis.
    pub fn continuous_target(pos_mm: f64, dir: f64, min_mm: f64, max_mm: f64) -> f64 {
        if dir >= 0.0 {
            let t = if max_mm.is_finite() {
                max_mm
            } else {
                pos_mm + UNLIMITED_MM
            };
            t.max(pos_mm)
        } else {
            let t = if min_mm.is_finite() {
                min_mm
            } else {
                pos_mm - UNLIMITED_MM
            };
            t.min(pos_mm)
        }
    }

    /// Whether the axis is being moved (or braked) by a jog.
    pub fn active(&self) -> bool {
        self.mode != Mode::Idle
    }

    pub fn axis(&self) -> usize {
        self.axis
    }

    /// Starts a jog from rest at `pos_mm`, or renews the running one (same axis, same
    /// direction): its target, speed and lease. A request for another axis or the opposite
    /// direction while moving is refused (false): stop first.
    pub fn request(&mut self, r: JogRequest, pos_mm: f64) -> bool {
        if self.mode == Mode::Idle {
            self.axis = r.axis;
            self.pos_mm = pos_mm;
            self.v_mm_s = 0.0;
        } else {
            let dir = r.target_mm - self.pos_mm;
            if r.axis != self.axis || self.mode == Mode::Stopping || dir * self.v_mm_s < 0.0 {
                return false;
            }
        }
        self.target_mm = r.target_mm;
        self.speed_mm_s = r.speed_mm_s.max(0.0);
        self.accel_mm_s2 = r.accel_mm_s2.max(1e-6);
        self.lease_ticks = r.lease_ticks;
        self.mode = Mode::Moving;
        true
    }

    /// Brakes to rest (operator stop, lease expired, a fault elsewhere).
    pub fn stop(&mut self) {
        if self.mode == Mode::Moving {
            self.mode = Mode::Stopping;
        }
    }

    /// Ends the jog at once without braking (only when the setpoints no longer come from it:
    /// a fault reaction took over).
    pub fn cancel(&mut self) {
        self.mode = Mode::Idle;
        self.v_mm_s = 0.0;
    }

    /// Setpoint of the last tick, mm.
    pub fn position_mm(&self) -> f64 {
        self.pos_mm
    }

    /// Speed of the last tick, mm/s (signed).
    pub fn velocity_mm_s(&self) -> f64 {
        self.v_mm_s
    }

    /// Advances one tick; returns the axis setpoint.
    pub fn tick(&mut self) -> f64 {
        match self.mode {
            Mode::Idle => {}
            Mode::Stopping => self.brake(),
            Mode::Moving => {
                if self.lease_ticks != u32::MAX {
                    self.lease_ticks = self.lease_ticks.saturating_sub(1);
                    if self.lease_ticks == 0 {
                        self.mode = Mode::Stopping;
                        self.brake();
                        return self.pos_mm;
                    }
                }
                self.approach();
            }
        }
        self.pos_mm
    }

    fn brake(&mut self) {
        let dv = self.accel_mm_s2 * TS_S;
        let v = self.v_mm_s;
        self.v_mm_s = if v > 0.0 {
            (v - dv).max(0.0)
        } else {
            (v + dv).min(0.0)
        };
        self.pos_mm += self.v_mm_s * TS_S;
        if self.v_mm_s == 0.0 {
            self.mode = Mode::Idle;
        }
    }

    /// One tick toward the target: accelerate, cruise, or brake so as to arrive at rest.
    fn approach(&mut self) {
        let d = self.target_mm - self.pos_mm;
        let dist = d.abs();
        if dist <= ARRIVE_EPS_MM && self.v_mm_s.abs() <= self.accel_mm_s2 * TS_S {
            self.pos_mm = self.target_mm;
            self.v_mm_s = 0.0;
            self.mode = Mode::Idle;
            return;
        }
        let dir = if d >= 0.0 { 1.0 } else { -1.0 };
        let a = self.accel_mm_s2;
        let v = self.v_mm_s * dir;
        // Highest speed this tick from which the axis still stops within the distance left:
        // v²/(2a) ≤ dist − v·Ts.
        let v_brake = (-a * TS_S + (a * a * TS_S * TS_S + 2.0 * a * dist).sqrt()).max(0.0);
        let v_next = (v + a * TS_S)
            .min(self.speed_mm_s)
            .min(v_brake)
            .max(v - a * TS_S)
            .max(0.0);
        let ds = v_next * TS_S;
        if ds >= dist {
            self.pos_mm = self.target_mm;
            self.v_mm_s = 0.0;
            self.mode = Mode::Idle;
        } else {
            self.pos_mm += dir * ds;
            self.v_mm_s = dir * v_next;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn req(target: f64, lease: u32) -> JogRequest {
        JogRequest {
            axis: 0,
            target_mm: target,
            speed_mm_s: 50.0,
            accel_mm_s2: 500.0,
            lease_ticks: lease,
        }
    }

    /// Runs to rest; checks speed and acceleration on the way; returns the setpoints.
    fn run(j: &mut Jog, start: f64) -> Vec<f64> {
        let mut out = vec![start];
        for _ in 0..100_000 {
            if !j.active() {
                break;
            }
            out.push(j.tick());
        }
        assert!(!j.active(), "never at rest");
        let v: Vec<f64> = out.windows(2).map(|w| (w[1] - w[0]) / TS_S).collect();
        for w in v.windows(2) {
            assert!(w[1].abs() <= 50.0 + 1e-9);
            assert!((w[1] - w[0]).abs() <= 500.0 * TS_S + 1e-6, "{w:?}");
        }
        out
    }

    #[test]
    fn a_step_ends_exactly_at_rest() {
        let mut j = Jog::default();
        assert!(j.request(req(10.1, u32::MAX), 10.0));
        let p = run(&mut j, 10.0);
        assert_eq!(*p.last().unwrap(), 10.1);
        assert!(j.request(req(-20.0, u32::MAX), 10.1));
        assert_eq!(*run(&mut j, 10.1).last().unwrap(), -20.0);
    }

    #[test]
    fn a_continuous_jog_decelerates_to_rest_on_the_soft_limit() {
        let mut j = Jog::default();
        let target = Jog::continuous_target(0.0, 1.0, -100.0, 30.0);
        assert_eq!(target, 30.0);
        assert!(j.request(req(target, 1_000_000), 0.0));
        let p = run(&mut j, 0.0);
        assert_eq!(*p.last().unwrap(), 30.0);
        assert!(p.iter().all(|&x| x <= 30.0));
    }

    #[test]
    fn without_renewal_the_lease_runs_out_and_the_axis_brakes_to_rest() {
        let mut j = Jog::default();
        assert!(j.request(req(1e9, 100), 0.0));
        let p = run(&mut j, 0.0);
        // 100 ticks at up to 50 mm/s (0.4 s, ~17.5 mm), then v²/2a = 2.5 mm of braking.
        let end = *p.last().unwrap();
        assert!(end > 15.0 && end < 0.4 * 50.0 + 2.5 + 1e-6, "{end}");
    }

    #[test]
    fn renewals_keep_it_going_and_reversing_needs_a_stop() {
        let mut j = Jog::default();
        assert!(j.request(req(1e9, 50), 0.0));
        for _ in 0..10 {
            for _ in 0..40 {
                j.tick();
            }
            assert!(j.request(req(1e9, 50), 0.0), "renewal");
        }
        assert!(j.active() && j.velocity_mm_s() > 49.0);
        assert!(
            !j.request(req(-1e9, 50), 0.0),
            "reversal refused while moving"
        );
        j.stop();
        let from = j.position_mm();
        let p = run(&mut j, from);
        // Braking from 50 mm/s at 500 mm/s²: 2.5 mm (discrete: within one tick of travel).
        assert!(
            (p.last().unwrap() - from - 2.5).abs() < 50.0 * TS_S,
            "{}",
            p.last().unwrap() - from
        );
    }
}
