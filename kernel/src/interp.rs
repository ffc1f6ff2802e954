//! The 4 ms interpolator: planned segments in, one setpoint per axis per tick out.
//!
//! Runs on the real-time thread, so it never allocates after [`Interpolator::new`]. Each tick it
//! chooses the path speed online from the limits the planner attached to each [`Segment`]:
//! - hard limits (geometry and axis ceilings, the planner's safe end speeds, and a stop at the
//!   end of what has been received) are braked for and never exceeded;
//! - soft limits (programmed feed × override) are approached within the acceleration limit, so an
//!   override change never makes a speed step.
//!
//! Speeds are per-tick averages: the position advances by `v·Ts` along the path each tick, across
//! as many segments as that distance covers. A late tick of the real-time thread therefore never
//! makes a setpoint jump: one call is one Ts of trajectory, however late it comes.

use crate::plan::Segment;
use crate::units::{AxesMm, TS_S};

/// How many segments the interpolator holds (its own look-ahead for braking).
pub const BUFFER_SEGMENTS: usize = 1024;

/// Remaining distance under which a stop point is reached exactly in the next tick.
const ARRIVE_EPS_MM: f64 = 1e-9;

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum InterpState {
    /// Nothing to do.
    #[default]
    Idle,
    /// Following the path.
    Running,
    /// Feed hold requested: braking to rest on the path.
    Holding,
    /// At rest on the path after a feed hold; `resume` continues.
    Held,
    /// Stop requested: braking to rest, then the remaining segments are dropped.
    Stopping,
}

/// What one tick produced.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TickOut {
    /// Commanded position of every axis.
    pub position: AxesMm,
    /// Path speed over this tick, mm/s.
    pub path_v_mm_s: f64,
    /// Source block (index, `N`, line) of the segment the position lies on.
    pub seq: u32,
    pub n: Option<u32>,
    pub line: u32,
    pub state: InterpState,
    /// The last segment of a program was completed in this tick.
    pub program_end: bool,
}

pub struct Interpolator {
    axes: usize,
    buf: Box<[Segment]>,
    head: usize,
    len: usize,
    /// Distance already travelled on the head segment, mm.
    s_mm: f64,
    v_mm_s: f64,
    position: AxesMm,
    state: InterpState,
    override_factor: f64,
    last_seq: u32,
    last_n: Option<u32>,
    last_line: u32,
}

impl Interpolator {
    pub fn new(axes: usize, position: AxesMm) -> Self {
        Interpolator {
            axes,
            buf: vec![Segment::default(); BUFFER_SEGMENTS].into_boxed_slice(),
            head: 0,
            len: 0,
            s_mm: 0.0,
            v_mm_s: 0.0,
            position,
            state: InterpState::Idle,
            override_factor: 1.0,
            last_seq: 0,
            last_n: None,
            last_line: 0,
        }
    }

    pub fn axes(&self) -> usize {
        self.axes
    }

    pub fn position(&self) -> AxesMm {
        self.position
    }

    pub fn state(&self) -> InterpState {
        self.state
    }

    pub fn has_room(&self) -> bool {
        self.len < self.buf.len()
    }

    pub fn buffered(&self) -> usize {
        self.len
    }

    /// Appends a segment. Gives it back when the buffer is full or while stopping.
    pub fn push(&mut self, seg: Segment) -> Result<(), Segment> {
        if !self.has_room() || self.state == InterpState::Stopping {
            return Err(seg);
        }
        let i = (self.head + self.len) % self.buf.len();
        self.buf[i] = seg;
        self.len += 1;
        if self.state == InterpState::Idle {
            self.state = InterpState::Running;
        }
        Ok(())
    }

    /// Feed override in percent, clamped to 0..=150.
    pub fn set_override(&mut self, percent: f64) {
        self.override_factor = percent.clamp(0.0, 150.0) / 100.0;
    }

    pub fn hold(&mut self) {
        if self.state == InterpState::Running {
            self.state = InterpState::Holding;
        }
    }

    pub fn resume(&mut self) {
        if matches!(self.state, InterpState::Holding | InterpState::Held) {
            self.state = if self.len > 0 {
                InterpState::Running
            } else {
                InterpState::Idle
            };
        }
    }

    /// Brakes to rest on the path with the stop deceleration, then drops every segment.
    pub fn stop(&mut self) {
        match self.state {
            InterpState::Idle => {}
            InterpState::Held => self.clear(),
            _ => self.state = InterpState::Stopping,
        }
    }

    fn clear(&mut self) {
        self.len = 0;
        self.s_mm = 0.0;
        self.v_mm_s = 0.0;
        self.state = InterpState::Idle;
    }

    fn seg(&self, k: usize) -> &Segment {
        &self.buf[(self.head + k) % self.buf.len()]
    }

    fn ceiling(&self, seg: &Segment) -> f64 {
        (seg.feed_mm_s * self.override_factor).min(seg.v_max_mm_s)
    }

    /// Highest per-tick speed that still lets us brake from the end of this tick to `v_cap` over
    /// the distance `d` (from the current position) with deceleration `a`:
    /// (v² − v_cap²)/(2a) ≤ d − v·Ts.
    fn v_brake(d: f64, v_cap: f64, a: f64) -> f64 {
        let d = d.max(0.0);
        (-a * TS_S + (a * a * TS_S * TS_S + v_cap * v_cap + 2.0 * a * d).sqrt()).max(0.0)
    }

    /// Advances one tick.
    pub fn tick(&mut self) -> TickOut {
        let mut program_end = false;
        if self.len > 0 && !matches!(self.state, InterpState::Held | InterpState::Idle) {
            program_end = self.advance();
        }
        TickOut {
            position: self.position,
            path_v_mm_s: self.v_mm_s,
            seq: self.last_seq,
            n: self.last_n,
            line: self.last_line,
            state: self.state,
            program_end,
        }
    }

    fn advance(&mut self) -> bool {
        let head = *self.seg(0);
        let braking = matches!(self.state, InterpState::Holding | InterpState::Stopping);
        let a = if braking {
            head.stop_accel_mm_s2
        } else {
            head.accel_mm_s2
        };
        let v = self.v_mm_s;
        // Soft limits: feed × override of this and later segments, approached at `a`.
        let mut soft = if braking { 0.0 } else { self.ceiling(&head) };
        // Hard limits: geometric ceilings, planned end speeds, end of the buffer.
        let mut hard = head.v_max_mm_s;
        let reach = (v + a * TS_S) * (v + a * TS_S) / (2.0 * a) + 2.0 * (v + a * TS_S) * TS_S;
        let mut d = head.length_mm - self.s_mm;
        let mut stop_dist = f64::INFINITY;
        for k in 0..self.len {
            let seg = *self.seg(k);
            let next = (k + 1 < self.len).then(|| *self.seg(k + 1));
            let hard_cap = match next {
                Some(n) => seg.v_end_mm_s.min(n.v_max_mm_s),
                None => 0.0,
            };
            let soft_cap = next.map_or(0.0, |n| self.ceiling(&n));
            hard = hard.min(Self::v_brake(d, hard_cap, a));
            soft = soft.min(Self::v_brake(d, soft_cap, a));
            if hard_cap == 0.0 && stop_dist.is_infinite() {
                stop_dist = d;
            }
            if d > reach || next.is_none() {
                break;
            }
            d += next.map_or(0.0, |n| n.length_mm);
        }
        let mut v_next = (v + a * TS_S)
            .min(soft)
            .max(v - a * TS_S)
            .min(hard)
            .max(0.0);
        // Arrive exactly at a stop point once the last step fits inside the deceleration limit.
        let mut ds = v_next * TS_S;
        if stop_dist.is_finite() && stop_dist <= (a * TS_S * TS_S).max(ARRIVE_EPS_MM) {
            ds = stop_dist;
            v_next = ds / TS_S;
        }
        if braking && v_next <= 0.0 {
            self.v_mm_s = 0.0;
            if self.state == InterpState::Stopping {
                self.clear();
            } else {
                self.state = InterpState::Held;
            }
            return false;
        }
        self.v_mm_s = v_next;
        self.move_along(ds)
    }

    /// Moves `ds` along the buffered path, dropping completed segments. Returns whether the
    /// program's last segment was completed.
    fn move_along(&mut self, mut ds: f64) -> bool {
        let mut program_end = false;
        while self.len > 0 {
            let seg = *self.seg(0);
            let rest = seg.length_mm - self.s_mm;
            self.last_seq = seg.seq;
            self.last_n = seg.n;
            self.last_line = seg.line;
            if ds < rest - ARRIVE_EPS_MM {
                self.s_mm += ds;
                self.position = seg.path.point_at(self.s_mm / seg.length_mm);
                return false;
            }
            ds -= rest;
            self.position = seg.path.end();
            self.head = (self.head + 1) % self.buf.len();
            self.len -= 1;
            self.s_mm = 0.0;
            program_end |= seg.last;
            if seg.v_end_mm_s == 0.0 || self.len == 0 {
                // A stop point: never carry distance past it.
                break;
            }
        }
        if self.len == 0 {
            self.v_mm_s = 0.0;
            if self.state != InterpState::Held {
                self.state = InterpState::Idle;
            }
        }
        program_end
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::SegPath;

    fn line(seq: u32, from: [f64; 3], to: [f64; 3], feed: f64, v_end: f64) -> Segment {
        let mut s = AxesMm::ZERO;
        let mut e = AxesMm::ZERO;
        s.0[..3].copy_from_slice(&from);
        e.0[..3].copy_from_slice(&to);
        let path = SegPath::Line { start: s, end: e };
        Segment {
            seq,
            path,
            length_mm: path.length(3),
            feed_mm_s: feed,
            v_max_mm_s: 1000.0,
            v_end_mm_s: v_end,
            accel_mm_s2: 500.0,
            jerk_mm_s3: f64::INFINITY,
            stop_accel_mm_s2: 500.0,
            ..Segment::default()
        }
    }

    fn run(ip: &mut Interpolator, max_ticks: usize) -> Vec<TickOut> {
        let mut out = vec![];
        for _ in 0..max_ticks {
            let t = ip.tick();
            out.push(t);
            if t.state == InterpState::Idle {
                break;
            }
        }
        out
    }

    fn check_limits(trace: &[TickOut], v_max: f64, a_max: f64) {
        let mut prev_v = 0.0;
        for w in trace.windows(2) {
            let v = (w[1].position - w[0].position).norm(3) / TS_S;
            assert!(v <= v_max * (1.0 + 1e-9) + 1e-9, "speed {v} > {v_max}");
            let a = (v - prev_v).abs() / TS_S;
            assert!(a <= a_max * (1.0 + 1e-6) + 1e-6, "accel {a} > {a_max}");
            prev_v = v;
        }
    }

    #[test]
    fn single_line_ends_exactly_within_limits() {
        let mut ip = Interpolator::new(3, AxesMm::ZERO);
        ip.push(line(0, [0.0; 3], [10.0, 5.0, 0.0], 50.0, 0.0))
            .unwrap();
        let mut trace = vec![TickOut::default()];
        trace.extend(run(&mut ip, 10_000));
        let end = trace.last().unwrap().position;
        assert_eq!(&end.0[..3], &[10.0, 5.0, 0.0]);
        check_limits(&trace, 50.0, 500.0);
    }

    #[test]
    fn smooth_junction_does_not_stop() {
        let mut ip = Interpolator::new(3, AxesMm::ZERO);
        ip.push(line(0, [0.0; 3], [10.0, 0.0, 0.0], 50.0, 50.0))
            .unwrap();
        ip.push(line(1, [10.0, 0.0, 0.0], [20.0, 0.0, 0.0], 50.0, 0.0))
            .unwrap();
        let trace = run(&mut ip, 10_000);
        let min_mid = trace
            .iter()
            .filter(|t| (5.0..15.0).contains(&t.position[0]))
            .map(|t| t.path_v_mm_s)
            .fold(f64::INFINITY, f64::min);
        assert!(min_mid > 49.0, "slowed to {min_mid}");
        assert_eq!(trace.last().unwrap().position[0], 20.0);
    }

    #[test]
    fn hold_brakes_and_resume_finishes() {
        let mut ip = Interpolator::new(3, AxesMm::ZERO);
        ip.push(line(0, [0.0; 3], [100.0, 0.0, 0.0], 50.0, 0.0))
            .unwrap();
        let mut trace = vec![TickOut::default()];
        for _ in 0..100 {
            trace.push(ip.tick());
        }
        ip.hold();
        for _ in 0..100 {
            trace.push(ip.tick());
        }
        assert_eq!(ip.state(), InterpState::Held);
        ip.resume();
        trace.extend(run(&mut ip, 10_000));
        check_limits(&trace, 50.0, 500.0);
        assert_eq!(trace.last().unwrap().position[0], 100.0);
    }

    #[test]
    fn stop_brakes_then_drops_the_rest() {
        let mut ip = Interpolator::new(3, AxesMm::ZERO);
        ip.push(line(0, [0.0; 3], [100.0, 0.0, 0.0], 50.0, 0.0))
            .unwrap();
        let mut trace = vec![TickOut::default()];
        for _ in 0..100 {
            trace.push(ip.tick());
        }
        ip.stop();
        trace.extend(run(&mut ip, 1000));
        check_limits(&trace, 50.0, 500.0);
        assert_eq!(ip.state(), InterpState::Idle);
        assert!(ip.position()[0] < 100.0);
    }
}
