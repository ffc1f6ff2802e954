#!/usr/bin/env python3
"""A sketch of a jerk-limited box for the parabolic profile (issue #49), not a reference: what a
controller that chooses its raw setpoints on the polyline each tick, as the linear profile's box
does, and sends them through the axis filter it has today (q = B2·B2·p: the mean of the last two
ticks, twice, T = 8 ms), would reach on the reference paths: the design of the interpolator's
jerk-limited box (kernel/src/interp/jerk_box.rs), which takes the same times to a few ticks, in
plain Python, to try changes to it (other filters, searches, brakings) in seconds.

Each tick takes the farthest next raw setpoint (arc length s on the polyline) such that
- the filtered setpoints keep, per axis, |Δq| <= v_k·Ts, |Δ²q| <= a_k·Ts², |Δ³q| <= j_k·Ts³ (j_k =
  50·a_k) and stay within Lm/2 of the polyline;
- the raw arc length keeps 0 <= Δs <= F·Ts, |Δ²s| <= A·Ts², |Δ³s| <= J·Ts³ and the R384/R385 speeds
  of the junctions a step crosses (as ticks.py);
- a braking from there proves it can come to rest on the path within all of the above: the raw
  acceleration falls at J to at most -A and rises back to 0 as the speed reaches 0 (the
  time-optimal stop of a jerk-limited axis, along the path); the braking of the last accepted
  proof is kept and its next setpoint taken when no farther one passes.
The search tries the farthest setpoint the path limits allow, then bisects towards the kept
braking's next one. Plain Python, no planner code; the setpoints are checked again at the end.
Run: python3 jerk_box_sketch.py [--dir arcs] [options] [name ...] (paths/ by default; a few
seconds a path, the zig-zag 20). Options: --runs N (N proofs a tick, searched as the
linear box's `box_search`), --proof-ticks N (a longer braking fails its proof), --bisect N,
--filter b2b2|b2b3|b4|b2b4|b3b3 (the axis filter), --line-steps (the axes checked only where
the filter's window spans a vertex), --override FROM PCT TO (the feed override PCT % from tick
FROM to tick TO; 0 is a hold). Each line prints the setpoint checks a tick (p99, max): the
tick cost of a box built this way.
"""

import math
import os
import sys

from machine import A_AXIS, LM_MM, TS, V_AXIS
from ticks import Polyline, program_folder, program_names, read_feed, read_polyline

HERE = os.path.dirname(os.path.abspath(__file__))
J_AXIS = 50.0 * A_AXIS
A_PATH = 500.0
J_PATH = J_AXIS
LIMITS = (V_AXIS * TS, A_AXIS * TS**2, J_AXIS * TS**3)
ROUNDING = 1e-9  # relative, of each limit: a limit met exactly is not passed by rounding
OFF_MM = LM_MM / 2
BISECT = 8  # bisections a tick (--bisect N)
PROOF_TICKS = 400  # longest braking a proof simulates (--proof-ticks N): longer fails
# The axis filter's weights on the raw setpoints, newest first (--filter NAME): today's B2·B2.
FILTERS = {
    "b2b2": (1, 2, 1),
    "b2b3": (1, 2, 2, 1),
    "b4": (1, 1, 1, 1),
    "b2b4": (1, 2, 2, 2, 1),
    "b3b3": (1, 2, 3, 2, 1),
}
KERNEL = FILTERS["b2b2"]
OVERRIDE = None  # --override FROM PCT TO: the feed override PCT % from tick FROM to tick TO
LINE_STEPS = False  # --line-steps: no check of the axes where the filter's window is on one line
RUNS = 0  # --runs N: N proofs a tick at most, searched as the linear box does (0: bisect)
REST_MM_S = 1e-6  # a braking this slow is at rest


class Sketch:
    def __init__(self, poly, feed_mm_s):
        self.poly = poly
        self.feed_step = feed_mm_s * TS  # the programmed feed's step
        self.step_f = self.feed_step  # with the override in force
        self.kept = 0  # ticks that took the kept braking (no search found a setpoint)
        self.steps = 0  # step checks this tick (the tick cost of a box built this way)
        self.tick_steps = []
        self.guess = 0.5  # the linear box's adaptive guess (`box_search`), for --runs

    def off_path(self, q, s_from, s_to):
        """Distance of q from the segments between arc lengths s_from and s_to."""
        p = self.poly
        best = math.inf
        for j in range(p.segment(s_from), p.segment(s_to) + 1):
            a, u = p.pts[j], p.u[j]
            d = [q[k] - a[k] for k in range(3)]
            t = min(max(sum(d[k] * u[k] for k in range(3)), 0.0), p.s[j + 1] - p.s[j])
            best = min(best, math.sqrt(sum((d[k] - u[k] * t) ** 2 for k in range(3))))
        return best

    def step(self, hist, s_new):
        """The new (s, p, q) after history `hist` (the last four at least), or None beyond a
        limit."""
        trivial = self.on_one_line(hist, s_new)
        self.steps += 0 if trivial else 1
        (s3, p3, q3), (s2, p2, q2), (s1, p1, q1), (s0, p0, q0) = hist[-4:]
        ds = s_new - s0
        top = max(self.step_f, s0 - s1)  # above the feed (an override lowered): not faster
        if ds < -1e-12 or ds > top * (1 + 1e-12) or s_new > self.poly.length + 1e-12:
            return None
        if abs(s_new - 2 * s0 + s1) > A_PATH * TS**2 * (1 + ROUNDING):
            return None
        if abs(s_new - 3 * s0 + 3 * s1 - s2) > J_PATH * TS**3 * (1 + ROUNDING):
            return None
        p = self.poly
        j = p.segment(s0)
        while j + 1 < len(p.u) and p.s[j + 1] <= s_new:
            j += 1
            if p.s[j] > s0 and ds > p.cap[j] * TS:
                return None
        pn = p.at(s_new)
        raw = (pn, p0, p1, p2, p3)
        total = sum(KERNEL)
        qn = [sum(w * raw[i][k] for i, w in enumerate(KERNEL)) / total for k in range(3)]
        if trivial:
            # Each axis moves as the arc length times its direction cosine, and the filter's
            # averages keep the raw arc length's bounds: within every limit checked above.
            return (s_new, pn, qn)
        v_lim, a_lim, j_lim = (x * (1 + ROUNDING) for x in LIMITS)
        for k in range(3):
            if abs(qn[k] - q0[k]) > v_lim:
                return None
            if abs(qn[k] - 2 * q0[k] + q1[k]) > a_lim:
                return None
            if abs(qn[k] - 3 * q0[k] + 3 * q1[k] - q2[k]) > j_lim:
                return None
        if self.off_path(qn, (s_new, s0, s1, s2, s3)[len(KERNEL) - 1], s_new) > OFF_MM:
            return None
        return (s_new, pn, qn)

    def on_one_line(self, hist, s_new):
        """Whether every raw setpoint the newest four filtered ones depend on, and `s_new`,
        lie on one segment (with LINE_STEPS: the box needs no check of the axes there)."""
        window = len(KERNEL) + 2
        if not LINE_STEPS or len(hist) < window:
            return False
        p = self.poly
        j = p.segment(s_new)
        return hist[-window][0] >= p.s[j] and p.s[j] <= s_new <= p.s[j + 1]

    def brake(self, hist):
        """The raw arc lengths of the braking from `hist` to rest (q settled), or None."""
        hist = list(hist)
        plan = []
        checks = self.steps
        while True:
            s0, s1, s2 = hist[-1][0], hist[-2][0], hist[-3][0]
            v = (s0 - s1) / TS
            a = (s0 - 2 * s1 + s2) / TS**2
            if v <= REST_MM_S and abs(a) <= REST_MM_S / TS:
                # At rest: two more ticks settle the filter.
                for _ in range(len(KERNEL)):
                    nxt = self.step(hist, s0)
                    if nxt is None:
                        return None
                    hist.append(nxt)
                    plan.append(s0)
                return plan
            a_next = stop_accel(v, a)
            v_next = v + a_next * TS
            if v_next <= REST_MM_S:
                v_next = 0.0
            nxt = self.step(hist, s0 + v_next * TS)
            if nxt is None or self.steps - checks > PROOF_TICKS or len(plan) > 400:
                return None
            hist.append(nxt)
            plan.append(nxt[0])

    def run(self):
        p0 = self.poly.at(0.0)
        hist = [(0.0, p0, p0)] * 6
        plan = []
        out = [p0]
        length = self.poly.length
        while True:
            s0, s1, s2 = hist[-1][0], hist[-2][0], hist[-3][0]
            settled = all(q == out[-1] for q in out[-len(KERNEL):])
            if s0 >= length - 1e-12 and settled and s0 == s1 == s2:
                break
            self.step_f = self.feed_step * override_at(len(out) - 1)
            hi = min(s0 + self.feed_reach(s0, s1, s2), length, 2 * s0 - s1 + A_PATH * TS**2,
                     3 * s0 - 3 * s1 + s2 + J_PATH * TS**3)
            good = plan[0] if plan else s0
            self.steps = 0
            chosen = self.search(hist, good, hi)
            self.tick_steps.append(self.steps)
            if chosen is None:
                self.kept += 1
                nxt = self.step(hist, good)
                assert nxt is not None, "the kept braking is proven"
                plan = plan[1:]
            else:
                nxt, plan = chosen
            hist = hist[-5:] + [nxt]
            out.append(nxt[2])
        return out

    def feed_reach(self, s0, s1, s2):
        """The step the feed allows: F·Ts, or above F (an override lowered it) the step of the
        time-optimal jerk-limited approach to F (the stop's, relative to F)."""
        v = (s0 - s1) / TS
        f = self.step_f / TS
        if v <= f * (1 + 1e-12):
            return self.step_f
        a = (s0 - 2 * s1 + s2) / TS**2
        return max(v + stop_accel(v - f, a) * TS, f) * TS

    def proven(self, hist, s_try):
        """The step to `s_try` and its braking, or None."""
        nxt = self.step(hist, s_try)
        if nxt is None:
            return None
        rest = self.brake(hist[-5:] + [nxt])
        return None if rest is None else (nxt, rest)

    def search(self, hist, good, hi):
        """The farthest proven step up to `hi`: `hi` itself, else bisecting between `good`
        (proven before) and it."""
        if hi <= good:
            return None
        if RUNS:
            return self.search_guess(hist, good, hi)
        found = self.proven(hist, hi)
        if found is not None:
            return found
        lo, top = good, hi
        for _ in range(BISECT):
            mid = 0.5 * (lo + top)
            x = self.proven(hist, mid)
            if x is None:
                top = mid
            else:
                found, lo = x, mid
        return found


    def search_guess(self, hist, good, hi):
        """As the linear box's `box_search`: `hi`, then a guess that follows what was found
        the tick before, then halving; RUNS proofs at most."""
        found, at, top = None, good, hi
        for run in range(RUNS):
            if run == 0:
                m = hi
            elif run == 1:
                m = good + min(max(self.guess, 1 / 16), 15 / 16) * (hi - good)
            else:
                m = 0.5 * (at + top)
            x = self.proven(hist, m)
            if x is None:
                top = m
                continue
            found, at = x, m
            if run == 0:
                break
        self.guess = min((at - good) / (hi - good) + 1 / 16, 1.0)
        return found


def override_at(tick):
    """The override's share of the feed at `tick` (--override FROM PCT TO)."""
    if OVERRIDE is None:
        return 1.0
    t_from, pct, t_to = OVERRIDE
    return pct / 100.0 if t_from <= tick < t_to else 1.0


def stop_accel(v, a):
    """The raw acceleration of the next tick of the time-optimal jerk-limited stop from speed
    v and acceleration a: as low as J and A allow while a rise back to 0 at J still ends at a
    speed >= 0. Closed form (a box in the tick needs it so): with the next acceleration -x·J·Ts,
    m = floor(x), the rise back ends at v - J·Ts²·(m + 1)·(x - m + m/2)."""
    lo = max(a - J_PATH * TS, -A_PATH)
    hi = min(a + J_PATH * TS, A_PATH)
    if end_speed(v, hi) < 0:
        return hi
    w = v / (J_PATH * TS * TS)  # the speed in units of one tick's rise
    m = math.floor((math.sqrt(1 + 8 * w) - 1) / 2)  # the largest m with m(m+1)/2 <= w
    while (m + 1) * (m + 2) / 2 <= w:
        m += 1
    while m > 0 and m * (m + 1) / 2 > w:
        m -= 1
    x = m + min(w / (m + 1) - m / 2, 1.0)
    return min(max(-x * J_PATH * TS, lo), hi)


def end_speed(v, a):
    """The speed once the acceleration, a in the next tick, has risen back to 0 at J."""
    if a >= 0:
        return v + a * TS
    x = -a / (J_PATH * TS)
    m = math.floor(x)
    return v - J_PATH * TS * TS * (m + 1) * (x - m + m / 2)


def check(qs):
    worst = [0.0, 0.0, 0.0]
    for order in (1, 2, 3):
        w = {1: (1, -1), 2: (1, -2, 1), 3: (1, -3, 3, -1)}[order]
        for i in range(order, len(qs)):
            for k in range(3):
                d = sum(c * qs[i - r][k] for r, c in enumerate(w))
                worst[order - 1] = max(worst[order - 1], abs(d) / LIMITS[order - 1])
    return worst


def options(args):
    """Reads --bisect N, --proof-ticks N, --runs N and --filter NAME; returns the rest."""
    global BISECT, PROOF_TICKS, RUNS, KERNEL, LINE_STEPS, OVERRIDE
    rest = []
    it = iter(args)
    for a in it:
        if a == "--bisect":
            BISECT = int(next(it))
        elif a == "--proof-ticks":
            PROOF_TICKS = int(next(it))
        elif a == "--filter":
            KERNEL = FILTERS[next(it)]
        elif a == "--override":
            OVERRIDE = (int(next(it)), float(next(it)), int(next(it)))
        elif a == "--line-steps":
            LINE_STEPS = True
        elif a == "--runs":
            RUNS = int(next(it))
        else:
            rest.append(a)
    return rest


def main():
    folder, args = program_folder(options(sys.argv[1:]))
    programs = os.path.join(HERE, folder)
    names = args or program_names(programs)
    for name in names:
        program = os.path.join(programs, f"{name}.nc")
        sketch = Sketch(Polyline(read_polyline(program)), read_feed(program) / 60.0)
        qs = sketch.run()
        ticks = len(qs) - 1
        cost = sorted(sketch.tick_steps)
        p99 = cost[int(0.99 * (len(cost) - 1))]
        print(f"{name:12s} {ticks:6d} ticks {ticks * TS:8.3f} s  worst v/a/j " +
              " ".join(f"{w:.4f}" for w in check(qs)) +
              f"  step checks a tick p99 {p99} max {cost[-1]}  kept braking {sketch.kept} ticks",
              flush=True)


if __name__ == "__main__":
    main()
