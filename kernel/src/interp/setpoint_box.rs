//! The per-axis box on the setpoints themselves (linear profile, issues #32 and #49;
//! docs/planner.md, *The per-axis box on the setpoints*).
//!
//! What the drives see is the setpoints: per axis, the second difference of three consecutive
//! ones is the axis's velocity change over a tick and must stay within a_k·Ts². The planner's
//! envelope bounds it from the geometry ahead for every speed (junction caps, line budgets),
//! which on a dense curve leaves 4-12 % of the time on the table, on arcs 24-42 %. On a line
//! or an arc of the linear profile (`Segment::axis_box`) the raw stage chooses each setpoint
//! from the box directly:
//! - the setpoints the box allows next lie in intervals of arc length, exact on lines, where
//!   each axis's position is linear in the arc length, and on arcs, a quarter turn at a time
//!   (`box_scan`, `path_within`); the path acceleration of
//!   the constants (R52, R236, R237, a set's A: `BoxAccel::path`) bounds the second difference
//!   of the arc length at the setpoint, the speed's change over a tick; the step also keeps every
//!   segment's ceiling it runs on, the manual's criteria (R385, R384) of every junction it
//!   crosses or starts on, R384 over all the junctions of the step together and the arcs'
//!   bend at its corners (`Accuracy`),
//!   and never passes a stop point;
//! - a setpoint is taken only with a proof that the motion can still come to rest from it:
//!   braking as hard as the box allows (each tick the nearest allowed setpoint) comes to rest
//!   within the buffered path (`box_proof`);
//! - each tick takes the farthest setpoint within the feed that a proof passes, out of three
//!   tried at most (`box_search`). The braking of the last accepted proof is kept (`Plan`):
//!   its next setpoint is proven whatever the search finds, so every tick stays within the box;
//! - a step turns the arcs it runs on by at most a half turn (`StepTurn`).
//!
//! The envelope takes over where the box cannot look (the jerk filters, a braking longer than
//! `PROOF_TICKS`) once it allows the current speed and its next setpoint is inside the box.

use super::ahead::Ahead;
use super::{ARRIVE_EPS_MM, InterpState, Interpolator};
use crate::plan::{SegPath, Segment};
use crate::units::{AxesMm, MAX_AXES, TS_S};

/// Braking ticks one proof may simulate (256 mm/s brake to rest at 1000 mm/s²): a longer
/// braking is not judged, as past an arc, and the envelope runs such speeds (long lines,
/// rapids), where it is exact anyway.
const PROOF_TICKS: usize = 64;
/// Smallest gain of a searched step over the nearest one, mm.
const SEARCH_TOL_MM: f64 = 1e-5;
/// Proofs one tick may run while it searches (the first tries the feed).
const PROOF_RUNS: usize = 3;
/// Guesses of the search, as fractions of the way from the nearest setpoint to the farthest
/// (the farthest itself has just failed): the range, and the step above the last find.
const GUESS_MIN: f64 = 1.0 / 16.0;
const GUESS_MAX: f64 = 15.0 / 16.0;
const GUESS_STEP: f64 = 1.0 / 16.0;
/// How far before the start of a segment the box cannot judge its steps end, mm.
const BOUNDARY_MM: f64 = 1e-6;
/// Slack on each axis's second difference, mm: the setpoints as sent snap to a segment's end
/// within `ARRIVE_EPS_MM`, which moves a second difference by up to four times that.
const BOX_SLACK_MM: f64 = 4.0 * ARRIVE_EPS_MM;

/// The next setpoints the box allows.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Reach {
    /// Allowed: `near` is the nearest (on segment `near_k`), `far` the farthest (with gaps
    /// between, at most).
    Within { near: f64, near_k: usize, far: f64 },
    /// None.
    Empty,
    /// None before the scan met a segment the box cannot judge.
    Unknown,
}

impl Reach {
    /// What a scan found before it met a segment the box cannot judge (`near` NaN: none).
    fn met(near: f64, near_k: usize, far: f64) -> Reach {
        if near.is_nan() {
            Reach::Unknown
        } else {
            Reach::Within { near, near_k, far }
        }
    }
}

/// How braking as hard as the box allows ends.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Proof {
    /// At rest at this arc length.
    Rest(f64),
    /// No allowed setpoint on the way.
    Fails,
    /// It meets a segment the box cannot judge, or needs more than `PROOF_TICKS`.
    Unknown,
}

/// Setpoints of one braking (a proof's) in a region of `Interpolator::box_paths`.
pub(super) const PLAN_SLOTS: usize = PROOF_TICKS;

/// The braking of the last accepted proof: `len` setpoints in region `region` of
/// `Interpolator::box_paths`, the next to take at `next` (all taken: at rest).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Plan {
    pub region: usize,
    pub len: usize,
    pub next: usize,
}

impl Plan {
    /// Where the braking comes to rest (`here`: at rest already).
    pub(super) fn rest_s(&self, paths: &[f64], here: f64) -> f64 {
        if self.len > 0 {
            paths[self.region * PLAN_SLOTS + self.len - 1]
        } else {
            here
        }
    }
}

/// A setpoint the search chose: with the region and length of its proof's braking (`None`:
/// the plan's next setpoint), and whether a proof met a segment the box cannot judge.
#[derive(Clone, Copy, Debug)]
pub(super) struct Choice {
    s: f64,
    plan: Option<(usize, usize)>,
    unknown: bool,
}

/// A tick of the box: the setpoint a tick ago, the current one (arc length on buffered
/// segment `k`, and the point) and the junction it lies on (`OnJunction::NONE`: none).
#[derive(Clone, Copy, Debug)]
struct Tick {
    prev: AxesMm,
    /// The arc length from the setpoint a tick ago to this one, mm (the speed along the path
    /// × Ts).
    ds_prev: f64,
    s: f64,
    k: usize,
    /// The setpoint at `s`.
    at: AxesMm,
    on: OnJunction,
}

/// What the box reads of a buffered segment besides `Ahead`, kept at push time.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct BoxSlot {
    /// The box judges the setpoints on it.
    pub boxed: bool,
    /// It ends at a stop point (`Segment::v_end_mm_s` 0).
    pub stop_end: bool,
    /// Its feed is `feed_mm_s` as programmed (not a rapid, not per revolution).
    pub plain_feed: bool,
    /// `SegmentBox::v_max_mm_s`.
    pub v_max_mm_s: f64,
    /// Room for the second difference of the arc length at a setpoint on it, mm: the path
    /// acceleration over a tick (∞: none).
    pub path_room_mm: f64,
    /// The end junction (`SegmentBox::criteria_end_mm_s`, `end_half_tan`, `lm_mm`).
    pub end: OnJunction,
    /// Its turn per mm of arc length, radians (0 on a line; `StepTurn`).
    pub turn_per_mm: f64,
}

impl BoxSlot {
    pub(super) fn of(seg: &Segment) -> Self {
        let b = &seg.axis_box;
        BoxSlot {
            // (The planner sets the accelerations on the lines and arcs the box may judge.)
            boxed: b.accel_mm_s2.is_set(),
            stop_end: seg.v_end_mm_s == 0.0,
            plain_feed: !seg.rapid && seg.per_rev_nominal_rpm <= 0.0,
            v_max_mm_s: b.v_max_mm_s,
            path_room_mm: b.accel_mm_s2.path() * TS_S * TS_S * (1.0 - 1e-9),
            end: OnJunction {
                crit_mm_s: b.criteria_end_mm_s,
                half_tan: b.end_half_tan,
                lm_mm: b.lm_mm,
            },
            turn_per_mm: turn_per_mm(seg),
        }
    }
}

/// A junction's criteria for the box: the speed the manual's criteria allow there, and its
/// turn as tan(α/2) with the criterion's Lm (mm) for the turns of a step (`Accuracy`).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct OnJunction {
    pub crit_mm_s: f64,
    pub half_tan: f64,
    pub lm_mm: f64,
}

impl OnJunction {
    /// No junction (or a stop point, which is left from rest).
    pub(super) const NONE: OnJunction = OnJunction {
        crit_mm_s: f64::INFINITY,
        half_tan: 0.0,
        lm_mm: f64::INFINITY,
    };
}

/// The manual's accuracy criterion (R384) over the blocks within one step (SPEC §7.2): the
/// chord of a step keeps the junctions it crosses within Lm. A junction of turn α at distance
/// d along a step of length L lies within w·min(d, L − d) of the chord, w = 2·tan(α/2) ≥ α
/// (one junction in the middle: L·tan(α/2) ≤ Lm, R384's own form), and the turns of several
/// add up: F(L) = Σ w_j·min(d_j, L − d_j) ≤ Lm. The scan keeps the sum of the weights: F is
/// at most that sum times L/2, and only where that bound reaches Lm is F followed exactly
/// (`Interpolator::box_accuracy_reach`).
///
/// F counts the junctions' turns, not the bend of the arcs between them, which moves a corner
/// (a junction that turns) off the chord too: by at most min(d, L − d)·Φ, Φ the arcs' turn
/// within the step. So where arcs bend within a step, each corner it crosses also keeps
/// min(d, L − d)·(Σw + Φ) ≤ Lm (`Interpolator::box_corner_cap`).
#[derive(Clone, Copy, Debug)]
struct Accuracy {
    lm_mm: f64,
    w_sum: f64,
    /// The last segment whose end junction the step crosses (with a turn).
    last: Option<usize>,
}

/// Below this tan(α/2) a junction is tangent for the arcs' bend (α < 0.001 rad: a program's
/// digits, not a corner; its own R384 speed is above 8000 mm/s at Lm 8 µm).
const CORNER_MIN_HALF_TAN: f64 = 5e-4;

impl Accuracy {
    const NONE: Accuracy = Accuracy {
        lm_mm: f64::INFINITY,
        w_sum: 0.0,
        last: None,
    };

    /// The step crosses the end junction `j` of segment `k`.
    fn cross(&mut self, k: usize, j: &OnJunction) {
        if j.half_tan > 0.0 && j.lm_mm.is_finite() {
            self.w_sum += 2.0 * j.half_tan;
            self.lm_mm = self.lm_mm.min(j.lm_mm);
            self.last = Some(k);
        }
    }
}

/// The turn of the arcs within one step, at most a half turn (`HALF_TURN_RAD`): within it the
/// chord of a step grows with the turn, so the setpoints cannot alias an arc (a step turning
/// a small circle almost once looks like a short step back), nor skip a loop of small arcs,
/// whose ends are tangent and whose turns the axes would not see across it. A fillet of up to
/// a half turn may still be crossed in one step, where the axes see its turn as a corner's.
#[derive(Clone, Copy, Debug)]
struct StepTurn {
    turned_rad: f64,
}

/// The most the arcs within one step may turn, radians.
const HALF_TURN_RAD: f64 = std::f64::consts::PI;

impl StepTurn {
    const NONE: StepTurn = StepTurn { turned_rad: 0.0 };

    /// The step from arc length `from` reaches a segment from `s0` that turns `rate` radians
    /// per mm: lowers `top` to where its arcs have turned a half turn.
    fn limit(&self, rate: f64, s0: f64, from: f64, top: &mut f64) {
        if rate > 0.0 {
            let start = s0.max(from);
            *top = top.min(start + (HALF_TURN_RAD - self.turned_rad).max(0.0) / rate);
        }
    }

    /// The turn of the step's arcs up to arc length `s` on a segment from `s0` that turns
    /// `rate` radians per mm.
    fn at(&self, rate: f64, s0: f64, from: f64, s: f64) -> f64 {
        self.turned_rad + rate * (s - s0.max(from)).max(0.0)
    }

    /// The step passes the end `s1` of a segment from `s0` that turns `rate` radians per mm.
    fn pass(&mut self, rate: f64, (s0, s1): (f64, f64), from: f64) {
        self.turned_rad += rate * (s1 - s0.max(from)).max(0.0);
    }
}

/// What `Interpolator::box_corner_cap` reads of a walk: the junctions the step crosses, and
/// the arcs' turn Φ up to the farthest setpoint found (radians).
#[derive(Clone, Copy, Debug)]
struct Bend {
    accuracy: Accuracy,
    phi_rad: f64,
}

impl Bend {
    const NONE: Bend = Bend {
        accuracy: Accuracy::NONE,
        phi_rad: 0.0,
    };
}

/// The turn of segment `seg` per mm of its arc length, radians (0 on a line).
fn turn_per_mm(seg: &Segment) -> f64 {
    match seg.path {
        SegPath::Arc { sweep_rad, .. } if seg.length_mm > 0.0 => sweep_rad.abs() / seg.length_mm,
        _ => 0.0,
    }
}

impl Interpolator {
    fn start_of(&self, k: usize) -> f64 {
        self.seg_start_s_mm[self.idx(k)]
    }

    /// The setpoint at arc length `s` on segment `k`, as `follow` sends it.
    pub(super) fn box_point(&self, k: usize, s: f64) -> AxesMm {
        let seg = self.seg(k);
        let local = s - self.start_of(k);
        if at_end(local, seg.length_mm) {
            seg.path.end()
        } else {
            seg.path.point_at((local / seg.length_mm).max(0.0))
        }
    }

    /// The segment from `k` on that holds arc length `s` (its end counts as on it).
    fn box_seg_at(&self, mut k: usize, s: f64) -> usize {
        // (The start of the next segment is this one's end: the walk reads one array.)
        while k + 1 < self.len && s > self.start_of(k + 1) {
            k += 1;
        }
        k
    }

    /// The junction at arc length `s` on segment `k` (`OnJunction::NONE` off a junction or at
    /// a stop point, which is left from rest).
    fn box_on(&self, k: usize, s: f64) -> OnJunction {
        let at = |j: usize| {
            let i = self.idx(j);
            if self.ahead[i].v_end_mm_s == 0.0 {
                OnJunction::NONE
            } else {
                self.box_slots[i].end
            }
        };
        let local = s - self.start_of(k);
        if at_end(local, self.ahead[self.idx(k)].length_mm) && k + 1 < self.len {
            at(k)
        } else if local <= ARRIVE_EPS_MM && k > 0 {
            at(k - 1)
        } else {
            OnJunction::NONE
        }
    }

    /// Called after each raw step, before `follow` may drop the segment behind: the junction
    /// the raw position lies on, for the next tick.
    pub(super) fn note_box_junction(&mut self) {
        self.box_on = if self.len > 0 {
            self.box_on(self.raw_seg, self.raw_s())
        } else {
            OnJunction::NONE
        };
    }

    /// The next setpoints the box allows after tick `t`, up to arc length `up_to`; with
    /// `feed`, also within the feed (× override) of each segment the step runs on.
    fn box_reach(&self, t: &Tick, up_to: f64, feed: bool) -> Reach {
        self.box_scan(t, up_to, feed, false)
    }

    /// The nearest setpoint the box allows after tick `t` within the feed (`far` is not
    /// looked for).
    fn box_near(&self, t: &Tick) -> Reach {
        self.box_scan(t, f64::INFINITY, true, true)
    }

    /// Where the scan after tick `t` looks: each axis's aim (the setpoint that keeps its
    /// velocity), and the arc lengths no allowed setpoint lies below or above (up to `up_to`).
    fn box_scan_range(&self, t: &Tick, up_to: f64) -> ([f64; MAX_AXES], f64, f64) {
        let x = &t.at;
        let mut aim = [0.0; MAX_AXES];
        let mut step2 = 0.0;
        for ax in 0..self.axes {
            aim[ax] = 2.0 * x[ax] - t.prev[ax];
            step2 += (x[ax] - t.prev[ax]).powi(2);
        }
        // Every allowed setpoint lies within |room| of the aim, which lies the last step's
        // chord ahead: at least that chord less |room| along the path (no shorter than its
        // chord). Segments before that are not looked at. The path acceleration bounds the
        // step from the last one's arc length both ways.
        let path_room = self.box_path_room(t);
        let first_s =
            (t.s + (step2.sqrt() - self.box_room_norm).max(0.0)).max(t.s + t.ds_prev - path_room);
        let path_top = t.s + t.ds_prev + path_room;
        let top = up_to.min(t.s + t.on.crit_mm_s * TS_S).min(path_top);
        (aim, first_s, top)
    }

    fn box_scan(&self, t: &Tick, up_to: f64, feed: bool, near_only: bool) -> Reach {
        let mut bend = Bend::NONE;
        let reach = self.box_walk(t, (up_to, feed, near_only), &mut bend);
        let Reach::Within { near, near_k, far } = reach else {
            return reach;
        };
        let cap = self.box_corner_cap(t, &bend, far);
        if near > cap {
            Reach::Empty
        } else if far <= cap || near_only {
            Reach::Within {
                near,
                near_k,
                far: far.min(cap),
            }
        } else {
            // The allowed setpoints up to the cap: a walk over less, with a turn and corners
            // no larger, whose own cap is no lower.
            let mut again = Bend::NONE;
            self.box_walk(t, (up_to.min(cap), feed, false), &mut again)
        }
    }

    /// Where arcs bend within the step up to `far` (`bend`), the corners it crosses bound its
    /// length (`Accuracy`): at most ε = Lm/(Σw + Φ) past the first corner farther than ε from
    /// the start (∞: no bound). Read only then, from the segments' end junctions.
    fn box_corner_cap(&self, t: &Tick, bend: &Bend, far: f64) -> f64 {
        let a = &bend.accuracy;
        if bend.phi_rad <= 0.0 || a.last.is_none() {
            return f64::INFINITY;
        }
        let eps = a.lm_mm / (a.w_sum + bend.phi_rad);
        let mut k = t.k;
        while k + 1 < self.len && self.start_of(k + 1) < far {
            let s = self.start_of(k + 1);
            if self.box_slots[self.idx(k)].end.half_tan > CORNER_MIN_HALF_TAN && s - t.s > eps {
                return s + eps;
            }
            k += 1;
        }
        f64::INFINITY
    }

    /// `box_scan` without the corners' bound: the reach, and into `bend` what the bound needs.
    fn box_walk(
        &self,
        t: &Tick,
        (up_to, feed, near_only): (f64, bool, bool),
        bend: &mut Bend,
    ) -> Reach {
        let room = &self.box_room;
        let (aim, first_s, mut top) = self.box_scan_range(t, up_to);
        let mut turn = StepTurn::NONE;
        let skipped = self.box_skip(t, first_s, feed, &mut top, (&mut bend.accuracy, &mut turn));
        let Some(mut j) = skipped else {
            return Reach::Unknown;
        };
        let (mut near, mut near_k, mut far) = (f64::NAN, 0, f64::NAN);
        // (The compact tables `ahead` and `box_slots`.)
        let mut slot = self.box_slots[self.idx(j)];
        while j < self.len {
            let i = self.idx(j);
            let ahead = &self.ahead[i];
            if !slot.boxed {
                return Reach::met(near, near_k, far);
            }
            let (s0, seg) = (self.seg_start_s_mm[i], &self.buf[i]);
            let s1 = s0 + ahead.length_mm;
            top = top.min(t.s + self.box_ceiling(ahead, &slot, feed) * TS_S);
            if s0 > top {
                break;
            }
            let last = ahead.v_end_mm_s == 0.0 || j + 1 >= self.len;
            let next = if last {
                slot
            } else {
                self.box_slots[self.idx(j + 1)]
            };
            // A step never ends on the start of a segment the box cannot judge (unless that
            // junction is a stop point): the envelope takes over before it, from a point the
            // box checks (`box_hand_back`).
            let end = if !last && !next.boxed {
                s1 - BOUNDARY_MM
            } else {
                s1
            };
            turn.limit(slot.turn_per_mm, s0, t.s, &mut top);
            let (lo, hi) = (s0.max(t.s).max(first_s), end.min(top));
            let within = match path_within(seg, s0, (lo, hi), &aim[..self.axes], room) {
                Within::Span(lo, hi) => Some((lo, hi)),
                Within::Empty => None,
                // (An arc turned more than the planner allows within a step: never met.)
                Within::Unknown => return Reach::met(near, near_k, far),
            };
            if let Some((lo, hi)) = within {
                bend.phi_rad = turn.at(slot.turn_per_mm, s0, t.s, hi);
                if near.is_nan() {
                    (near, near_k) = (lo, j);
                    if near_only {
                        return Reach::met(near, near_k, hi);
                    }
                }
                far = hi;
            }
            if last || s1 >= top {
                break;
            }
            // Crossing the junction at the end of this segment.
            turn.pass(slot.turn_per_mm, (s0, s1), t.s);
            bend.accuracy.cross(j, &slot.end);
            top = top.min(t.s + slot.end.crit_mm_s * TS_S);
            top = top.min(t.s + self.box_accuracy_reach(t, &bend.accuracy, top - t.s));
            slot = next;
            j += 1;
        }
        if near.is_nan() {
            Reach::Empty
        } else {
            Reach::Within { near, near_k, far }
        }
    }

    /// The speed a step on a segment may reach: its box ceiling, with `feed` within its feed
    /// × override too.
    fn box_ceiling(&self, ahead: &Ahead, slot: &BoxSlot, feed: bool) -> f64 {
        if feed {
            (self.feed_of_ahead(ahead) * self.override_factor).min(slot.v_max_mm_s)
        } else {
            slot.v_max_mm_s
        }
    }

    /// The segments of tick `t` on that end before `first_s` hold no allowed setpoint: a step
    /// that reaches one crosses them whole, so only their ceilings, the criteria of their
    /// end junctions (`accuracy` adds their turns) and the turn of their arcs (`turn`) count,
    /// which lower `top`. Returns the first segment left to look at (`None`: one of them is
    /// not judged by the box), or the one that ends at a stop point.
    fn box_skip(
        &self,
        t: &Tick,
        first_s: f64,
        feed: bool,
        top: &mut f64,
        (accuracy, turn): (&mut Accuracy, &mut StepTurn),
    ) -> Option<usize> {
        let mut k = t.k;
        let (mut fixed, mut feeds) = (f64::INFINITY, f64::INFINITY);
        while k + 1 < self.len && self.start_of(k + 1) <= first_s {
            let i = self.idx(k);
            let slot = &self.box_slots[i];
            if !slot.boxed {
                return None;
            }
            if slot.stop_end {
                // (Never passed: the scan ends on this segment.)
                break;
            }
            accuracy.cross(k, &slot.end);
            let span = (self.start_of(k), self.start_of(k + 1));
            turn.limit(slot.turn_per_mm, span.0, t.s, top);
            turn.pass(slot.turn_per_mm, span, t.s);
            fixed = fixed.min(slot.v_max_mm_s).min(slot.end.crit_mm_s);
            if feed {
                let f = if slot.plain_feed {
                    self.ahead[i].feed_mm_s
                } else {
                    self.feed_of_ahead(&self.ahead[i])
                };
                feeds = feeds.min(f);
            }
            k += 1;
        }
        *top = top.min(t.s + fixed.min(feeds * self.override_factor) * TS_S);
        // (The accuracy's reach from the last junction crossed: the steps that end before it
        // hold no allowed setpoint.)
        *top = top.min(t.s + self.box_accuracy_reach(t, accuracy, *top - t.s));
        Some(k)
    }

    /// The longest step from tick `t` that keeps the junctions it crosses up to
    /// `accuracy.last` within Lm of its chord (`Accuracy`), where a step up to `l_max` could
    /// break it (∞ where not). F is piecewise linear, concave and nondecreasing in L: each
    /// junction's term rises up to L = 2d, then stays; from the last junction on, the walk
    /// goes through those peaks.
    fn box_accuracy_reach(&self, t: &Tick, accuracy: &Accuracy, l_max: f64) -> f64 {
        let Some(last) = accuracy.last else {
            return f64::INFINITY;
        };
        if accuracy.w_sum * 0.5 * l_max <= accuracy.lm_mm {
            return f64::INFINITY;
        }
        let turn = |j: usize| {
            let end = &self.box_slots[self.idx(j)].end;
            let d = self.start_of(j + 1) - t.s;
            let w = if end.half_tan > 0.0 && end.lm_mm.is_finite() && d > 0.0 {
                2.0 * end.half_tan
            } else {
                0.0
            };
            (d, w)
        };
        let d_last = self.start_of(last + 1) - t.s;
        let (mut f, mut slope) = (0.0, 0.0);
        for j in t.k..=last {
            let (d, w) = turn(j);
            f += w * d.min(d_last - d);
            if 2.0 * d > d_last {
                slope += w;
            }
        }
        let mut l = d_last;
        for j in t.k..=last {
            let (d, w) = turn(j);
            if 2.0 * d <= d_last || w == 0.0 {
                continue;
            }
            let at_peak = f + slope * (2.0 * d - l);
            if at_peak > accuracy.lm_mm {
                break;
            }
            (f, l) = (at_peak, 2.0 * d);
            slope -= w;
        }
        if slope <= 1e-300 {
            return f64::INFINITY;
        }
        l + (accuracy.lm_mm - f).max(0.0) / slope
    }

    /// Brakes as hard as the box allows from tick `from` moving on to setpoint `c`, writing
    /// the setpoints after `c` into `path` (the last one where it rests). Returns how it ends
    /// and how many setpoints it wrote.
    fn box_proof(&self, from: &Tick, c: f64, path: &mut [f64]) -> (Proof, usize) {
        let mut t = self.box_tick(from, c);
        for (n, slot) in path.iter_mut().take(PROOF_TICKS).enumerate() {
            match self.box_near(&t) {
                Reach::Within { near, .. } if near <= t.s + 1e-12 => return (Proof::Rest(t.s), n),
                Reach::Within { near, near_k, .. } => {
                    *slot = near;
                    t = Tick {
                        prev: t.at,
                        ds_prev: near - t.s,
                        s: near,
                        k: near_k,
                        at: self.box_point(near_k, near),
                        on: self.box_on(near_k, near),
                    };
                }
                Reach::Empty => return (Proof::Fails, 0),
                Reach::Unknown => return (Proof::Unknown, 0),
            }
        }
        (Proof::Unknown, 0)
    }

    /// The raw position's tick now.
    fn box_here(&self) -> Tick {
        Tick {
            prev: self.box_prev_point,
            ds_prev: self.raw_v_mm_s * TS_S,
            s: self.raw_s(),
            k: self.raw_seg,
            at: self.box_point(self.raw_seg, self.raw_s()),
            on: self.box_on,
        }
    }

    /// The tick at arc length `s` after tick `from`.
    fn box_tick(&self, from: &Tick, s: f64) -> Tick {
        let k = self.box_seg_at(from.k, s);
        Tick {
            prev: from.at,
            ds_prev: s - from.s,
            s,
            k,
            at: self.box_point(k, s),
            on: self.box_on(k, s),
        }
    }

    /// Whether the envelope's setpoint at arc length `s` (on any segment: an arc too) keeps
    /// every axis within its acceleration after tick `t`. The bound is the axes' own (the
    /// box's room plus its slack, to rounding): the envelope accelerates at the very limit,
    /// and the box's narrower room would keep it from ever taking over a speed the box
    /// cannot prove (a braking longer than `PROOF_TICKS`: long lines at high speed).
    fn box_holds_at(&self, t: &Tick, s: f64) -> bool {
        let x = &t.at;
        let k = self.box_seg_at(t.k, s);
        let y = self.box_point(k, s.min(self.start_of(k) + self.seg(k).length_mm));
        let rounding = 1e-9 * self.box_room_norm;
        (s - t.s - t.ds_prev).abs() <= self.box_path_room(t) + rounding
            && (0..self.axes).all(|ax| {
                (y[ax] - (2.0 * x[ax] - t.prev[ax])).abs()
                    <= self.box_room[ax] + BOX_SLACK_MM + rounding
            })
    }

    /// The room for the second difference of the arc length at tick `t`: the path
    /// acceleration of the segment it lies on (of both, on a junction), over a tick.
    fn box_path_room(&self, t: &Tick) -> f64 {
        let room = |k: usize| self.box_slots[self.idx(k)].path_room_mm;
        let here = room(t.k);
        let local = t.s - self.start_of(t.k);
        if at_end(local, self.ahead[self.idx(t.k)].length_mm) && t.k + 1 < self.len {
            here.min(room(t.k + 1))
        } else {
            here
        }
    }

    /// Each axis's room for the second difference of its setpoints, mm (its acceleration
    /// over a tick less the slack), from the segment the raw position lies on.
    fn note_box_room(&mut self) {
        let accel = self.seg(self.raw_seg).axis_box.accel_mm_s2;
        let mut norm2 = 0.0;
        for ax in 0..self.axes {
            let room = accel.axis(ax) * TS_S * TS_S * (1.0 - 1e-9) - BOX_SLACK_MM;
            self.box_room[ax] = room;
            norm2 += room * room;
        }
        self.box_room_norm = norm2.sqrt();
    }

    /// Whether a proof from tick `t` moving on to setpoint `c` can come to rest within
    /// `PROOF_TICKS`: each braking tick shortens the step (a chord) by at most the box's
    /// diagonal `box_room_norm`, and on a line that the braking cannot leave by at most what
    /// the axes along it and the path acceleration allow. Where it cannot, the proof would
    /// end `Unknown` or `Fails`, which leave the envelope alike: not running it keeps a cruise
    /// at high speed at one scan a tick instead of `PROOF_TICKS`.
    fn box_may_rest(&self, t: &Tick, c: f64) -> bool {
        let step = c - t.s;
        let i = self.idx(t.k);
        let seg = &self.buf[i];
        let line_end = self.start_of(t.k) + seg.length_mm;
        let (chord, brake) = match seg.path {
            SegPath::Line { start, end } if line_end >= t.s + step * (PROOF_TICKS as f64 + 2.0) => {
                let mut brake = self.box_slots[i].path_room_mm;
                for ax in 0..self.axes {
                    let per_mm = (end[ax] - start[ax]).abs() / seg.length_mm;
                    if per_mm > 0.0 {
                        brake = brake.min(self.box_room[ax] / per_mm);
                    }
                }
                (step, brake)
            }
            _ => {
                let y = self.box_point(self.box_seg_at(t.k, c), c);
                let step2: f64 = (0..self.axes).map(|ax| (y[ax] - t.at[ax]).powi(2)).sum();
                (step2.sqrt(), self.box_room_norm)
            }
        };
        chord <= PROOF_TICKS as f64 * brake * (1.0 + 1e-6) + 1e-9
    }

    /// The farthest allowed setpoint at most `s` after tick `t`.
    fn box_below(&self, t: &Tick, s: f64) -> Option<f64> {
        match self.box_reach(t, s, true) {
            Reach::Within { far, .. } => Some(far),
            _ => None,
        }
    }

    /// The next setpoint of the last accepted proof's braking (`box_plan`), or the current
    /// one where that braking has come to rest.
    fn box_plan_next(&self, paths: &[f64], here: f64) -> f64 {
        let plan = &self.box_plan;
        if plan.next < plan.len {
            paths[plan.region * PLAN_SLOTS + plan.next]
        } else {
            here
        }
    }

    /// The farthest setpoint up to `want` with a proof it finds, from `lo` (the next setpoint
    /// of the last proof's braking, proven), with `PROOF_RUNS` proofs at most: `want` itself,
    /// else a guess, the fraction `box_guess` of the way from `lo` to `want`, then halving.
    /// The fraction follows what the search finds, so over the ticks of a braking or a curve
    /// the guess lands where the proofs start to fail. Proofs write their braking into the
    /// regions of `paths` other than the plan's.
    fn box_search(&mut self, t: &Tick, lo: f64, want: f64, paths: &mut [f64]) -> Choice {
        let mut choice = Choice {
            s: lo,
            plan: None,
            unknown: false,
        };
        if want <= lo {
            return choice;
        }
        let range = want - lo;
        let mut hi = want;
        // (Three regions: the plan's, the best proof's so far, and the one being written.)
        let live = self.box_plan.region;
        let mut free = [(live + 1) % 3, (live + 2) % 3];
        for run in 0..PROOF_RUNS {
            let m = match run {
                0 => want,
                1 => lo + self.box_guess.clamp(GUESS_MIN, GUESS_MAX) * range,
                _ => 0.5 * (choice.s + hi),
            };
            // (The farthest itself may lie a hair above the plan's next setpoint: a stop point
            // the braking would otherwise miss by micrometres, then creep to.)
            let gain = if run == 0 { 0.0 } else { SEARCH_TOL_MM };
            let Some(c) = self.box_below(t, m).filter(|&c| c > choice.s + gain) else {
                hi = m;
                continue;
            };
            let region = free[0] * PLAN_SLOTS;
            match self.box_proof(t, c, &mut paths[region..region + PLAN_SLOTS]) {
                (Proof::Rest(_), len) => {
                    choice.s = c;
                    choice.plan = Some((free[0], len));
                    free.swap(0, 1);
                    if run == 0 {
                        break;
                    }
                }
                (proof, _) => {
                    choice.unknown |= proof == Proof::Unknown;
                    hi = m;
                }
            }
        }
        // Next time a little above what was found (the proofs may pass there again).
        self.box_guess = ((choice.s - lo) / range + GUESS_STEP).min(1.0);
        choice
    }

    /// Takes `choice`: the plan of its proof, or one more setpoint of the plan.
    fn box_take(&mut self, choice: &Choice) {
        match choice.plan {
            Some((region, len)) => {
                self.box_plan = Plan {
                    region,
                    len,
                    next: 0,
                }
            }
            None => self.box_plan.next = (self.box_plan.next + 1).min(self.box_plan.len),
        }
    }

    /// The raw step of this tick by the box, before the envelope is computed: `Some(ds)`
    /// where the box decides alone, `None` where the envelope's step stands or must be seen
    /// first (`box_hand_back`).
    ///
    /// Outside box mode the box takes over where the farthest setpoint within the feed has a
    /// proof: the envelope's step is within the box and the feed, so it is never farther.
    /// In box mode the box searches up from the next setpoint of the last accepted proof's
    /// braking, which keeps a proof however the search goes (the proof was run from this
    /// very state, so its setpoints are taken as it found them, not found again); where a
    /// proof met a segment the box cannot judge (an arc ahead), the envelope is computed and
    /// may take over.
    pub(super) fn box_step(&mut self, braking: bool) -> Option<f64> {
        self.box_pending = None;
        let departs = std::mem::take(&mut self.box_departs);
        let applies = !self.filtered()
            && self.len > 0
            && !self.seg(self.raw_seg).jerk_mm_s3.is_finite()
            && matches!(
                self.state,
                InterpState::Running | InterpState::Holding | InterpState::Stopping
            )
            && self.box_slots[self.idx(self.raw_seg)].boxed;
        if !applies || self.raw_v_mm_s == 0.0 {
            // At rest every limit of the envelope holds.
            self.box_mode = false;
        }
        if !applies {
            return departs.then_some(0.0);
        }
        self.note_box_room();
        // (Taken out for the proofs to write into while they read the buffer; an empty boxed
        // slice in the meantime, which does not allocate.)
        let mut paths = std::mem::take(&mut self.box_paths);
        let step = self.box_step_with(braking, &mut paths);
        self.box_paths = paths;
        if departs && step.is_none() && !self.entry_cap_mm_s.is_finite() {
            // Left right after the box's arrival, but the box takes no step: the envelope
            // may not either (its departure cap does not allow one), so the path rests this
            // tick.
            return Some(0.0);
        }
        step
    }

    fn box_step_with(&mut self, braking: bool, paths: &mut [f64]) -> Option<f64> {
        let here = self.box_here();
        let lo = if self.box_mode {
            self.box_plan_next(paths, here.s)
        } else {
            here.s
        };
        // Within the feed: the farthest setpoint it allows, or the proven one (the feed or
        // its override fell: braking as hard as the box allows approaches it).
        let far = match self.box_reach(&here, f64::INFINITY, true) {
            Reach::Within { far, .. } => far.max(lo),
            _ => lo,
        };
        let want = if braking {
            let stop_a = self.seg(self.raw_seg).stop_accel_mm_s2;
            let gentle = here.s + self.raw_v_mm_s * TS_S - stop_a * TS_S * TS_S;
            self.box_below(&here, gentle.clamp(lo, far))
                .unwrap_or(lo)
                .max(lo)
        } else {
            far
        };
        if !self.box_mode {
            if want <= here.s + SEARCH_TOL_MM || !self.box_may_rest(&here, want) {
                return None;
            }
            let region = (self.box_plan.region + 1) % 3;
            let out = &mut paths[region * PLAN_SLOTS..(region + 1) * PLAN_SLOTS];
            let (Proof::Rest(_), len) = self.box_proof(&here, want, out) else {
                return None;
            };
            self.box_mode = true;
            self.box_plan = Plan {
                region,
                len,
                next: 0,
            };
            return Some(want - here.s);
        }
        let choice = self.box_search(&here, lo, want, paths);
        if choice.unknown {
            self.box_pending = Some(choice);
            return None;
        }
        self.box_take(&choice);
        Some(choice.s - here.s)
    }

    /// In box mode, where a proof met a segment the box cannot judge: the envelope, whose
    /// step is `envelope_ds` and hard and soft limits `limits_mm_s`, takes over where it goes
    /// farther, allows the current speed and its setpoint is inside the box (`None`); else
    /// the box's step stands.
    pub(super) fn box_hand_back(
        &mut self,
        envelope_ds: f64,
        limits_mm_s: (f64, f64),
    ) -> Option<f64> {
        let (hard_mm_s, soft_mm_s) = limits_mm_s;
        let choice = self.box_pending.take()?;
        let c = choice.s;
        let here = self.box_here();
        let envelope_s = here.s + envelope_ds;
        // (Within its soft limit too: the feed of a segment ahead the box cannot judge is
        // then still met, the envelope braking for it as it plans.)
        if envelope_s > c + SEARCH_TOL_MM
            && hard_mm_s.min(soft_mm_s) >= self.raw_v_mm_s
            && self.box_holds_at(&here, envelope_s)
        {
            self.box_mode = false;
            return None;
        }
        self.box_take(&choice);
        Some(c - here.s)
    }
}

/// Whether arc length `local` on a segment of length `length_mm` is its end, as sent (a
/// setpoint this close snaps to the end point).
fn at_end(local: f64, length_mm: f64) -> bool {
    local >= length_mm - ARRIVE_EPS_MM
}

/// Where on a segment every axis is within its room of its aim.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Within {
    /// From the nearest such arc length to the farthest (an arc may have gaps between).
    Span(f64, f64),
    Empty,
    /// An arc the scan would meet in more than `ARC_PIECES` monotone pieces.
    Unknown,
}

/// Monotone pieces (quarter turns) of an arc one scan looks at, at most: a step turns at most
/// a half turn (`StepTurn`), three quarters.
const ARC_PIECES: usize = 8;

/// The part of `[lo, hi]` (arc length on segment `seg`, which starts at `s0`) where every
/// axis is within `room` of `aim`: exact on a line and on an arc.
fn path_within(
    seg: &Segment,
    s0: f64,
    (lo, hi): (f64, f64),
    aim: &[f64],
    room: &[f64; MAX_AXES],
) -> Within {
    if lo > hi {
        return Within::Empty;
    }
    match seg.path {
        SegPath::Line { .. } => match line_within(seg, s0, (lo, hi), aim, room, None) {
            Some((lo, hi)) => Within::Span(lo, hi),
            None => Within::Empty,
        },
        SegPath::Arc { .. } => arc_within(seg, s0, (lo, hi), aim, room),
    }
}

/// The part of `[lo, hi]` (arc length on `seg`, which starts at `s0`) where every axis that
/// moves linearly with the arc length (all on a line; on an arc those outside its plane,
/// `skip`) is within `room` of `aim`.
fn line_within(
    seg: &Segment,
    s0: f64,
    (mut lo, mut hi): (f64, f64),
    aim: &[f64],
    room: &[f64; MAX_AXES],
    skip: Option<(usize, usize)>,
) -> Option<(f64, f64)> {
    let (start, end) = (seg.path.start(), seg.path.end());
    for (ax, &aim) in aim.iter().enumerate() {
        if skip.is_some_and(|(a, b)| ax == a || ax == b) {
            continue;
        }
        let d = end[ax] - start[ax];
        let off = aim - start[ax];
        if d == 0.0 {
            if off.abs() > room[ax] {
                return None;
            }
            continue;
        }
        // x(s) = start + d·(s − s0)/length
        let per_mm = d / seg.length_mm;
        let (a, b) = ((off - room[ax]) / per_mm, (off + room[ax]) / per_mm);
        let (a, b) = if per_mm > 0.0 { (a, b) } else { (b, a) };
        lo = lo.max(s0 + a);
        hi = hi.min(s0 + b);
        if lo > hi {
            return None;
        }
    }
    Some((lo, hi))
}

/// `path_within` on an arc: the axes outside its plane as on a line, then the two in it,
/// x_a = c_a + r·cos φ and x_b = c_b + r·sin φ with φ linear in the arc length, piece by
/// piece between the multiples of π/2, where both are monotone and each axis's room is one
/// interval of φ (`cos_within`). The nearest and the farthest of those intervals are kept.
fn arc_within(
    seg: &Segment,
    s0: f64,
    (lo, hi): (f64, f64),
    aim: &[f64],
    room: &[f64; MAX_AXES],
) -> Within {
    let SegPath::Arc {
        center,
        plane,
        radius_mm: r,
        start_angle_rad: a0,
        sweep_rad,
        ..
    } = seg.path
    else {
        unreachable!("arc_within on a line");
    };
    let (a, b) = plane.axes();
    let Some((lo, hi)) = line_within(seg, s0, (lo, hi), aim, room, Some((a, b))) else {
        return Within::Empty;
    };
    if sweep_rad == 0.0 || seg.length_mm <= 0.0 {
        return Within::Unknown;
    }
    // φ(s) = a0 + rate·(s − s0); pieces are walked in φ, increasing.
    let rate = sweep_rad / seg.length_mm;
    let phi = |s: f64| a0 + rate * (s - s0);
    let s_of = |p: f64| s0 + (p - a0) / rate;
    let (p_lo, p_hi) = if rate > 0.0 {
        (phi(lo), phi(hi))
    } else {
        (phi(hi), phi(lo))
    };
    let quarter = std::f64::consts::FRAC_PI_2;
    let mut from = p_lo;
    let mut spans = 0;
    let (mut near, mut far) = (f64::INFINITY, f64::NEG_INFINITY);
    while from <= p_hi {
        if spans == ARC_PIECES {
            return Within::Unknown;
        }
        spans += 1;
        let to = (((from / quarter).floor() + 1.0) * quarter).min(p_hi);
        let mut piece = Some((from, to));
        for (ax, shift) in [(a, 0.0), (b, quarter)] {
            piece = piece.and_then(|p| cos_within(p, shift, center[ax], r, aim[ax], room[ax]));
        }
        if let Some((p0, p1)) = piece {
            let (s_a, s_b) = (s_of(p0).clamp(lo, hi), s_of(p1).clamp(lo, hi));
            near = near.min(s_a.min(s_b));
            far = far.max(s_a.max(s_b));
        }
        if to >= p_hi {
            break;
        }
        from = to;
    }
    if near <= far {
        Within::Span(near, far)
    } else {
        Within::Empty
    }
}

/// The part of `[p0, p1]` (angles within one quarter turn, where cos(φ − shift) is
/// monotone) where c + r·cos(φ − shift) lies within `room` of `aim`.
fn cos_within(
    (p0, p1): (f64, f64),
    shift: f64,
    c: f64,
    r: f64,
    aim: f64,
    room: f64,
) -> Option<(f64, f64)> {
    let u_lo = ((aim - room - c) / r).max(-1.0);
    let u_hi = ((aim + room - c) / r).min(1.0);
    if u_lo > u_hi {
        return None;
    }
    // θ = φ − shift lies in [2πk, 2πk + π] (cos falling) or [2πk − π, 2πk] (rising).
    let mid = 0.5 * (p0 + p1) - shift;
    let k = (mid / std::f64::consts::TAU).round() * std::f64::consts::TAU;
    let (t0, t1) = if mid - k >= 0.0 {
        (k + u_hi.acos(), k + u_lo.acos())
    } else {
        (k - u_lo.acos(), k - u_hi.acos())
    };
    let (lo, hi) = (p0.max(t0 + shift), p1.min(t1 + shift));
    (lo <= hi).then_some((lo, hi))
}
