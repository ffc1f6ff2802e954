#!/usr/bin/env python3
"""What 4 ms ticks on the polyline allow (issue #32): a feasible tick sequence, found greedily.

The limit of reference.py is continuous in time. A controller that keeps its setpoints on the
programmed polyline, one every Ts, is held instead by the setpoints themselves: per axis the
second difference |x_k(s_i+1) - 2·x_k(s_i) + x_k(s_i-1)| <= a_k·Ts², the step |Δx_k| <= v_k·Ts,
the path step s_i+1 - s_i <= F·Ts (F the program's), with a path acceleration A (R52, R236, R237
of a constants file) the second difference of the arc length |s_i+1 - 2·s_i + s_i-1| <= A·Ts², and at each
junction the step that crosses it within the junction's R384/R385 speeds (the same criteria as
reference.py's exact bound).

This script finds such a sequence, from rest to rest, greedily: each tick takes the farthest
next setpoint that keeps every constraint and from which braking as hard as the constraints
allow (each tick the nearest feasible setpoint) reaches rest before the end of the path. The
braking continuation proves each state safe, so the sequence is feasible; being greedy, it is
not always optimal (it gives up up to half a tick at a sharp corner, where a planner chooses
the phase of its ticks). Its time is therefore an upper bound on what on-path 4 ms setpoints
can do, independent of the planner's model. The sequence is checked again at the end from
its setpoints alone.

Nothing here uses the planner's code. Input: paths/<name>.nc (reference.py). Output
(committed): ticks.tsv without a path acceleration (the axes' limits alone: R52 = R236 = R237
= 0), ticks-a<A>.tsv with one. Run: python3 ticks.py [--path-accel A] [name ...] (plain
Python, about a minute a table); python3 ticks.py --dir arcs [--path-accel A] for the
arc-fitted programs of arcs.py (G2/G3, drawn in 5 µm chords here), --dir fast for fast.py's. The
feed is the program's F.
"""

import math
import os
import sys

from machine import A_AXIS, FEED, TS, V_AXIS, criteria_cap_mm_s

HERE = os.path.dirname(os.path.abspath(__file__))
STEP_A = A_AXIS * TS * TS  # per axis, mm per tick²
STEP_V = V_AXIS * TS  # per axis, mm per tick
STEP_F = FEED * TS  # path, mm per tick
STEP_P = math.inf  # path acceleration, mm per tick² (--path-accel)


ARC_CHORD_MM = 0.005  # arcs are drawn in chords this long (5 µm: off the circle by < 7 nm at R0.5)


def read_moves(path):
    """The moves of a program of G1 X Y Z lines and G2/G3 arcs in the XY plane from the origin:
    (motion, start, end, centre), centre (I J) relative to the start."""
    cur = [0.0, 0.0, 0.0]
    motion = "G1"
    with open(path) as f:
        for line in f:
            start = list(cur)
            centre = [0.0, 0.0]
            for word in line.split():
                if word in ("G1", "G2", "G3"):
                    motion = word
                axis = "XYZ".find(word[0])
                if axis >= 0:
                    cur[axis] = float(word[1:])
                if word[0] in "IJ":
                    centre["IJ".find(word[0])] = float(word[1:])
            yield motion, start, list(cur), centre


def read_polyline(path):
    """The points of a program (`read_moves`), arcs in ARC_CHORD_MM chords (repeated points
    dropped)."""
    pts = [(0.0, 0.0, 0.0)]
    for motion, start, end, centre in read_moves(path):
        if motion == "G1":
            new = [tuple(end)]
        else:
            new = arc_points(start, end, centre, motion == "G3")
        for p in new:
            if p != pts[-1]:
                pts.append(p)
    return pts


def read_feed(path):
    """The feed a program sets (its first F word), mm/min; machine.FEED where it sets none."""
    with open(path) as f:
        for line in f:
            for word in line.split():
                if word[0] == "F":
                    return float(word[1:])
    return FEED


def arc_geometry(start, end, centre, ccw):
    """An arc's centre (XY), radius, start angle and signed sweep."""
    cx, cy = start[0] + centre[0], start[1] + centre[1]
    r = math.hypot(start[0] - cx, start[1] - cy)
    a0 = math.atan2(start[1] - cy, start[0] - cx)
    sweep = math.atan2(end[1] - cy, end[0] - cx) - a0
    if ccw and sweep <= 0:
        sweep += 2 * math.pi
    if not ccw and sweep >= 0:
        sweep -= 2 * math.pi
    return cx, cy, r, a0, sweep


def arc_points(start, end, centre, ccw, chord_mm=ARC_CHORD_MM):
    """The points of an arc from `start` to `end` about `start` + `centre` (XY), every
    `chord_mm` of its length, the end exactly; Z linear in the angle."""
    cx, cy, r, a0, sweep = arc_geometry(start, end, centre, ccw)
    n = max(1, math.ceil(abs(sweep) * r / chord_mm))
    out = []
    for i in range(1, n):
        a = a0 + sweep * i / n
        z = start[2] + (end[2] - start[2]) * i / n
        out.append((cx + r * math.cos(a), cy + r * math.sin(a), z))
    out.append(tuple(end))
    return out


class Polyline:
    def __init__(self, pts):
        self.pts = pts
        self.s = [0.0]
        self.u = []
        for p, q in zip(pts, pts[1:]):
            d = [q[k] - p[k] for k in range(3)]
            n = math.sqrt(sum(x * x for x in d))
            self.s.append(self.s[-1] + n)
            self.u.append([x / n for x in d])
        self.length = self.s[-1]
        # Speed cap of the step crossing point j (R384, R385), as reference.py's exact bound.
        self.cap = [math.inf] * len(pts)
        for j in range(1, len(pts) - 1):
            chord = math.sqrt(sum((self.u[j][k] - self.u[j - 1][k]) ** 2 for k in range(3)))
            if chord > 1e-12:
                self.cap[j] = criteria_cap_mm_s(chord)

    def segment(self, s):
        lo, hi = 0, len(self.u) - 1
        while lo < hi:
            mid = (lo + hi + 1) // 2
            if self.s[mid] <= s:
                lo = mid
            else:
                hi = mid - 1
        return lo

    def at(self, s):
        j = self.segment(s)
        t = s - self.s[j]
        return [self.pts[j][k] + self.u[j][k] * t for k in range(3)]

    def next_setpoints(self, a, b):
        """The feasible next setpoints c >= b after setpoints a, b: a list of intervals in s."""
        xa, xb = self.at(a), self.at(b)
        aim = [2 * xb[k] - xa[k] for k in range(3)]
        top = min(b + STEP_F, self.length, 2 * b - a + STEP_P)
        low = 2 * b - a - STEP_P
        out = []
        j = self.segment(b)
        while True:
            if j > 0 and self.s[j] > b:
                top = min(top, b + self.cap[j] * TS)
            lo, hi = max(self.s[j], b, low), min(self.s[j + 1], top)
            if lo > hi:
                if low <= top and self.s[j + 1] < low and j + 1 < len(self.u):
                    # (Wholly behind the path acceleration's nearest setpoint: crossed.)
                    j += 1
                    continue
                break
            for k in range(3):
                uk = self.u[j][k]
                base = self.pts[j][k] - uk * self.s[j]
                for centre, radius in ((aim[k], STEP_A), (xb[k], STEP_V)):
                    if abs(uk) < 1e-15:
                        if abs(base - centre) > radius:
                            lo, hi = 1.0, 0.0
                    elif uk > 0:
                        lo = max(lo, (centre - radius - base) / uk)
                        hi = min(hi, (centre + radius - base) / uk)
                    else:
                        lo = max(lo, (centre + radius - base) / uk)
                        hi = min(hi, (centre - radius - base) / uk)
            if lo <= hi:
                out.append((lo, hi))
            if self.s[j + 1] >= top or j + 1 >= len(self.u):
                break
            j += 1
        return out

    def can_stop(self, a, b):
        """Braking as hard as the constraints allow from setpoints a, b reaches rest."""
        while True:
            nxt = self.next_setpoints(a, b)
            if not nxt:
                return False
            c = nxt[0][0]
            if c <= b + 1e-12:
                return True
            a, b = b, c


def below(intervals, c):
    """The largest feasible setpoint at most c, or None."""
    best = None
    for lo, hi in intervals:
        if lo <= c:
            best = min(hi, c)
    return best


def greedy_ticks(line):
    """The setpoints (arc lengths) of the greedy sequence, from rest at 0 to rest at the end."""
    seq = [0.0, 0.0]
    while seq[-1] < line.length - 1e-9:
        a, b = seq[-2], seq[-1]
        nxt = line.next_setpoints(a, b)
        c = nxt[-1][1]
        if not line.can_stop(b, c):
            # The nearest setpoint is the braking step the previous tick proved safe.
            lo, hi = nxt[0][0], c
            while hi - lo > 1e-9:
                mid = 0.5 * (lo + hi)
                cand = below(nxt, mid)
                if cand is not None and line.can_stop(b, cand):
                    lo = mid
                else:
                    hi = mid
            c = below(nxt, lo)
        seq.append(c)
    return seq


def check(line, seq):
    """From the setpoints alone: the largest axis acceleration / a_k, axis speed / v_k, path
    speed / F and path acceleration / A over the sequence held at rest at both ends."""
    xs = [line.at(s) for s in [seq[0]] + seq + [seq[-1]]]
    acc = max(abs(p[k] - 2 * q[k] + r[k]) for p, q, r in zip(xs, xs[1:], xs[2:]) for k in range(3))
    vel = max(abs(q[k] - p[k]) for p, q in zip(xs, xs[1:]) for k in range(3))
    path = max(q - p for p, q in zip(seq, seq[1:]))
    ss = [seq[0]] + seq + [seq[-1]]
    path_a = max(abs(r - 2 * q + p) for p, q, r in zip(ss, ss[1:], ss[2:]))
    return acc / STEP_A, vel / STEP_V, path / STEP_F, path_a / STEP_P


def program_folder(args):
    """`--dir D` at the head of the arguments: the programs D/*.nc (arcs.py's, fast.py's)
    instead of paths/. Returns the folder and the other arguments."""
    if args[:1] == ["--dir"]:
        return args[1], args[2:]
    return "paths", args


def program_names(folder):
    """The names of the programs in `folder` (a path), sorted."""
    return sorted(n[:-3] for n in os.listdir(folder) if n.endswith(".nc"))


def main():
    global STEP_P, STEP_F
    table = "ticks.tsv"
    # --dir D: the programs D/*.nc, the table written into D.
    folder, args = program_folder(sys.argv[1:])
    paths = os.path.join(HERE, folder)
    out_dir = HERE if folder == "paths" else paths
    if args[:1] == ["--path-accel"]:
        accel = float(args[1])
        STEP_P = accel * TS * TS
        table = f"ticks-a{accel:g}.tsv"
        args = args[2:]
    only = set(args)
    rows = []
    if out_dir == HERE:
        with open(os.path.join(HERE, "reference.tsv")) as f:
            names = [l.split("\t")[0] for l in f if not l.startswith("#")]
    else:
        names = program_names(paths)
    for name in names:
        if only and name not in only:
            continue
        program = os.path.join(paths, f"{name}.nc")
        STEP_F = read_feed(program) / 60.0 * TS
        line = Polyline(read_polyline(program))
        seq = greedy_ticks(line)
        ticks = len(seq) - 2
        acc, vel, path, path_a = check(line, seq)
        rows.append((name, ticks, ticks * TS, acc, vel, path, path_a))
        print(f"{name:10s} {ticks:6d} ticks {ticks * TS:8.3f} s  axis a {acc:.6f}  axis v {vel:.6f}  F {path:.6f}  A {path_a:.6f}", flush=True)
    if only:
        return
    with open(os.path.join(out_dir, table), "w") as f:
        f.write("# name\tticks\tticks_s\tmax_axis_a\tmax_axis_v\tmax_path_v\tmax_path_a\n")
        for r in rows:
            f.write(f"{r[0]}\t{r[1]}\t{r[2]:.3f}\t{r[3]:.6f}\t{r[4]:.6f}\t{r[5]:.6f}\t{r[6]:.6f}\n")


if __name__ == "__main__":
    main()
