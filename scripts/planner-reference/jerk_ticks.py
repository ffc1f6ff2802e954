#!/usr/bin/env python3
"""What jerk-limited 4 ms setpoints near the polyline allow (issue #49): a feasible tick
sequence, found by linear programs over a receding horizon.

ticks.py keeps the setpoints on the polyline. Under a jerk limit they cannot stay on it: at a
corner each axis's acceleration would jump within one tick. So here each setpoint may leave
the path by up to half of Lm (R384), the planner's own split for its axis filter (the other half
is for the chord of a tick): q_i = P(s_i) + e_i, e_i normal to the segment s_i lies on, |e_i| <=
Lm/2 (on a planar path in the plane; otherwise each of two normals within Lm/(2·√2), the square
inside the disk). At the start and the end of the path the corridor narrows to 0 along the first
and last segment. Limits, all on 4 ms differences:
- per axis: |Δq| <= v_k·Ts, |Δ²q| <= a_k·Ts², |Δ³q| <= j_k·Ts³ (j_k = 50·a_k, the daemon's);
- along the path (the foot points' arc length s): 0 <= Δs <= F·Ts, |Δ²s| <= A·Ts²,
  |Δ³s| <= J·Ts³ (A = R236 → R52, 500 mm/s² by default; J the axes' jerk).
- the step whose foot point crosses a junction within the junction's R384 and R385 speeds, the
  manual's criteria, as ticks.py has them (Lm 8 µm, am 1000 mm/s²).

With the segment each tick's foot point lies on fixed, every limit is linear, so a window of H
ticks is a linear program (scipy's HiGHS): maximise the progress Σ s_i, the window's last four
setpoints at rest (so the rest of the last window is always a feasible continuation). A tick
whose foot point ends at its segment's end is moved on to the next segment and the program
solved again until none moves. The first C ticks are kept, and the next window starts from them.
Being a receding horizon, the sequence is feasible, not proven optimal: an upper bound on what
jerk-limited 4 ms setpoints within Lm/2 of the path need. It is checked again at the end from
its setpoints alone. Nothing here uses the planner's code.

Arcs (G2/G3, the arc-fitted programs of arcs.py) are drawn in chords within ARC_SAG_MM (0.2 µm)
of the arc; on a chord the corridor is narrowed by its distance from the arc, so the setpoints stay
within Lm/2 of the arc itself. The points inside an arc are not junctions: no R384/R385 speed there
(the axes' limits hold the arc).

Run: scripts/planner-reference/run.sh (a venv with scipy), or in that venv
python3 jerk_ticks.py [name ...] for paths/ (writes jerk-ticks.tsv) and python3 jerk_ticks.py
--dir arcs [name ...] for arcs/ (writes arcs/jerk-ticks.tsv); machine-parabolic.rek: R338 = 2,
R384 = 8 µm, the default path acceleration 500 mm/s². About a minute a path.
"""

import math
import os
import sys

import numpy as np
from scipy.optimize import linprog
from scipy.sparse import csr_matrix

from machine import A_AXIS, LM_MM, TS, V_AXIS, criteria_cap_mm_s
from ticks import (arc_geometry, arc_points, program_folder, program_names, read_feed,
                   read_moves)

HERE = os.path.dirname(os.path.abspath(__file__))
J_AXIS = 50.0 * A_AXIS  # mm/s³, the daemon's axis jerk (50·a)
A_PATH = 500.0  # mm/s², R236 → R52 default
J_PATH = J_AXIS  # mm/s³, the path jerk without a P: the axes'
CORRIDOR_MM = LM_MM / 2
WINDOW = 72  # ticks a program looks at (braking from F6000 at 500 mm/s² takes ~55)
KEEP = 12  # ticks kept of each window
MARGIN = 1.0 - 1e-4  # of every limit and the corridor: HiGHS keeps rows to ~1e-7 mm (3e-5 J·Ts³)
PUSHES = 400  # most re-solves a window
GUIDES = 12  # most guided solves a window
GUIDE_MM = 0.4  # how far a guided foot point may run past its segment (a tick at F6000)
ARC_SAG_MM = 0.0002  # arcs are drawn in chords off the arc by at most this (0.2 µm)


def read_path(program):
    """The polyline of a program, arcs drawn in chords off them by at most ARC_SAG_MM: its
    points, each segment's distance from the arc it stands for (0 on lines) and whether each
    point lies inside an arc (not a junction of the program)."""
    pts, sag, inside = [(0.0, 0.0, 0.0)], [], [False]
    for motion, start, end, centre in read_moves(program):
        if motion == "G1":
            new, off = [tuple(end)], 0.0
        else:
            ccw = motion == "G3"
            _, _, r, _, sweep = arc_geometry(start, end, centre, ccw)
            n = max(1, math.ceil(abs(sweep) / (2.0 * math.acos(1.0 - ARC_SAG_MM / r))))
            chord = abs(sweep) * r / n
            new = arc_points(start, end, centre, ccw, chord * (1.0 + 1e-9))
            off = r * (1.0 - math.cos(sweep / (2 * len(new))))
        for k, q in enumerate(new):
            if q != pts[-1]:
                pts.append(q)
                sag.append(off)
                inside.append(k < len(new) - 1)
    inside[-1] = False
    return pts, sag, inside


class Path:
    """The polyline with each segment's start, tangent and normals, and the corridor."""

    def __init__(self, pts, sag=None, inside=None):
        p = np.array(pts, dtype=float)
        d = p[1:] - p[:-1]
        ln = np.linalg.norm(d, axis=1)
        self.pts, self.t, self.len = p, d / ln[:, None], ln
        self.s0 = np.concatenate(([0.0], np.cumsum(ln)))
        self.length = self.s0[-1]
        # Speed cap of the step crossing vertex j (R384, R385), as ticks.py's.
        self.cap = np.full(len(p), np.inf)
        for j in range(1, len(p) - 1):
            if inside is not None and inside[j]:
                continue  # inside an arc: no junction
            chord = np.linalg.norm(self.t[j] - self.t[j - 1])
            if chord > 1e-12:
                self.cap[j] = criteria_cap_mm_s(chord)
        centred = p - p.mean(axis=0)
        _, sv, vt = np.linalg.svd(centred, full_matrices=False)
        planar = len(p) < 3 or sv[-1] < 1e-9 * max(sv[0], 1.0)
        self.n1 = np.zeros_like(self.t)
        self.n2 = np.zeros_like(self.t)
        if planar:
            # A line or a plane: the normal within the plane (a line's own plane is any).
            m = vt[-1] if len(p) >= 3 and sv[1] > 1e-9 * max(sv[0], 1.0) else None
            for k, t in enumerate(self.t):
                n = np.cross(m, t) if m is not None else np.cross(t, least_axis(t))
                self.n1[k] = n / np.linalg.norm(n)
            self.c1, self.c2 = CORRIDOR_MM * MARGIN, 0.0
            split = 1.0
        else:
            for k, t in enumerate(self.t):
                n = np.cross(t, least_axis(t))
                self.n1[k] = n / np.linalg.norm(n)
                self.n2[k] = np.cross(t, self.n1[k])
            self.c1 = self.c2 = CORRIDOR_MM * MARGIN / math.sqrt(2.0)
            split = 1.0 / math.sqrt(2.0)
        # An arc's chords: the corridor less their distance from the arc, per segment.
        self.sag = np.zeros(len(self.len)) if sag is None else np.array(sag)
        width = (CORRIDOR_MM - self.sag) * MARGIN * split
        self.c1 = np.where(self.c1 > 0.0, width, 0.0)
        self.c2 = np.where(self.c2 > 0.0, width, 0.0)

    def at(self, j, s):
        return self.pts[j] + self.t[j] * (s - self.s0[j])


def least_axis(t):
    e = np.zeros(3)
    e[int(np.argmin(np.abs(t)))] = 1.0
    return e


class Window:
    """One linear program: variables (s, e1, e2) per tick; `hist` the last three setpoints
    kept, as (s, q)."""

    def __init__(self, path, hist, seg, feed_mm_s, past_mm=0.0):
        self.path, self.hist, self.seg, self.past_mm = path, hist, seg, past_mm
        s_kept = hist[-1][0]
        self.seg_before = min(int(np.searchsorted(path.s0, s_kept, side="right")) - 1, len(path.len) - 1)
        self.h = len(seg)
        self.rows, self.cols, self.vals, self.rhs = [], [], [], []
        self.eq = []
        self.step_f = feed_mm_s * TS

    def expr(self, k, axis):
        """Tick k's coordinate `axis` (0..2: q, 3: s) as (constant, {column: coefficient});
        k < 0 are the kept setpoints."""
        if k < 0:
            s, q = self.hist[k]
            return (s if axis == 3 else q[axis]), {}
        j = self.seg[k]
        if axis == 3:
            return 0.0, {3 * k: 1.0}
        p = self.path
        const = p.pts[j][axis] - p.t[j][axis] * p.s0[j]
        return const, {3 * k: p.t[j][axis], 3 * k + 1: p.n1[j][axis], 3 * k + 2: p.n2[j][axis]}

    def diff(self, k, axis, order):
        weights = {1: (1, -1), 2: (1, -2, 1), 3: (1, -3, 3, -1)}[order]
        const, coef = 0.0, {}
        for r, w in enumerate(weights):
            c, e = self.expr(k - r, axis)
            const += w * c
            for col, v in e.items():
                coef[col] = coef.get(col, 0.0) + w * v
        return const, coef

    def row(self, coef, rhs, sign=1.0):
        n = len(self.rhs)
        for col, v in coef.items():
            self.rows.append(n)
            self.cols.append(col)
            self.vals.append(sign * v)
        self.rhs.append(rhs)

    def within(self, k, axis, order, limit):
        const, coef = self.diff(k, axis, order)
        self.row(coef, limit - const)
        self.row(coef, limit + const, -1.0)

    def build(self):
        per_axis = [(1, V_AXIS * TS), (2, A_AXIS * TS**2), (3, J_AXIS * TS**3)]
        per_axis = [(order, limit * MARGIN) for order, limit in per_axis]
        for k in range(self.h):
            for axis in range(3):
                for order, limit in per_axis:
                    self.within(k, axis, order, limit)
            const, coef = self.diff(k, 3, 1)
            before = self.seg[k - 1] if k > 0 else self.seg_before
            cap = self.path.cap[before + 1 : self.seg[k] + 1].min(initial=math.inf)
            self.row(coef, min(self.step_f, cap * TS) - const)  # Δs <= F·Ts, the junctions'
            self.row(coef, const, -1.0)  # Δs >= 0
            self.within(k, 3, 2, A_PATH * TS**2 * MARGIN)
            self.within(k, 3, 3, J_PATH * TS**3 * MARGIN)
            self.narrow(k)
        for k in range(self.h - 3, self.h):  # at rest at the end of the window
            for v in range(3):
                self.eq.append((3 * k + v, 3 * (k - 1) + v))

    def narrow(self, k):
        """The corridor narrows to 0 along the first and the last segment."""
        p, j = self.path, self.seg[k]
        for col, c in ((3 * k + 1, p.c1[j]), (3 * k + 2, p.c2[j])):
            if c == 0.0:
                continue
            if j == 0:
                slope = c / p.len[0]
                self.row({col: 1.0, 3 * k: -slope}, 0.0)
                self.row({col: -1.0, 3 * k: -slope}, 0.0)
            if j == len(p.len) - 1:
                slope = c / p.len[j]
                self.row({col: 1.0, 3 * k: slope}, slope * p.length)
                self.row({col: -1.0, 3 * k: slope}, slope * p.length)

    def solve(self):
        self.build()
        n = 3 * self.h
        a_ub = csr_matrix((self.vals, (self.rows, self.cols)), shape=(len(self.rhs), n))
        a_eq = np.zeros((len(self.eq), n))
        for r, (x, y) in enumerate(self.eq):
            a_eq[r, x], a_eq[r, y] = 1.0, -1.0
        p = self.path
        bounds = []
        for j in self.seg:
            s_lo, s_hi = max(p.s0[j] - self.past_mm, 0.0), min(p.s0[j + 1] + self.past_mm, p.length)
            bounds += [(s_lo, s_hi), (-p.c1[j], p.c1[j]), (-p.c2[j], p.c2[j])]
        cost = np.zeros(n)
        cost[0::3] = -1.0
        res = linprog(cost, A_ub=a_ub, b_ub=self.rhs, A_eq=a_eq, b_eq=np.zeros(len(self.eq)),
                      bounds=bounds, method="highs")
        return res.x.reshape(self.h, 3) if res.status == 0 else None


def solve_window(path, hist, seg, feed):
    """The window's program with the best segments found for its ticks.

    First guided: each tick may leave its segment by up to `GUIDE_MM` along the segment's line
    (not the path), and moves to the segment its foot point came to, until none moves. Then
    strict, from there or from the kept window, whichever goes farther: a tick whose foot point
    ends at its segment's end moves on to the next, until none does."""
    best = Window(path, hist, seg, feed).solve()
    assert best is not None, "the kept window is always feasible"
    guess = guided(path, hist, seg, feed)
    if guess is not None:
        x = Window(path, hist, guess, feed).solve()
        if x is not None and x[:, 0].sum() >= best[:, 0].sum():
            best, seg = x, guess
    last = len(path.len) - 1
    for _ in range(PUSHES):
        moved = list(seg)
        for k, (s, _, _) in enumerate(best):
            if seg[k] < last and s >= path.s0[seg[k] + 1] - 1e-9:
                moved[k] = seg[k] + 1
        if moved == seg:
            return best, seg
        x = Window(path, hist, moved, feed).solve()
        if x is None:
            return best, seg
        best, seg = x, moved
    return best, seg


def guided(path, hist, seg, feed):
    """Segments for the window's ticks from programs whose foot points may run past their
    segment along its line; None where that does not settle."""
    for _ in range(GUIDES):
        x = Window(path, hist, seg, feed, GUIDE_MM).solve()
        if x is None:
            return None
        moved = np.clip(np.searchsorted(path.s0, x[:, 0], side="right") - 1, 0, len(path.len) - 1)
        moved = list(np.maximum.accumulate(moved))
        if moved == seg:
            return seg
        seg = moved
    return seg


def run(path, feed):
    """The kept setpoints q and foot points s, from rest at the start to rest at the end."""
    start = path.pts[0]
    hist = [(0.0, start)] * 3
    qs, ss = [start] * 3, [0.0] * 3
    seg = [0] * WINDOW
    while ss[-1] < path.length - 1e-9:
        x, seg = solve_window(path, hist, seg, feed)
        for k in range(KEEP):
            s, e1, e2 = x[k]
            j = seg[k]
            q = path.at(j, s) + e1 * path.n1[j] + e2 * path.n2[j]
            qs.append(q)
            ss.append(s)
        hist = [(ss[-3], qs[-3]), (ss[-2], qs[-2]), (ss[-1], qs[-1])]
        seg = seg[KEEP:] + [seg[-1]] * KEEP
    end = next(i for i, s in enumerate(ss) if s >= path.length - 1e-9)
    return np.array(qs[: end + 1]), np.array(ss[: end + 1])


def check(path, qs, ss):
    """The largest ratios to each limit, from the setpoints alone, and the largest distance of a
    setpoint from the programmed path (at most its distance from a chord and the chord's from
    the arc)."""
    q = np.vstack([qs[:1]] * 3 + [qs] + [qs[-1:]] * 3)
    out = {}
    for order, limit in ((1, V_AXIS * TS), (2, A_AXIS * TS**2), (3, J_AXIS * TS**3)):
        out[f"axis{order}"] = np.abs(np.diff(q, n=order, axis=0)).max() / limit
    s = np.concatenate(([ss[0]] * 3, ss, [ss[-1]] * 3))
    out["path_a"] = np.abs(np.diff(s, n=2)).max() / (A_PATH * TS**2)
    out["path_j"] = np.abs(np.diff(s, n=3)).max() / (J_PATH * TS**3)
    out["off_um"] = max(distance(path, x) for x in qs) * 1000.0
    return out


def distance(path, x):
    a, t = path.pts[:-1], path.t
    along = np.clip(np.einsum("ij,ij->i", x - a, t), 0.0, path.len)
    return (np.linalg.norm(a + t * along[:, None] - x, axis=1) + path.sag).min()


NAMES = ["line", "pentagram", "pocket", "circle", "lissajous", "splines", "surface", "zigzag",
         "arcs", "helix"]


def main():
    folder, args = program_folder(sys.argv[1:])
    programs = os.path.join(HERE, folder)
    every = NAMES if folder == "paths" else program_names(programs)
    names = args or every
    # The paths' table beside the script (as ticks.py's), another folder's in it.
    table = os.path.join(HERE if folder == "paths" else programs, "jerk-ticks.tsv")
    rows = {}
    if os.path.exists(table):
        with open(table) as f:
            for line in f:
                if not line.startswith("#"):
                    rows[line.split("\t")[0]] = line
    for name in names:
        program = os.path.join(programs, f"{name}.nc")
        path = Path(*read_path(program))
        qs, ss = run(path, read_feed(program) / 60.0)
        ticks = len(qs) - 3
        c = check(path, qs, ss)
        over = [k for k, v in c.items() if v > (CORRIDOR_MM * 1000 if k == "off_um" else 1.0)]
        assert not over, f"{name}: {over} beyond their limits: {c}"
        print(f"{name:10s} {ticks:6d} ticks {ticks * TS:8.3f} s  " +
              "  ".join(f"{k} {v:.6f}" for k, v in c.items()), flush=True)
        rows[name] = (f"{name}\t{ticks}\t{ticks * TS:.3f}\t" +
                      "\t".join(f"{c[k]:.6f}" for k in c) + "\n")
    with open(table, "w") as f:
        f.write("# name\tticks\tticks_s\tmax_axis_v\tmax_axis_a\tmax_axis_j\tmax_path_a"
                "\tmax_path_j\tmax_off_um\n")
        for name in every:
            if name in rows:
                f.write(rows[name])


if __name__ == "__main__":
    main()
