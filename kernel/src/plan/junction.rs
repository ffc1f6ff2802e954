//! Finalizing a junction (SPEC §7.2): the criteria speed at the end of a block, the choice
//! between passing a corner and stopping there, the block's acceleration budget and its R395
//! ceiling. `Planner::finalize` runs these steps in order; each is a function of its own.

use super::budget::{JunctionTurns, LineBudget};
use super::near::{AbsTurns, NearJunction};
use super::{
    BoxAccel, BoxJerk, NORMAL_SHARE, OVERRIDE_MAX, Pending, Planner, Profile, SegPath, Segment,
    criteria, junction_of,
};
use crate::units::{AxesMm, MAX_AXES, TS_S};

/// Share of each axis's acceleration the normal acceleration of the turns may take at a
/// junction's cap in the linear profile (issue #32); the rest is the floor of the
/// tangential acceleration of the lines beside it, so braking never stalls. (0.85 gains up
/// to 1.2 % on the dense paths over 0.8; its cost, the interpolator's tick p99 on the dense
/// circle 58.4 k → 71.3 k instructions, is within the 10 µs allowed, and the half share's
/// search no longer runs where it cannot win (`own_turn_cap`); from 0.87 on the random
/// splines lose: docs/planner.md, *The share*.)
pub const BOX_NORMAL_SHARE: f64 = 0.85;

/// How much of the axes' path acceleration a block may use along the path.
enum Share {
    /// A fixed fraction of `a_axes`.
    Fixed(f64),
    /// A line between turning junctions: a [`LineBudget`].
    Line,
}

/// What the curvature window of a junction is checked against (SPEC §7.2 criteria applied to
/// the turn within one tick, and in the parabolic profile the axis filter's corner budgets).
struct WindowLimits {
    /// Normal share of the smallest axis acceleration of the axes involved, mm/s².
    a_iso: f64,
    /// Dynamic criterion am (R385), mm/s².
    am: f64,
    /// Share of each axis's acceleration the turns may take (box rule).
    share: f64,
    /// Accuracy criterion Lm, µm (0 = off).
    lm_um: f64,
    /// Axis filter time T (0 without the filter), s.
    t_f: f64,
    /// Path acceleration next to the corner (parabolic corner jerk term), mm/s².
    a_corner: f64,
    jerk_budget: [f64; MAX_AXES],
    accel_budget: [f64; MAX_AXES],
}

/// Largest speed in [0, v] within `bound` (bound(v) ≥ v), to 0.2 % (far below the spread of
/// the other criteria): a speed `lo` within its bound with one above it, `hi` ≤ lo/0.998,
/// that is not. `v` itself when it is within its bound. Returns the speed and whether a
/// search ran; 0 once `give_up(hi)` holds for a speed `hi` the result cannot exceed.
///
/// The probes follow the bound's own value: where the bound is flat around the crossing (the
/// same tangents within the tick window, as on the chords of a curve) that value is the
/// crossing, so 0.999 of it is within and 1.0019 times that is not, which ends the search.
/// `guess_mm_s` (the previous junction's crossing: neighbouring junctions of a dense path
/// have similar limits) is the first estimate. After a few probes, or without an estimate
/// inside the bracket, bisection (the bound need not be flat).
fn largest_within(
    v: f64,
    guess_mm_s: f64,
    bound: impl Fn(f64) -> f64,
    give_up: impl Fn(f64) -> bool,
) -> (f64, bool) {
    if give_up(v) {
        return (0.0, false);
    }
    let within_v = |b: f64| b >= v * (1.0 - 1e-12);
    let first = 0.999 * guess_mm_s;
    let (mut lo, mut hi) = (0.0, v);
    let mut est = if first > 0.0 && first < v {
        let b = bound(first);
        if b >= first {
            lo = first;
        } else {
            hi = first;
        }
        b
    } else {
        let b = bound(v);
        if within_v(b) {
            return (v, false);
        }
        b
    };
    // v needs no probe of its own once it was the first (nothing found within) or a probe
    // below it was not within.
    let mut v_probed = hi < v || lo == 0.0;
    let mut steps = 0;
    while hi - lo > 0.002 * hi && steps < 64 {
        if give_up(hi) {
            return (0.0, true);
        }
        steps += 1;
        let x = if lo > 0.0 && est <= lo * 1.0019 {
            // The crossing lies within 0.19 % above lo: close the bracket there (0.19: the
            // bracket's test must hold with rounding).
            lo * 1.0019
        } else if steps <= 4 && est > lo && est < hi {
            0.999 * est
        } else if !v_probed {
            // Every probe so far was within: v itself may be.
            v_probed = true;
            v
        } else {
            0.5 * (lo + hi)
        };
        let b = bound(x);
        if x == v {
            if within_v(b) {
                return (v, true);
            }
            hi = v;
        } else if b >= x {
            lo = x;
        } else {
            hi = x;
        }
        est = b;
    }
    (lo, true)
}

impl Planner {
    /// Computes the junction at the end of block `i` (all criteria of SPEC §7.2) and the final
    /// limits of block `i` itself.
    pub(super) fn finalize(&mut self, i: usize, last: bool) {
        // The window changed since the last walk near a junction.
        if let Some(near) = self.near.as_mut() {
            near.invalidate();
        }
        let box_rule = !last && self.box_rule(i);
        let (mut crit, mut criteria_cap) = if last {
            (0.0, 0.0)
        } else {
            self.junction_speed(i, BOX_NORMAL_SHARE, None, box_rule)
        };
        let passed = !last && self.win[i].smooth && criteria_cap > 0.0;
        let mut turns = (passed && self.cfg.envelope.profile == Profile::Linear)
            .then(|| self.junction_turns(i, criteria_cap));
        // What passing gains over stopping and what the lines lose, once known.
        let mut net = None;
        if passed && box_rule {
            // The per-axis box lets the turn take nearly all of an axis; the lines beside
            // it then ramp slowly. Where that loses time (long lines that ramp far from
            // the turn's speed) the turn takes half of each axis instead (issue #32).
            let (gain, loss) = self.corner_net_s(i, criteria_cap, turns.as_ref());
            net = Some((gain, loss));
            // (The half share's cap is at most `own_turn_cap`, and its gain rises with the
            // speed: where even that gain cannot beat this share, its search is not run.)
            let may_win = || {
                let upper = self.own_turn_cap(i, NORMAL_SHARE);
                self.pass_gain_s(i, upper).1 > gain - loss
            };
            if loss > 0.05 * gain.max(0.0) && may_win() {
                // The half share wins only if its gain minus its loss (≥ 0) beats this one:
                // its search stops (cap 0) once its gain alone cannot, and then its turns
                // and budgets are not needed (on an alternating zig-zag every junction gets
                // here and never wins).
                let (c, cap) = self.junction_speed(i, NORMAL_SHARE, Some(gain - loss), box_rule);
                if cap > 0.0 && self.pass_gain_s(i, cap).1 > gain - loss {
                    let t = self.junction_turns(i, cap);
                    let (g, l) = self.corner_net_s(i, cap, Some(&t));
                    if g - l > gain - loss {
                        (crit, criteria_cap, turns) = (c, cap, Some(t));
                        net = Some((g, l));
                    }
                }
            }
        }
        let certain_stop = self.win[i].certain_stop;
        // Between two lines the per-axis box may judge, a junction is passed rather than
        // stopped where the envelope's estimate finds stopping faster: the box passes it as
        // fast as the axes allow (a stop is one of the speeds it could choose), and the
        // envelope only runs there from rest (issue #32).
        let boxed_both = !last && self.win[i].box_candidate && self.win[i + 1].box_candidate;
        let planned_stop = !last
            && (certain_stop
                || (!boxed_both && self.corner_is_a_stop(i, criteria_cap, turns.as_ref(), net)));
        let criteria_end = (!last && !planned_stop).then(|| self.box_criteria_end(i));
        let p = &mut self.win[i];
        if planned_stop {
            p.smooth = false;
        }
        p.turns = if planned_stop { None } else { turns };
        p.crit = crit;
        p.cap = if planned_stop { 0.0 } else { criteria_cap };
        // (A certain stop was never smooth here: its criteria speed, as a stop's cap.)
        p.seg.junction_cap_mm_s = if certain_stop { crit } else { criteria_cap };
        let b = &mut p.seg.axis_box;
        (b.criteria_end_mm_s, b.end_half_tan, b.lm_mm) =
            criteria_end.unwrap_or((0.0, 0.0, f64::INFINITY));
        if planned_stop {
            self.rebudget_before(i);
        }
        self.unfilter_isolated_line(i, last);
        self.set_accelerations(i, last);
        self.apply_rise_limit(i);
        let p = &mut self.win[i];
        let drop = self.cfg.envelope.sets[p.set].drop_percent / 100.0;
        p.seg.junction = junction_of(planned_stop, p.smooth && !last, p.cap, drop, &p.seg);
    }

    /// What the per-axis box reads of the passed junction after block `i` (`criteria_alone`
    /// where a line beside it is boxed; nothing to bound otherwise).
    fn box_criteria_end(&self, i: usize) -> (f64, f64, f64) {
        if self.win[i].box_candidate || self.win[i + 1].box_candidate {
            self.criteria_alone(i)
        } else {
            (f64::INFINITY, 0.0, f64::INFINITY)
        }
    }

    /// The manual's criteria alone at the junction after block `i`, without the axes
    /// (`SegmentBox`): the speed R385 (with the 8.R385 correction) and R384 allow, the
    /// junction's turn as tan(α/2), and R384's Lm (mm, ∞ where off).
    fn criteria_alone(&self, i: usize) -> (f64, f64, f64) {
        let (p, n) = (&self.win[i], &self.win[i + 1]);
        let set = &self.cfg.envelope.sets[n.set];
        let len = 0.5 * (p.seg.length_mm + n.seg.length_mm);
        let v = p
            .turn
            .dynamic_len_mm_s(set.overload_mm_s2, set.overload_ref_len_mm, len)
            .min(p.turn.accuracy_mm_s(set.accuracy_um));
        let half_tan = if p.turn.chord <= 1e-12 {
            0.0
        } else {
            p.turn.chord / p.turn.sum
        };
        let lm_mm = if set.accuracy_um > 0.0 {
            set.accuracy_um * 1e-3
        } else {
            f64::INFINITY
        };
        (v, half_tan, lm_mm)
    }

    /// Criteria speed at the end of block `i` as if the junction were smooth, and its hard cap
    /// (0 when it is not smooth): dynamic (R385 with the 8.R385 correction), accuracy (R384),
    /// the ceilings of both blocks, and for a smooth junction the local curvature window.
    /// With `beat_s`, 0 once passing at any speed the search may still find gains no more
    /// than `beat_s` ([`Planner::pass_gain_s`], which rises with the speed).
    /// `box_rule`: [`Planner::box_rule`] of junction `i`.
    fn junction_speed(
        &mut self,
        i: usize,
        share: f64,
        beat_s: Option<f64>,
        box_rule: bool,
    ) -> (f64, f64) {
        let env = &self.cfg.envelope;
        let (p, n) = (&self.win[i], &self.win[i + 1]);
        let set = &env.sets[n.set];
        // Linear profile: the normal acceleration is checked per axis against the whole
        // axis limit over the tick window (`window_bound`, issue #32), so the manual's
        // dynamic criterion keeps only its own am here. Elsewhere the fixed normal share.
        // Under the box rule the lines beside a turn keep what the turn leaves of each axis
        // at the highest speed they run; with the override headroom on top (150 %) that is
        // next to nothing on a curve that allows more than the feed. So a box-rule turn is
        // passed at most at the programmed feed: override above 100 % does not raise the
        // speed through it (issue #32).
        let override_max = if box_rule { 1.0 } else { OVERRIDE_MAX };
        let a_iso = if box_rule {
            f64::INFINITY
        } else {
            self.cfg.iso_accel(&p.t_end, &n.t_start) * NORMAL_SHARE
        };
        let am = set.overload_mm_s2.min(a_iso);
        let len = 0.5 * (p.seg.length_mm + n.seg.length_mm);
        let v = p
            .turn
            .dynamic_len_mm_s(am, set.overload_ref_len_mm, len)
            .min(p.turn.accuracy_mm_s(set.accuracy_um))
            .min(p.seg.v_max_mm_s)
            .min(n.seg.v_max_mm_s)
            .min(override_max * p.seg.feed_mm_s.max(n.seg.feed_mm_s));
        if !p.smooth {
            return (v, 0.0);
        }
        let mut limits = self.window_limits(i, a_iso);
        limits.share = share;
        let guess = if share == BOX_NORMAL_SHARE {
            self.window_guess_mm_s
        } else {
            0.0
        };
        let (v, searched) = if box_rule {
            let near = self.near_junction(i, v);
            // (Not the exact crossing, although the bound is constant over ranges of v where
            // every tangent it looks up stays on the same line: caps at the exact crossing
            // took an axis of the random arcs to 1.0005-1.0011 × its limit; the search's
            // result below it, 0.1 % where the bound is flat, is what the tests hold.)
            let give_up = |hi| beat_s.is_some_and(|b| self.pass_gain_s(i, hi).1 <= b);
            let (found, searched) = largest_within(
                v,
                guess,
                |v| self.box_window_bound(i, v, &limits, &near),
                give_up,
            );
            let found = (found, searched);
            self.near = Some(near);
            found
        } else {
            largest_within(v, guess, |v| self.window_bound(i, v, &limits), |_| false)
        };
        if searched && share == BOX_NORMAL_SHARE {
            // (The search ends 0.1 % below a flat bound's crossing.)
            self.window_guess_mm_s = v / 0.999;
        }
        (v, v)
    }

    fn window_limits(&self, i: usize, a_iso: f64) -> WindowLimits {
        let env = &self.cfg.envelope;
        let (p, n) = (&self.win[i], &self.win[i + 1]);
        let mut jerk_budget = [0.0; MAX_AXES];
        let mut accel_budget = [0.0; MAX_AXES];
        for k in 0..self.cfg.axes {
            jerk_budget[k] = self.cfg.axis_j_max_mm_s3[k] * NORMAL_SHARE;
            accel_budget[k] = self.cfg.axis_a_max_mm_s2[k] * NORMAL_SHARE;
        }
        let a_path = |q: &Pending| env.sets[q.set].accel_mm_s2.min(q.a_axes) * (1.0 - NORMAL_SHARE);
        WindowLimits {
            a_iso,
            am: env.sets[n.set].overload_mm_s2,
            share: BOX_NORMAL_SHARE,
            lm_um: env.sets[n.set].accuracy_um,
            t_f: self.cfg.axis_filter_s(),
            a_corner: a_path(p).max(a_path(n)),
            jerk_budget,
            accel_budget,
        }
    }

    /// Several junctions can fall within one tick: both criteria are applied to the turn over
    /// the path one tick covers at `v` (centred on junction `i`), the local curvature cap
    /// v ≤ √(a/κ) in the form of the dynamic criterion. With the axis smoothing filter
    /// (parabolic profile) the corner share of the axis jerk and acceleration, and half of Lm,
    /// bound what the filter makes of the turns within ±v·T (criteria::FilterWindow); 0 when
    /// `v` breaks them.
    fn window_bound(&self, i: usize, v: f64, l: &WindowLimits) -> f64 {
        let axes = self.cfg.axes;
        let half = v * TS_S / 2.0;
        let t0 = self.tangent_near(i, -half);
        let t1 = self.tangent_near(i, half);
        let turn = criteria::Turn::between(&t0, &t1, axes);
        if l.t_f > 0.0 {
            let h = v * l.t_f;
            let w = criteria::FilterWindow {
                before: self.tangent_near(i, -h),
                end: self.win[i].t_end,
                start: self.win[i + 1].t_start,
                after: self.tangent_near(i, h),
            };
            let lm_half_mm = l.lm_um * 1e-3 / 2.0;
            // The offset the turns within reach give the setpoints, where no arc is there;
            // the window's own bound otherwise.
            let offset_mm = self.filter_offset_mm(i, v, l.t_f);
            let window_lm_mm = if offset_mm.is_some() { 0.0 } else { lm_half_mm };
            if !w.allows(
                v,
                l.a_corner,
                l.t_f,
                axes,
                &l.jerk_budget,
                &l.accel_budget,
                window_lm_mm,
            ) || (lm_half_mm > 0.0 && offset_mm.is_some_and(|o| o > lm_half_mm))
            {
                return 0.0;
            }
        }
        turn.dynamic_mm_s(l.a_iso).min(turn.accuracy_mm_s(l.lm_um))
    }

    /// Largest distance of the axis filter's setpoints from the path around junction `i` at
    /// speed `v`, mm; None where an arc lies within the filter's reach (the window's own
    /// bound, `FilterWindow::allows`, holds there). The setpoints average the path positions
    /// of ±T with triangular weights (no wider in the 4 ms ticks); centred at the junction, a
    /// turn Δ_j at distance d_j moves the average off the path by at most |Δ_j|·v·w(d_j/v),
    /// w(τ) = (T − τ)³/(6·T²) the weights' mean excess beyond τ. So the sum bounds it: v·|Δ|·T/6
    /// for a corner alone, v²T²/(12R) on a curve of radius R, half of what the window's
    /// largest turn taken as one corner gave there. w is convex, so between two junctions the
    /// distance is largest at one of them, and each junction checks its own.
    fn filter_offset_mm(&self, i: usize, v: f64, t_f: f64) -> Option<f64> {
        let h = v * t_f;
        let w = |d: f64| (t_f - (d / v).min(t_f)).powi(3) / (6.0 * t_f * t_f);
        let is_arc = |k: usize| matches!(self.win[k].seg.path, SegPath::Arc { .. });
        let mut sum = self.win[i].turn.chord * w(0.0);
        // Behind: junction k − 1 lies at the start of block k.
        let (mut k, mut d) = (i, 0.0);
        loop {
            if is_arc(k) {
                return None;
            }
            d += self.win[k].seg.length_mm;
            if d >= h || k == 0 || !self.win[k - 1].smooth {
                break;
            }
            k -= 1;
            sum += self.win[k].turn.chord * w(d);
        }
        // Ahead: junction k lies at the end of block k.
        let (mut k, mut d) = (i + 1, 0.0);
        loop {
            if is_arc(k) {
                return None;
            }
            d += self.win[k].seg.length_mm;
            if d >= h || k + 1 >= self.win.len() || !self.win[k].smooth {
                break;
            }
            sum += self.win[k].turn.chord * w(d);
            k += 1;
        }
        Some(v * sum)
    }

    /// Whether junction `i` takes its normal acceleration from the per-axis box (issue #32):
    /// linear profile, lines on both sides whose neighbours are lines too (arcs and the
    /// lines next to them keep the fixed split of `tangential_share`), axes with finite
    /// limits. The block after the next must be known (it decides whether the next line
    /// is next to an arc).
    pub(super) fn box_rule(&self, i: usize) -> bool {
        if self.cfg.envelope.profile != Profile::Linear {
            return false;
        }
        let is_line =
            |q: &Pending| matches!(q.seg.path, SegPath::Line { .. }) && q.a_axes.is_finite();
        let (p, n) = (&self.win[i], &self.win[i + 1]);
        if !is_line(p) || !is_line(n) {
            return false;
        }
        if i > 0 && self.win[i - 1].smooth && !is_line(&self.win[i - 1]) {
            return false;
        }
        match self.win.get(i + 2) {
            Some(q) => !n.smooth || is_line(q),
            None => self.closed(),
        }
    }

    /// The per-axis form of the curvature criterion (linear profile, issue #32): over the
    /// tick window around junction `i` at speed `v`, per axis k
    /// - the normal acceleration v_ref·T_k/Ts (the turns of [`Planner::junction_turns`],
    ///   v_ref = v + A·Ts) within `BOX_NORMAL_SHARE` of a_k: constant speed on constant
    ///   curvature needs no tangential budget, and the lines beside it keep what is left
    ///   ([`LineBudget`], at least the floor of the other share);
    /// - the dynamic criterion R385 on the velocity step of each axis, v·|Θ_k| ≤ am·Ts
    ///   (**decided**: am is an axis acceleration; at the junction itself the manual's
    ///   formula on the norm holds as well);
    /// - the accuracy criterion on the chord of a tick: v·Ts·|Θ|/4 ≤ Lm (a tick chord of
    ///   v·Ts across a turn Θ misses its apex by at most v·Ts·sin(Θ/2)/2).
    ///
    /// Θ = t(+h) − t(−h), h = v_ref·Ts/2. The tangents come from the walk `near`, which
    /// keeps the turns with the range of h over which they are the same, for the search's
    /// later speeds and [`Planner::junction_turns`] at the speed it settles on.
    fn box_window_bound(&self, i: usize, v: f64, l: &WindowLimits, near: &NearJunction) -> f64 {
        // (A fresh lookup is kept in `near`: the search's next speeds, and its result, are
        // likely in its piece.)
        let (t, window, complete, _) = self.turns_and_window(i, v, near, true);
        if !complete {
            // (Not reached: the walk covers 2h of the search's highest speed.)
            return 0.0;
        }
        self.box_bound(&t, &window, v, l)
    }

    /// The bound of [`Planner::box_window_bound`] for these turns and window at `v`.
    fn box_bound(&self, t: &JunctionTurns, window: &AxesMm, v: f64, l: &WindowLimits) -> f64 {
        let axes = self.cfg.axes;
        let a_ts = t.v_turn_mm_s - v;
        let mut bound = f64::INFINITY;
        // (Plain comparisons, as `min` treats a NaN term: the bound starts at ∞, never NaN.)
        let mut lower = |x: f64| {
            if x < bound {
                bound = x;
            }
        };
        // (The turns' dir is not needed here: `junction_turns` adds it.)
        for k in 0..axes {
            let turn = t.normal_per_s[k] * TS_S;
            if turn > 1e-12 {
                // v_turn·(turn − own) + v·own ≤ share·a_k·Ts: the ticks touching the
                // junction may run one acceleration step faster than v, but the steps that
                // carry its own turn are within v (`JunctionTurns::own_per_s`).
                let a_k = self.cfg.axis_a_max_mm_s2[k] * l.share;
                let others = (1.0 - t.own_per_s[k] * TS_S / turn).max(0.0);
                lower(a_k * TS_S / turn - a_ts * others);
            }
            let w = window[k].abs();
            if w > 1e-12 {
                lower(l.am * TS_S / w);
            }
        }
        let chord = window.norm(axes);
        if l.lm_um > 0.0 && chord > 1e-12 {
            lower(4.0 * l.lm_um * 1e-3 / (TS_S * chord));
        }
        bound
    }

    /// A line from a stop to a stop runs without the axis smoothing filter (parabolic
    /// profile): the filter smooths the turns of a continuous path, and along one line each
    /// axis follows the path's own jerk, so it would only add 2(n − 1) ticks to the move
    /// (issue #49). The interpolator changes the filter at the stop, at rest.
    fn unfilter_isolated_line(&mut self, i: usize, last: bool) {
        let starts_at_stop = !(i > 0 && self.win[i - 1].smooth);
        let p = &mut self.win[i];
        let ends_at_stop = last || !p.smooth;
        if starts_at_stop && ends_at_stop && matches!(p.seg.path, SegPath::Line { .. }) {
            p.seg.axis_filter_ticks = 1;
        }
    }

    /// What the jerk-limited box reads of block `i` (parabolic profile, where the box may
    /// judge it): the axes' jerks; the path acceleration `accel_mm_s2` and the path jerk,
    /// each within the lowest axis's (so within the axes along any line: the box need not
    /// compute the axes where its setpoints run on one line, and a braking is the same
    /// whichever way the path turns); and half R384's Lm.
    fn box_jerk_of(&self, i: usize, accel_mm_s2: f64) -> BoxJerk {
        let env = &self.cfg.envelope;
        let axes = self.cfg.axes.max(1);
        let lowest = |v: &[f64]| v[..axes].iter().fold(f64::INFINITY, |m, x| m.min(*x));
        let accel_mm_s2 = accel_mm_s2.min(lowest(&self.cfg.axis_a_max_mm_s2));
        let boxed = self.win[i].box_candidate && accel_mm_s2 > 0.0 && accel_mm_s2.is_finite();
        if env.profile != Profile::Parabolic || !boxed {
            return BoxJerk::default();
        }
        let p = &self.win[i];
        let path_j = self
            .path_jerk_of(p.seg.rapid, p.set, p.j_axes)
            .min(lowest(&self.cfg.axis_j_max_mm_s3));
        let lm_um = env.sets[p.set].accuracy_um;
        let off_mm = if lm_um > 0.0 {
            0.5 * lm_um * 1e-3
        } else {
            f64::INFINITY
        };
        BoxJerk::of_axes(&self.cfg.axis_j_max_mm_s3, (accel_mm_s2, path_j), off_mm)
    }

    /// Acceleration of block `i` (feed, and stop/hold): R52 without continuity, R236 (or the
    /// set's A) during continuity, R237 for rapids, capped by the axes it moves. Where the
    /// path turns, part of every axis's acceleration is taken by the normal acceleration;
    /// see [`Planner::tangential_share`]. A line between turning junctions (linear profile)
    /// keeps its [`LineBudget`]: the backward pass and the commit give it the acceleration of
    /// the speeds it actually runs at.
    fn set_accelerations(&mut self, i: usize, last: bool) {
        let env = &self.cfg.envelope;
        let prev_smooth = i > 0 && self.win[i - 1].smooth;
        let p = &self.win[i];
        let set_a = env.sets[p.set].accel_mm_s2;
        let base = if p.seg.rapid {
            env.accel_rapid_mm_s2.min(env.rapid_accel_mm_s2)
        } else if prev_smooth || p.smooth {
            set_a
        } else {
            env.accel_stop_mm_s2.min(set_a)
        };
        let rapid_a = env.rapid_accel_mm_s2;
        let (a_axes, j_axes) = (p.a_axes, p.j_axes);
        let (share, budget) = match self.tangential_share(i, last) {
            Share::Fixed(share) => (share, None),
            Share::Line => (1.0, Some(self.line_budget(i, base))),
        };
        let linear_line = self.cfg.envelope.profile == Profile::Linear
            && matches!(self.win[i].seg.path, SegPath::Line { .. });
        let box_accel = if self.win[i].box_candidate && a_axes.is_finite() {
            BoxAccel::of_axes(&self.cfg.axis_a_max_mm_s2, base)
        } else {
            BoxAccel::NONE
        };
        let box_jerk = self.box_jerk_of(i, box_accel.path());
        let p = &mut self.win[i];
        p.seg.axis_box.accel_mm_s2 = box_accel;
        p.seg.axis_box.jerk = box_jerk;
        p.budget = budget;
        // Ticks inside a line see no turn (`Segment::free_accel_mm_s2`).
        (p.seg.free_accel_mm_s2, p.seg.free_accel_v_max_mm_s) = if linear_line && a_axes.is_finite()
        {
            (base.min(a_axes), f64::INFINITY)
        } else {
            (0.0, 0.0)
        };
        if let Some(b) = budget {
            p.apply_budget(&b, f64::INFINITY, rapid_a);
            return;
        }
        p.seg.accel_mm_s2 = base.min(a_axes * share);
        if share < 1.0 && p.seg.axis_filter_ticks > 1 {
            // The rest of the axis jerk is for the turns the axis filter smooths.
            p.seg.jerk_mm_s3 = p.seg.jerk_mm_s3.min(j_axes * share);
        }
        p.seg.stop_accel_mm_s2 = rapid_a.min(a_axes * share);
        if p.seg.stop_accel_mm_s2 <= 0.0 || !p.seg.stop_accel_mm_s2.is_finite() {
            p.seg.stop_accel_mm_s2 = p.seg.accel_mm_s2;
        }
    }

    /// Junction `i` has just become a stop: the junctions before it measured their turns
    /// across it (as if it were passed); they and the budgets of their lines are measured
    /// again.
    fn rebudget_before(&mut self, i: usize) {
        let mut first = i;
        let mut dist = 0.0;
        while first > self.emitted {
            let k = first - 1;
            dist += self.win[k + 1].seg.length_mm;
            let Some(t) = self.win[k].turns else { break };
            // Tangents were looked up to 3h = 1.5·v_ref·Ts past the junction.
            if dist > 1.5 * t.v_ref_mm_s * TS_S {
                break;
            }
            let cap = self.win[k].cap;
            self.win[k].turns = Some(self.junction_turns(k, cap));
            first = k;
        }
        let rapid_a = self.cfg.envelope.rapid_accel_mm_s2;
        for k in first..i {
            let Some(b) = self.win[k].budget else {
                continue;
            };
            let b = self.line_budget(k, b.base_mm_s2());
            let p = &mut self.win[k];
            p.budget = Some(b);
            p.apply_budget(&b, f64::INFINITY, rapid_a);
        }
    }

    /// Fraction of the path acceleration of the axes (`a_axes`) block `i` may use along the
    /// path. 1 where the path does not turn at a smooth junction of the block. On arcs, next
    /// to arcs and in the parabolic profile: 1 − NORMAL_SHARE (the normal acceleration takes
    /// at most NORMAL_SHARE of the smallest axis acceleration, **decided**). On lines between
    /// turning junctions in the linear profile, per axis what the normal acceleration of the
    /// turns leaves at the speed the line runs ([`Planner::line_budget`]), never less than
    /// that split.
    fn tangential_share(&self, i: usize, last: bool) -> Share {
        let is_arc = |q: &Pending| matches!(q.seg.path, SegPath::Arc { .. });
        let prev_smooth = i > 0 && self.win[i - 1].smooth;
        let p = &self.win[i];
        let next_smooth = p.smooth && !last;
        let arcs = is_arc(p)
            || (next_smooth && is_arc(&self.win[i + 1]))
            || (prev_smooth && is_arc(&self.win[i - 1]));
        // A junction turns the path where it turns itself or where its turns see a turn
        // within a tick's step of it (a straight junction beside a short turning block: the
        // tick after both weighs their turns; issue #32).
        let turns = |q: &Pending| {
            q.turn.chord > 1e-9
                || q.turns
                    .is_some_and(|t| t.normal_per_s.iter().any(|&n| n > 0.0))
        };
        let turning = (prev_smooth && turns(&self.win[i - 1])) || (next_smooth && turns(p));
        if !arcs && !turning {
            return Share::Fixed(1.0);
        }
        let split = 1.0 - NORMAL_SHARE;
        if arcs || self.cfg.envelope.profile != Profile::Linear || !p.a_axes.is_finite() {
            return Share::Fixed(split);
        }
        Share::Line
    }

    /// Tangential acceleration on line block `i` as a function of its highest speed
    /// ([`LineBudget`]): per axis k, a_t·|u_k| + N_k(v) ≤ a_k over the turns of the junctions
    /// it passes (`Pending::turns`, [`Planner::junction_turns`]). This is the per-axis form of
    /// the local curvature criterion that bounds the junction speed (|N| ≤ NORMAL_SHARE·a_iso
    /// at the cap). `base`: the constants' path acceleration.
    pub(super) fn line_budget(&self, i: usize, base: f64) -> LineBudget {
        let (start, end) = self.line_turns(i);
        self.budget_between(i, start, end, base)
    }

    /// The turns of line block `i`'s start and end junctions (None: a stop there).
    fn line_turns(&self, i: usize) -> (Option<&JunctionTurns>, Option<&JunctionTurns>) {
        let start = (i > 0 && self.win[i - 1].smooth)
            .then(|| self.win[i - 1].turns.as_ref())
            .flatten();
        let end = if self.win[i].smooth {
            self.win[i].turns.as_ref()
        } else {
            None
        };
        (start, end)
    }

    /// The budget of line block `i` between junctions with these turns (None: a stop).
    fn budget_between(
        &self,
        i: usize,
        start: Option<&JunctionTurns>,
        end: Option<&JunctionTurns>,
        base: f64,
    ) -> LineBudget {
        let axes = self.cfg.axes;
        let (dir, floor) = self.line_dirs(i, start, end);
        let mut b = LineBudget::new(self.win[i].a_axes, floor, base);
        let mut normal = [[0.0f64; 2]; MAX_AXES];
        let mut half = [[0.0f64; 2]; MAX_AXES];
        for (e, t) in [start, end].into_iter().enumerate() {
            if let Some(t) = t {
                b.set_v_ref(e, t.v_turn_mm_s);
                for k in 0..axes {
                    normal[k][e] = t.normal_per_s[k];
                    half[k][e] = t.half_per_s[k];
                }
            }
        }
        for k in 0..axes {
            b.add_axis(self.cfg.axis_a_max_mm_s2[k], dir[k], normal[k], half[k]);
        }
        b
    }

    /// `budget_between(i, start, end, base).accel_at(∞)` without building the budget: the
    /// acceleration the line keeps with every junction at its cap (the pass-or-stop
    /// estimate's), mm/s².
    fn accel_at_caps(
        &self,
        i: usize,
        start: Option<&JunctionTurns>,
        end: Option<&JunctionTurns>,
        base: f64,
    ) -> f64 {
        let (dir, floor) = self.line_dirs(i, start, end);
        let mut a = f64::INFINITY;
        for (k, &d) in dir.iter().enumerate().take(self.cfg.axes) {
            if d <= 1e-12 {
                continue;
            }
            let p = self.cfg.axis_a_max_mm_s2[k] / d;
            for t in [start, end].into_iter().flatten() {
                let x = p - t.normal_per_s[k] / d * t.v_turn_mm_s;
                if x < a {
                    a = x;
                }
            }
            if p < a {
                a = p;
            }
        }
        base.min(a.min(self.win[i].a_axes).max(floor))
    }

    /// Per axis the largest tangent component the ticks on line block `i` and near its
    /// junctions with these turns move along, and the budget's floor: what the normal
    /// acceleration leaves on every axis at any junction's cap (`box_window_bound`; the
    /// fixed split leaves more), mm/s².
    fn line_dirs(
        &self,
        i: usize,
        start: Option<&JunctionTurns>,
        end: Option<&JunctionTurns>,
    ) -> ([f64; MAX_AXES], f64) {
        // (Plain comparisons: every value here is finite and ≥ 0, and the NaN-aware max and
        // min cost a third of this function, which runs five times per line.)
        let larger = |a: f64, b: f64| if b > a { b } else { a };
        let axes = self.cfg.axes;
        let p = &self.win[i];
        let mut dir = [0.0f64; MAX_AXES];
        for (k, d) in dir.iter_mut().enumerate().take(axes) {
            *d = larger(p.t_start[k].abs(), p.t_end[k].abs());
        }
        for t in [start, end].into_iter().flatten() {
            for (d, &td) in dir.iter_mut().zip(&t.dir).take(axes) {
                *d = larger(*d, td);
            }
        }
        let mut floor = p.a_axes;
        for (&d, &a_max) in dir.iter().zip(&self.cfg.axis_a_max_mm_s2).take(axes) {
            if d > 1e-12 && a_max / d < floor {
                floor = a_max / d;
            }
        }
        (dir, (1.0 - BOX_NORMAL_SHARE) * floor)
    }

    /// The turns near junction `j` passed at `cap`, per axis: N_k(v) = min(v, v_ref)·T_k/Ts
    /// with T_k the turn of the tangent within the tick window (h = v_ref·Ts/2) and v_ref =
    /// cap + A·Ts the fastest a tick touching the junction runs (A the larger path
    /// acceleration of the two blocks); and the tangent components the ticks near it move
    /// along. Looked up once per junction for the lines on both sides.
    pub(super) fn junction_turns(&mut self, j: usize, cap: f64) -> JunctionTurns {
        let near = self.near_junction(j, cap);
        // (`near_junction` walked 2h at `cap`: the absolute turns are found.)
        let (mut t, _, _, exact) = self.turns_and_window(j, cap, &near, false);
        let h = self.turn_window(j, cap).1;
        t.dir = self.turn_dirs(j, h, &near);
        t.half_per_s = t.normal_per_s;
        if exact && t.v_turn_mm_s >= t.v_ref_mm_s {
            self.half_turns(j, h, &near, &mut t.half_per_s);
        }
        self.near = Some(near);
        t
    }

    /// Lowers `half` to the absolute turns within h of junction `j` (only lines within 2h,
    /// not passed at its cap alone): [`JunctionTurns::half_per_s`].
    fn half_turns(&self, j: usize, h: f64, near: &NearJunction, half: &mut [f64; MAX_AXES]) {
        let mut piece = (0.0, f64::INFINITY);
        let own = self.own_turn(j).abs();
        let Some(abs) = self.abs_turns_at(j, 0.5 * h, &own, near, &mut piece) else {
            return;
        };
        for (k, x) in half.iter_mut().enumerate().take(self.cfg.axes) {
            let n = abs.at(k, 0.5 * h) / TS_S;
            if n < *x {
                *x = n;
            }
        }
    }

    /// An upper bound of every speed the box-rule search at `share` finds within its bound
    /// at junction `j`: the absolute turns count the junction's own turn |Δu_k| with weight
    /// 1, so such a speed v keeps v·|Δu_k| ≤ share·a_k·Ts (the margin a_ts only lowers it).
    /// ∞ where the junction does not turn (mm/s).
    fn own_turn_cap(&self, j: usize, share: f64) -> f64 {
        let own = self.own_turn(j);
        let mut cap = f64::INFINITY;
        for k in 0..self.cfg.axes {
            let turn = own[k].abs();
            if turn > 1e-12 {
                // (1e-9 above: the bound's sum and the search's tolerance round.)
                let v = share * self.cfg.axis_a_max_mm_s2[k] * TS_S / turn * (1.0 + 1e-9);
                if v < cap {
                    cap = v;
                }
            }
        }
        cap
    }

    /// The turn of the tangent at junction `j` itself, t_start of the next block − t_end of
    /// this one: the absolute turns count it with weight 1, which `own_turn_cap` relies on.
    fn own_turn(&self, j: usize) -> AxesMm {
        self.win[j + 1].t_start - self.win[j].t_end
    }

    /// The blocks near junction `j` that its turns at speeds up to `cap` look at, within
    /// 2h (the walk of the last call when it covers them; hand it back to `self.near`
    /// after use). The `dir` lookups at 3h, once per junction, walk the window instead
    /// (`tangents_near`, the same tangents): walking 3h for them cost more.
    fn near_junction(&mut self, j: usize, cap: f64) -> Box<NearJunction> {
        // (Boxed: moving it out and back costs a pointer.)
        let mut near = self.near.take().unwrap_or_default();
        let reach = 2.0 * self.turn_window(j, cap).1;
        if !near.covers(j, reach) {
            self.walk_near(j, reach, &mut near);
        }
        near
    }

    /// The fastest a tick touching junction `j` passed at `cap` runs, v_ref = cap + A·Ts (A
    /// the larger path acceleration of the two blocks), and half its tick window, h =
    /// v_ref·Ts/2 (mm/s, mm).
    fn turn_window(&self, j: usize, cap: f64) -> (f64, f64) {
        let (a0, a1) = (self.win[j].a_axes, self.win[j + 1].a_axes);
        let a = if a0.is_finite() && a1.is_finite() {
            a0.max(a1)
        } else {
            a0.min(a1)
        };
        let v = cap + if a.is_finite() { a * TS_S } else { 0.0 };
        (v, v * TS_S / 2.0)
    }

    /// Whether junction `j` between two lines is alone in the ticks that touch it at speeds
    /// up to `v_ref` (mm/s): both lines longer than two such ticks, so no other junction
    /// lies within the ticks n−1, n, n+1 around the tick n that crosses it (see
    /// `JunctionTurns::v_turn_mm_s`).
    fn isolated(&self, j: usize, v_ref: f64) -> bool {
        let reach = 2.0 * v_ref * TS_S * (1.0 + 1e-9);
        [&self.win[j], &self.win[j + 1]]
            .iter()
            .all(|q| matches!(q.seg.path, SegPath::Line { .. }) && q.seg.length_mm > reach)
    }

    /// The turns of [`Planner::junction_turns`] without `dir`, and the turn of the tangent
    /// over the tick window, t(+h) − t(−h), with the tangents looked up in `near` where it
    /// covers them. With `keep`, a fresh lookup is kept in `near` with the range of h =
    /// v_ref·Ts/2 (h_lo, h_hi] over which it is the same (not where it varies, near arcs).
    /// Whether the absolute turns are in them (the walk covers 2h), and whether they alone
    /// are (only lines within 2h, [`AbsTurns::exact`]).
    #[inline(always)]
    fn turns_and_window(
        &self,
        j: usize,
        cap: f64,
        near: &NearJunction,
        keep: bool,
    ) -> (JunctionTurns, AxesMm, bool, bool) {
        let axes = self.cfg.axes;
        let (v, h) = self.turn_window(j, cap);
        let v_turn = if self.isolated(j, v) { cap } else { v };
        let own = self.own_turn(j).abs();
        if let Some((signed, window, abs, _)) = near.same_piece(j, h) {
            // The same tangents and junctions within 2h as a recent lookup: v_ref and the
            // weights of the absolute turns differ.
            let mut t = JunctionTurns {
                normal_per_s: signed,
                v_ref_mm_s: v,
                v_turn_mm_s: v_turn,
                ..JunctionTurns::default()
            };
            Self::apply_abs_turns(axes, &abs, h, &own, &mut t);
            return (t, window, true, abs.exact());
        }
        let mut t = JunctionTurns {
            v_ref_mm_s: v,
            v_turn_mm_s: v_turn,
            ..JunctionTurns::default()
        };
        let mut h_piece = (0.0, f64::INFINITY);
        let abs = self.abs_turns_at(j, h, &own, near, &mut h_piece);
        let window = if abs.is_some_and(|a| a.exact()) {
            // Only lines within 2h: the absolute turns replace the window's samples.
            let (mut ahead, mut behind) = ([AxesMm::ZERO; 1], [AxesMm::ZERO; 1]);
            self.tangents_from(near, true, h, &[1.0], &mut ahead, &mut h_piece);
            self.tangents_from(near, false, h, &[1.0], &mut behind, &mut h_piece);
            ahead[0] - behind[0]
        } else {
            self.signed_turns(j, h, near, &mut t, &mut h_piece)
        };
        let Some(abs) = abs else {
            return (t, window, false, false);
        };
        if keep && h_piece.0 < h_piece.1 {
            near.remember((t.normal_per_s, window, abs, h_piece));
        }
        Self::apply_abs_turns(axes, &abs, h, &own, &mut t);
        (t, window, true, abs.exact())
    }

    /// Sets the turns of `t` to the turn of the tangent over the tick window, sampled as a
    /// tick weighs the turns within ±v·Ts of it, by 1 − |x|/(v·Ts): the mean of the turns
    /// within ±h/2 and ±3h/2; returns the window's turn t(+h) − t(−h).
    #[inline(always)]
    fn signed_turns(
        &self,
        j: usize,
        h: f64,
        near: &NearJunction,
        t: &mut JunctionTurns,
        h_piece: &mut (f64, f64),
    ) -> AxesMm {
        let mut ahead = [AxesMm::ZERO; 3];
        let mut behind = [AxesMm::ZERO; 3];
        let ds = [h / 2.0, h, 1.5 * h];
        if near.covers(j, ds[2]) {
            // (c·h is bit-identical to the distances above.)
            let cs = [0.5, 1.0, 1.5];
            self.tangents_from(near, true, h, &cs, &mut ahead, h_piece);
            self.tangents_from(near, false, h, &cs, &mut behind, h_piece);
        } else {
            *h_piece = (h, h);
            self.tangents_near(j, true, &ds, &mut ahead);
            self.tangents_near(j, false, &ds, &mut behind);
        }
        let [ti1, t1, to1] = ahead;
        let [ti0, t0, to0] = behind;
        for k in 0..self.cfg.axes {
            let turn = 0.5 * ((ti1[k] - ti0[k]).abs() + (to1[k] - to0[k]).abs());
            t.normal_per_s[k] = turn / TS_S;
        }
        t1 - t0
    }

    /// The absolute turns near junction `j` at half window `h` ([`AbsTurns`]; the walk must
    /// cover 2h, `near_junction` walks that far), `own` its own turn (absolute per axis),
    /// with `h_piece` narrowed to the range of h over which the same junctions lie within
    /// 2h. None where the walk does not cover them.
    fn abs_turns_at(
        &self,
        j: usize,
        h: f64,
        own: &AxesMm,
        near: &NearJunction,
        h_piece: &mut (f64, f64),
    ) -> Option<AbsTurns> {
        if !near.covers(j, 2.0 * h) {
            return None;
        }
        let mut abs = AbsTurns::default();
        abs.add_own(self.cfg.axes, own);
        self.abs_turns_from(near, true, h, &mut abs, h_piece);
        self.abs_turns_from(near, false, h, &mut abs, h_piece);
        Some(abs)
    }

    /// Sets the turns to the absolute turns near the junction at h ([`AbsTurns`]): the
    /// tangent's turn over the window lets turns of opposite sign cancel and weighs the
    /// turns by two samples of the window, not as the ticks' second differences do. Where
    /// only lines lie within 2h the absolute turns are what the ticks see (issue #32: the
    /// window's samples weighed a turn within h/2 by 1 where a tick weighs it by at most
    /// 1 − d/2h, and cost the Lissajous 1.028 → 1.032); near arcs, whose turn the sums
    /// count at the arc's far end, the larger of the two is kept.
    #[inline]
    fn apply_abs_turns(axes: usize, abs: &AbsTurns, h: f64, own: &AxesMm, t: &mut JunctionTurns) {
        let exact = abs.exact();
        for k in 0..axes {
            // (A plain comparison, as `max` treats a NaN turn.)
            let n = abs.at(k, h) / TS_S;
            if exact || n > t.normal_per_s[k] {
                t.normal_per_s[k] = n;
            }
            t.own_per_s[k] = if exact { own[k] / TS_S } else { 0.0 };
        }
    }

    /// Per axis the largest tangent component the ticks near junction `j` move along: of
    /// t(h), t(3h) and t(−3h) (`h` of [`Planner::turn_window`]).
    fn turn_dirs(&self, j: usize, h: f64, near: &NearJunction) -> [f64; MAX_AXES] {
        let mut ahead = [AxesMm::ZERO; 2];
        let mut behind = [AxesMm::ZERO; 1];
        if near.covers(j, 3.0 * h) {
            let mut piece = (0.0, f64::INFINITY);
            self.tangents_from(near, true, h, &[1.0, 3.0], &mut ahead, &mut piece);
            self.tangents_from(near, false, h, &[3.0], &mut behind, &mut piece);
        } else {
            self.tangents_near(j, true, &[h, 3.0 * h], &mut ahead);
            self.tangents_near(j, false, &[3.0 * h], &mut behind);
        }
        let [t1, t2] = ahead;
        let [tm] = behind;
        let mut dir = [0.0; MAX_AXES];
        for (k, d) in dir.iter_mut().enumerate().take(self.cfg.axes) {
            *d = t1[k].abs().max(t2[k].abs()).max(tm[k].abs());
        }
        dir
    }

    /// R395: keep the junction speeds through a short block (linear profile: one that takes
    /// less than R395 at them; parabolic: unless rising saves more than R395). Only between
    /// two smooth junctions (**decided**): at a stop there is no criterion speed to keep, and
    /// a block between stops is a plain point-to-point move.
    ///
    /// The per-axis box search (`SegmentBox::v_max_mm_s`) keeps the manual's criteria
    /// speeds at the junctions.
    fn apply_rise_limit(&mut self, i: usize) {
        let prev = (i > 0 && self.win[i - 1].smooth).then(|| {
            (
                self.win[i - 1].crit,
                self.win[i - 1].seg.axis_box.criteria_end_mm_s,
            )
        });
        let rise_limit = self.cfg.envelope.rise_time_s;
        let linear = self.cfg.envelope.profile == Profile::Linear;
        let boxed = self.win[i].box_candidate;
        let p = &mut self.win[i];
        let Some((prev_crit, prev_criteria)) = prev else {
            return;
        };
        if p.seg.rapid || !p.smooth {
            return;
        }
        let seg: &mut Segment = &mut p.seg;
        if boxed {
            let box_flat = prev_criteria
                .max(seg.axis_box.criteria_end_mm_s)
                .min(seg.axis_box.v_max_mm_s);
            let box_top = seg.axis_box.v_max_mm_s.min(seg.feed_mm_s);
            let rises = box_top <= box_flat
                || criteria::rise_allowed_linear(seg.length_mm, box_flat, rise_limit);
            if !rises {
                seg.axis_box.v_max_mm_s = box_flat.max(1e-9);
            }
        }
        let v_flat = prev_crit.max(p.crit).min(seg.v_max_mm_s);
        let v_top = seg.v_max_mm_s.min(seg.feed_mm_s);
        let rises = if linear {
            v_top <= v_flat || criteria::rise_allowed_linear(seg.length_mm, v_flat, rise_limit)
        } else {
            criteria::rise_pays_off(seg.length_mm, v_flat, v_top, seg.accel_mm_s2, rise_limit)
        };
        if !rises {
            seg.v_max_mm_s = seg.v_max_mm_s.min(v_flat.max(1e-9).max(p.cap));
        }
    }
}

impl Planner {
    /// A smooth junction where the path turns (a corner, or an arc next to it) is planned as a
    /// stop where that is faster (**decided**, issue #16): when the speed it can actually be
    /// passed at is below one tick's acceleration step, or when the time the line sides lose
    /// by ramping at the acceleration the turn leaves them exceeds what passing at that speed
    /// gains over stopping.
    ///
    /// `net`: [`Planner::corner_net_s`] for these arguments where already computed.
    pub(super) fn corner_is_a_stop(
        &self,
        i: usize,
        cap: f64,
        turns: Option<&JunctionTurns>,
        net: Option<(f64, f64)>,
    ) -> bool {
        let (p, n) = (&self.win[i], &self.win[i + 1]);
        let is_arc = |q: &Pending| matches!(q.seg.path, SegPath::Arc { .. });
        let shares = p.turn.chord > 1e-9 || is_arc(p) || is_arc(n);
        if !p.smooth || !shares {
            return false;
        }
        let (gain, loss) = net.unwrap_or_else(|| self.corner_net_s(i, cap, turns));
        loss > gain
    }

    /// What passing junction `i` at `cap` gains over stopping there, and what the lines
    /// beside it lose by ramping at the acceleration the turn leaves them, s (see
    /// [`Planner::corner_is_a_stop`]). A gain of −∞ where the corner is passed slower than
    /// one tick's acceleration step.
    pub(super) fn corner_net_s(
        &self,
        i: usize,
        cap: f64,
        turns: Option<&JunctionTurns>,
    ) -> (f64, f64) {
        let (p, n) = (&self.win[i], &self.win[i + 1]);
        let is_arc = |q: &Pending| matches!(q.seg.path, SegPath::Arc { .. });
        let a = |q: &Pending| self.cfg.envelope.sets[q.set].accel_mm_s2.min(q.a_axes);
        let (cap, gain) = self.pass_gain_s(i, cap);
        if gain == f64::NEG_INFINITY {
            return (gain, 0.0);
        }
        let (start, _) = self.line_turns(i);
        let split = 1.0 - NORMAL_SHARE;
        let linear = self.cfg.envelope.profile == Profile::Linear;
        // Per side, with V the speed the block reaches from the cap: a line ramping between
        // cap and V at b < a instead of a loses (1/b − 1/a)·(V − cap)²/(2V); where its far
        // end is a stop (or the start) it also ramps between 0 and V at b, not at the a a
        // stop at this junction would leave it: (1/b − 1/a)·V/2 more (a two-line path
        // turning 34° at 5-8 mm/s ran 3 ticks slower passed than stopped).
        let mut loss = 0.0;
        for (side, q) in [(i, p), (i + 1, n)] {
            if is_arc(q) {
                continue;
            }
            let aq = a(q);
            let v = pass_reach_mm_s(q, aq, cap);
            let b = if linear && q.a_axes.is_finite() && !is_arc(p) && !is_arc(n) {
                let (t0, t1) = if side == i {
                    (start, turns)
                } else {
                    (turns, None)
                };
                self.accel_at_caps(side, t0, t1, aq)
            } else {
                split * aq
            };
            let far_stop = if side == i {
                i == 0 || !self.win[i - 1].smooth
            } else {
                !n.smooth
            };
            let far = if far_stop { v * v } else { 0.0 };
            loss += (1.0 / b - 1.0 / aq) * ((v - cap) * (v - cap) + far) / (2.0 * v);
        }
        (gain, loss)
    }

    /// The speed junction `i` can actually be passed at below `cap`, and what passing there
    /// gains over stopping, s (−∞ below one tick's acceleration step): the gain part of
    /// [`Planner::corner_net_s`].
    fn pass_gain_s(&self, i: usize, cap: f64) -> (f64, f64) {
        let (p, n) = (&self.win[i], &self.win[i + 1]);
        let a = |q: &Pending| self.cfg.envelope.sets[q.set].accel_mm_s2.min(q.a_axes);
        // The speed the corner can actually be passed at, from the speeds at the far ends
        // (rest at a stop; on a dense path a tiny block between smooth junctions must not
        // turn its junctions into stops, issue #32).
        let far_p = if i > 0 && self.win[i - 1].smooth {
            self.win[i - 1].cap
        } else {
            0.0
        };
        let far_n = if n.smooth {
            n.seg.feed_mm_s.min(n.seg.v_max_mm_s)
        } else {
            0.0
        };
        let cap = cap
            .min((far_p * far_p + a(p) * p.seg.length_mm).sqrt())
            .min((far_n * far_n + a(n) * n.seg.length_mm).sqrt());
        if cap < a(p).min(a(n)) * TS_S {
            return (cap, f64::NEG_INFINITY);
        }
        // Per side, with V the speed the block reaches from the cap: passing at the cap
        // instead of from rest saves cap/a − cap²/(2aV).
        let mut gain = 0.0;
        for q in [p, n] {
            let aq = a(q);
            let v = pass_reach_mm_s(q, aq, cap);
            gain += cap / aq - cap * cap / (2.0 * aq * v);
        }
        (cap, gain)
    }
}

/// The speed block `q` reaches from `cap` at `aq` (at least `cap`).
fn pass_reach_mm_s(q: &Pending, aq: f64, cap: f64) -> f64 {
    q.seg
        .feed_mm_s
        .min(q.seg.v_max_mm_s)
        .min((cap * cap + aq * q.seg.length_mm).sqrt())
        .max(cap)
}
