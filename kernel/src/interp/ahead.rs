//! What the look-ahead of the raw stage reads of each buffered segment, kept at push time in
//! a compact table (issue #32): the walk over the caps ahead reads ~300 segments per tick on
//! a dense curve, and reading them from the full `Segment` ring (paths, spindle states,
//! technology) cost cache misses and the per-segment work of picking the caps out.
//!
//! The table is also summarized per group of `GROUP` ring slots (smallest caps and
//! accelerations). A group whose every cap is provably unable to lower this tick's limits
//! (`group_bound_clear`) is crossed by adding up its lengths only; the caps that could bind
//! are evaluated exactly as before, so the trajectory is bit-identical.

use super::{BUFFER_SEGMENTS, Interpolator};
use crate::plan::Segment;
use crate::units::TS_S;

/// Ring slots per group (a power of two dividing `BUFFER_SEGMENTS`).
pub(super) const GROUP: usize = 16;
const _: () = assert!(BUFFER_SEGMENTS.is_multiple_of(GROUP) && GROUP.is_power_of_two());

/// The fields of a buffered segment the look-ahead reads.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Ahead {
    pub length_mm: f64,
    pub v_max_mm_s: f64,
    pub feed_mm_s: f64,
    pub per_rev_nominal_rpm: f64,
    pub v_end_mm_s: f64,
    pub junction_cap_mm_s: f64,
    pub accel_mm_s2: f64,
    /// `Segment::free_accel_mm_s2`: the braking walk's acceleration away from junctions.
    pub free_accel_mm_s2: f64,
    /// `Segment::accel_start_mm_s2`, `accel_end_mm_s2`: the braking walk's acceleration
    /// near one junction of the line only (0: none beyond `accel_mm_s2`).
    pub accel_start_mm_s2: f64,
    pub accel_end_mm_s2: f64,
    pub stop_accel_mm_s2: f64,
    pub jerk_mm_s3: f64,
    pub rapid: bool,
}

impl Ahead {
    pub(super) fn of(seg: &Segment) -> Self {
        Ahead {
            length_mm: seg.length_mm,
            v_max_mm_s: seg.v_max_mm_s,
            feed_mm_s: seg.feed_mm_s,
            per_rev_nominal_rpm: seg.per_rev_nominal_rpm,
            v_end_mm_s: seg.v_end_mm_s,
            junction_cap_mm_s: seg.junction_cap_mm_s,
            accel_mm_s2: seg.accel_mm_s2,
            free_accel_mm_s2: seg.free_accel_mm_s2,
            accel_start_mm_s2: seg.accel_start_mm_s2,
            accel_end_mm_s2: seg.accel_end_mm_s2,
            stop_accel_mm_s2: seg.stop_accel_mm_s2,
            jerk_mm_s3: seg.jerk_mm_s3,
            rapid: seg.rapid,
        }
    }
}

/// Lower bounds over the slots of one group filled since its first slot was (segments that
/// have left since only lower them: still bounds).
#[derive(Clone, Copy, Debug)]
pub(super) struct AheadGroup {
    /// Smallest planned end speed (0: a stop point in the group).
    pub v_end_mm_s: f64,
    /// Smallest end cap of the linear profile, max(planned end speed, junction cap).
    pub end_linear_mm_s: f64,
    pub v_max_mm_s: f64,
    /// Smallest feed; a rapid or a feed per revolution in the group makes it unknown (NaN).
    pub feed_mm_s: f64,
    /// Smallest of the feed and stop accelerations, and smallest jerk.
    pub accel_mm_s2: f64,
    pub jerk_mm_s3: f64,
    /// A slot the jerk-limited box does not judge (`jerk_box`: its walk to the stop point
    /// ahead crosses a group only without one).
    pub jerk_unboxed: bool,
}

impl AheadGroup {
    pub(super) const NONE: AheadGroup = AheadGroup {
        v_end_mm_s: f64::INFINITY,
        end_linear_mm_s: f64::INFINITY,
        v_max_mm_s: f64::INFINITY,
        feed_mm_s: f64::INFINITY,
        accel_mm_s2: f64::INFINITY,
        jerk_mm_s3: f64::INFINITY,
        jerk_unboxed: false,
    };

    /// Lowers the bounds by one slot's fields.
    pub(super) fn add(&mut self, a: &Ahead) {
        self.v_end_mm_s = self.v_end_mm_s.min(a.v_end_mm_s);
        self.end_linear_mm_s = self
            .end_linear_mm_s
            .min(a.v_end_mm_s.max(a.junction_cap_mm_s));
        self.v_max_mm_s = self.v_max_mm_s.min(a.v_max_mm_s);
        // (`min` ignores a NaN operand: an unknown feed stays unknown.)
        self.feed_mm_s = if self.feed_mm_s.is_nan() || a.rapid || a.per_rev_nominal_rpm > 0.0 {
            f64::NAN
        } else {
            self.feed_mm_s.min(a.feed_mm_s)
        };
        self.accel_mm_s2 = self.accel_mm_s2.min(a.accel_mm_s2.min(a.stop_accel_mm_s2));
        self.jerk_mm_s3 = self.jerk_mm_s3.min(a.jerk_mm_s3);
    }
}

/// Whether no cap in a stretch of the path can lower a limit `cur` of `speed_limits`: every
/// cap c of the stretch is at least `c_lo`, its distance at least `d_lo_mm` (after the lead
/// `lead_s`), the look-ahead brakes for it with an acceleration u/Ts in [`a_lo`, `a_hi`] and
/// the coast gap `coast`. A cap c < cur is skipped by `Interpolator::v_brake_at_least` when
/// L + c ≤ d/Ts (its margins aside), with W = cur − c (+ margin m) and
/// L + c = ((W + c)² − c²)/(2u) + (3/2 + coast)·W + (1 + coast)·u + (3 + coast)·c; this is
/// at most H(c), the same with u_lo in the first term and u_hi in the third, which is
/// concave in c with its maximum at c = 1.5·u_lo: H at c_lo, 1.5·u_lo clamped to [c_lo, cur],
/// bounds every cap of the stretch. The margin 1e-6 covers the rounding of both tests.
pub(super) fn group_bound_clear(
    cur: f64,
    c_lo: f64,
    d_lo_mm: f64,
    lead_s: f64,
    a_lo: f64,
    a_hi: f64,
    coast: f64,
) -> bool {
    if c_lo >= cur {
        // (No cap of the stretch is below the limit: `CapWalk::limit` skips each.)
        return true;
    }
    let (u_lo, u_hi) = (a_lo * TS_S, a_hi * TS_S);
    let c = (1.5 * u_lo).clamp(c_lo, cur);
    let v = cur + 1e-9 * (cur + u_hi);
    let w = v - c;
    let h = (v * v - c * c) / (2.0 * u_lo)
        + (1.5 + coast) * w
        + (1.0 + coast) * u_hi
        + (3.0 + coast) * c;
    let d = d_lo_mm - cur * lead_s;
    h * (1.0 + 1e-6) * TS_S <= d
}

impl Interpolator {
    /// Keeps the table and its group in step with the segment just stored in slot `i`. A
    /// group is judged only when its slots hold consecutive segments from its first slot on
    /// (`group_clear`), all pushed after that first one: the bounds restart there, and what
    /// is left in its other slots from before (a nearly full ring) is never judged with them.
    pub(super) fn note_pushed(&mut self, i: usize) {
        self.ahead[i] = Ahead::of(&self.buf[i]);
        self.box_slots[i] = super::setpoint_box::BoxSlot::of(&self.buf[i]);
        self.jbox_slots[i] = super::jerk_box::JerkSlot::of(&self.buf[i]);
        let g = &mut self.groups[i / GROUP];
        if i.is_multiple_of(GROUP) {
            *g = AheadGroup::NONE;
        }
        g.add(&self.ahead[i]);
        g.jerk_unboxed |= !self.jbox_slots[i].set;
    }

    /// Segment in slot `i` now ends at rest (single block).
    pub(super) fn note_stop_at(&mut self, i: usize) {
        self.ahead[i].v_end_mm_s = 0.0;
        self.jbox_stop.valid = false;
        self.box_slots[i].stop_end = true;
        self.jbox_slots[i].stop_end = true;
        self.groups[i / GROUP].v_end_mm_s = 0.0;
    }

    /// Whether the caps at the ends of the `GROUP` segments from `k` (a group's first slot,
    /// all followed by a buffered segment) cannot lower any limit of `walk`, `d_mm` ahead
    /// (the end of segment `k`), braked for with at most `a_walk` (the walk's so far) and at
    /// least the group's smallest acceleration.
    pub(super) fn group_clear(
        &self,
        k: usize,
        walk: &super::raw::CapWalk,
        d_mm: f64,
        a_walk: f64,
        lead_s: f64,
        braking: bool,
    ) -> bool {
        let g = &self.groups[self.idx(k) / GROUP];
        let next = &self.ahead[self.idx(k + GROUP)];
        let filtered = self.filtered();
        if g.v_end_mm_s <= 0.0 {
            return false;
        }
        let v_max = g.v_max_mm_s.min(next.v_max_mm_s);
        let end = if filtered {
            g.v_end_mm_s
        } else {
            g.end_linear_mm_s
        };
        let hard_lo = end.min(v_max);
        // Soft caps: the ceilings of the segments after each, feed × override or v_max.
        let soft_lo = if braking {
            f64::INFINITY
        } else if g.feed_mm_s.is_nan() || next.rapid || next.per_rev_nominal_rpm > 0.0 {
            0.0
        } else {
            (g.feed_mm_s.min(next.feed_mm_s) * self.override_factor).min(v_max)
        };
        let a_group = if g.jerk_mm_s3.is_finite() {
            g.accel_mm_s2
                .min(g.jerk_mm_s3 * self.jerk_filter_ticks as f64 * TS_S)
        } else {
            g.accel_mm_s2
        };
        let a_lo = a_walk.min(a_group.max(1e-6));
        // (The look-ahead's acceleration only falls along the walk: `a_walk` bounds it above.)
        let clear = |cur: f64, lo: f64, gap: f64| {
            group_bound_clear(cur, lo, d_mm, lead_s, a_lo, a_walk, gap)
        };
        let mut ok = clear(walk.hard, hard_lo, walk.coast) && clear(walk.soft, soft_lo, walk.coast);
        if walk.coast_accel != walk.coast {
            ok = ok
                && clear(walk.hard_acc, hard_lo, walk.coast_accel)
                && clear(walk.soft_acc, soft_lo, walk.coast_accel);
        }
        ok
    }
}
