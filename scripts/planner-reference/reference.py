#!/usr/bin/env python3
"""Independent reference for the look-ahead planner on dense paths (issue #32).

Generates dense paths (the issue's toolpaths and seeded random ones: splines, arcs and 3D
surfaces sampled as chords of 0.01-0.5 mm, random chord lengths, corners mixed in), writes
them as .nc programs, and computes for each the time no controller can beat under the
machine's limits:

- exact: the polyline itself, its junctions passed at the exact per-junction bound (per axis
  the velocity step within one 4 ms tick at most a_k·Ts; R384 accuracy Lm/(Ts·tan(α/2)); R385
  am·Ts/(2·sin(α/2))), each chord at the full path acceleration min_k a_k/|u_k| and the path
  speed min(F, v_k/|u_k|): an exact forward/backward pass in continuous time;
- smooth: the time-optimal time on the smooth curve the chords sample, by TOPP-RA (PyPI
  `toppra`) with per-axis box constraints |v_k| <= vmax_k, |a_k| <= amax_k and the path speed
  F, from rest to rest between the corners the generator mixed in;
- limit = max(exact, smooth).

With `--path-accel A` (a constants file's R52/R236/R237) the speed along the path changes by at
most A as well: each chord's acceleration is at most A in the exact bound, and TOPP-RA bounds
the second derivative of a coordinate linear in its chord-length parameter by A.

Nothing here uses the planner's code. Output (committed): paths/<name>.nc and reference.tsv;
with --path-accel, reference-a<A>.tsv only. Run: scripts/planner-reference/run.sh (makes a venv
under target/ and installs toppra).
"""

import math
import os
import sys

import numpy as np
import toppra as ta
import toppra.algorithm as algo
import toppra.constraint as constraint
from scipy.interpolate import CubicSpline

ta.setup_logging("WARNING")

# The daemon's configuration of issue #32 (machine.py).
from machine import A_AXIS, AM, FEED, LM_MM, TS, V_AXIS  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
# Path acceleration, mm/s² (--path-accel; ∞: the axes' limits alone).
A_PATH = math.inf


# ---------------------------------------------------------------- path generation
class PathBuilder:
    """A polyline as smooth pieces: a corner between pieces (the smooth curve stops)."""

    def __init__(self, start):
        self.pieces = [[np.asarray(start, float)]]

    @property
    def pos(self):
        return self.pieces[-1][-1]

    def corner(self):
        if len(self.pieces[-1]) > 1:
            self.pieces.append([self.pos])

    def point(self, p):
        p = np.asarray(p, float)
        if np.linalg.norm(p - self.pos) > 1e-6:
            self.pieces[-1].append(p)

    def line(self, p):
        """A straight block with corners at both ends."""
        self.corner()
        self.point(p)
        self.corner()

    def curve(self, f, t0, t1, chord, rng=None, lo=0.01, hi=0.5):
        """Samples the curve f(t) from t0 to t1 in chords of `chord` mm (or random chords in
        lo..hi when rng is given), continuing the current piece (no corner)."""
        t = t0
        k = 0
        while t < t1:
            c = rng.uniform(lo, hi) if rng is not None else chord(k)
            d = (np.asarray(f(t + 1e-6)) - np.asarray(f(t - 1e-6))) / 2e-6
            speed = max(np.linalg.norm(d), 1e-6)
            t = min(t + c / speed, t1)
            self.point(f(t))
            k += 1


def line_100():
    b = PathBuilder((0, 0, 0))
    b.line((100, 0, 0))
    return b


def circle(r, chord):
    b = PathBuilder((r, 0, 0))
    n = round(2 * math.pi * r / chord)
    for i in range(1, n + 1):
        a = 2 * math.pi * i / n
        b.point((r * math.cos(a), r * math.sin(a), 0))
    return b


def zigzag(passes, width, step, seg):
    """Raster over z = 2·sin(x/5)·cos(y/7), passes along X, 1 mm step-overs (corners)."""
    z = lambda x, y: 2 * math.sin(x / 5) * math.cos(y / 7)
    b = PathBuilder((0, 0, z(0, 0)))
    n = round(width / seg)
    for k in range(passes):
        y = k * step
        for i in range(1, n + 1):
            x = i * seg if k % 2 == 0 else width - i * seg
            b.point((x, y, z(x, y)))
        x, y1 = b.pos[0], y + step
        b.line((x, y1, z(x, y1)))
    return b


def lissajous():
    f = lambda t: (30 * math.sin(3 * t), 20 * math.sin(4 * t), 0.0)
    b = PathBuilder(f(0))
    b.curve(f, 0.0, 2 * math.pi, lambda k: 0.06 + 0.04 * math.sin(k * 0.37))
    return b


def pocket_spiral(w, h, step, sides):
    b = PathBuilder((0, 0, 0))
    x0, y0, x1, y1 = 0.0, 0.0, w, h
    for k in range(sides):
        m = k % 4
        if m == 0:
            b.line((x1, y0, 0))
        elif m == 1:
            b.line((x1, y1, 0))
        elif m == 2:
            b.line((x0, y1, 0))
        else:
            x0 += step
            y0 += step
            x1 -= step
            y1 -= step
            b.line((x0 - step, y0, 0))
            b.line((x0, y0, 0))
    return b


def pentagram(r):
    pt = lambda k: (r * math.cos(2 * math.pi * (k % 5) * 2 / 5), r * math.sin(2 * math.pi * (k % 5) * 2 / 5), 0)
    b = PathBuilder(pt(0))
    for k in range(1, 6):
        b.line(pt(k))
    return b


def random_splines(seed):
    """Random smooth 2D curves (a few Fourier terms) joined at corners, random chords."""
    rng = np.random.default_rng(seed)
    b = PathBuilder((0, 0, 0))
    for _ in range(4):
        amp = rng.uniform(3, 15, size=(2, 3))
        freq = rng.integers(1, 4, size=(2, 3))
        phase = rng.uniform(0, 2 * math.pi, size=(2, 3))
        o = b.pos.copy()
        base = [sum(amp[d, j] * math.sin(phase[d, j]) for j in range(3)) for d in range(2)]

        def f(t, amp=amp, freq=freq, phase=phase, o=o, base=base):
            xy = [sum(amp[d, j] * math.sin(freq[d, j] * t + phase[d, j]) for j in range(3)) - base[d] for d in range(2)]
            return (o[0] + xy[0], o[1] + xy[1], 0.0)

        b.curve(f, 0.0, rng.uniform(2.0, 4.0), None, rng)
        b.corner()
    return b


def random_arcs(seed):
    """Arcs of random radius 2..30 mm and sweep, mostly tangent, some corners."""
    rng = np.random.default_rng(seed)
    b = PathBuilder((0, 0, 0))
    heading = 0.0
    for i in range(24):
        if i % 6 == 5:
            b.corner()
            heading += rng.uniform(0.5, 2.5) * rng.choice([-1, 1])
        r = rng.uniform(2, 30)
        sweep = rng.uniform(0.3, 2.5) * rng.choice([-1, 1])
        o = b.pos.copy()
        # centre on the left (ccw) or right (cw) of the heading
        s = 1 if sweep > 0 else -1
        cx = o[0] - s * r * math.sin(heading)
        cy = o[1] + s * r * math.cos(heading)
        a0 = math.atan2(o[1] - cy, o[0] - cx)

        def f(t, cx=cx, cy=cy, a0=a0, r=r, sweep=sweep):
            return (cx + r * math.cos(a0 + sweep * t), cy + r * math.sin(a0 + sweep * t), 0.0)

        b.curve(f, 0.0, 1.0, None, rng)
        heading += sweep
    return b


def random_surface(seed):
    """Raster over a random smooth surface in random chords, step-overs as corners."""
    rng = np.random.default_rng(seed)
    a = rng.uniform(0.5, 2.0, size=3)
    kx = rng.uniform(0.1, 0.4, size=3)
    ky = rng.uniform(0.05, 0.3, size=3)
    z = lambda x, y: sum(a[j] * math.sin(kx[j] * x + j) * math.cos(ky[j] * y) for j in range(3))
    width = 30.0
    b = PathBuilder((0, 0, z(0, 0)))
    for k in range(8):
        y = k * 1.0
        x0 = b.pos[0]
        sign = 1 if k % 2 == 0 else -1
        b.curve(lambda t, y=y, x0=x0, sign=sign: (x0 + sign * t, y, z(x0 + sign * t, y)), 0.0, width, None, rng)
        x = b.pos[0]
        b.line((x, y + 1.0, z(x, y + 1.0)))
    return b


def random_helix(seed):
    """A 3D spiral with a wobble in Z in random chords."""
    rng = np.random.default_rng(seed)
    r0, r1 = rng.uniform(5, 10), rng.uniform(15, 25)
    turns = 3
    wob = rng.uniform(0.5, 2.0)
    f = lambda t: (
        (r0 + (r1 - r0) * t / (2 * math.pi * turns)) * math.cos(t),
        (r0 + (r1 - r0) * t / (2 * math.pi * turns)) * math.sin(t),
        -0.5 * t + wob * math.sin(3 * t),
    )
    b = PathBuilder(f(0))
    b.curve(f, 0.0, 2 * math.pi * turns, None, rng)
    return b


PATHS = [
    ("line", "line 100 mm", line_100),
    ("circle", "circle r20, 0.05 mm chords", lambda: circle(20.0, 0.05)),
    ("zigzag", "3D zig-zag, 0.2 mm chords", lambda: zigzag(50, 40.0, 1.0, 0.2)),
    ("pocket", "rectangular spiral pocket", lambda: pocket_spiral(60.0, 40.0, 1.0, 41)),
    ("lissajous", "Lissajous, 0.02-0.1 mm chords", lissajous),
    ("pentagram", "pentagram R40", lambda: pentagram(40.0)),
    ("splines", "random splines, 0.01-0.5 mm chords, corners", lambda: random_splines(1)),
    ("arcs", "random arcs R2-30, 0.01-0.5 mm chords, corners", lambda: random_arcs(2)),
    ("surface", "random 3D surface raster, 0.01-0.5 mm chords", lambda: random_surface(3)),
    ("helix", "3D spiral with Z wobble, 0.01-0.5 mm chords", lambda: random_helix(4)),
]


# ---------------------------------------------------------------- programs
def fmt(v):
    s = f"{v:.6f}"
    return "0.000000" if s == "-0.000000" else s


def to_program(builder):
    """Rounds the points as the program states them; translates the start to the origin.
    Returns (points as the program has them, corner flags per junction, .nc text)."""
    pts = [builder.pieces[0][0]]
    corner_after = []  # per point index (junction) whether the smooth curve stops there
    for i, piece in enumerate(builder.pieces):
        for p in piece[1:]:
            pts.append(p)
            corner_after.append(False)
        if corner_after:
            corner_after[-1] = True
    origin = pts[0]
    rounded = [np.array([float(fmt(c)) for c in (p - origin)]) for p in pts]
    lines = []
    for k, p in enumerate(rounded[1:]):
        words = f"G1 X{fmt(p[0])} Y{fmt(p[1])} Z{fmt(p[2])}"
        lines.append(("G23 " + words + f" F{FEED * 60:.0f}") if k == 0 else words)
    # drop zero-length chords created by rounding
    keep = [rounded[0]]
    flags = []
    for p, c in zip(rounded[1:], corner_after):
        if np.linalg.norm(p - keep[-1]) > 1e-9:
            keep.append(p)
            flags.append(c)
        elif flags:
            flags[-1] = flags[-1] or c
    keep = np.array(keep)
    # A "corner" where the path runs straight on (the pocket's step-over continuing into
    # the next side) is no corner of the smooth curve.
    u = np.diff(keep, axis=0)
    u /= np.linalg.norm(u, axis=1)[:, None]
    for i in range(len(flags) - 1):
        if flags[i] and np.dot(u[i], u[i + 1]) > 1 - 1e-12:
            flags[i] = False
    return keep, flags, "\n".join(lines) + "\n"


# ---------------------------------------------------------------- exact polyline bound
def exact_polyline_s(pts):
    d = np.diff(pts, axis=0)
    L = np.linalg.norm(d, axis=1)
    u = d / L[:, None]
    n = len(L)
    with np.errstate(divide="ignore"):
        vseg = np.minimum(FEED, np.min(np.where(np.abs(u) > 1e-12, V_AXIS / np.abs(u), np.inf), axis=1))
        aseg = np.min(np.where(np.abs(u) > 1e-12, A_AXIS / np.abs(u), np.inf), axis=1)
    aseg = np.minimum(aseg, A_PATH)
    cap = np.zeros(n)  # speed at the end of chord i
    for i in range(n - 1):
        du = u[i + 1] - u[i]
        chord = np.linalg.norm(du)  # 2·sin(α/2)
        c = min(vseg[i], vseg[i + 1])
        if chord > 1e-12:
            c = min(c, np.min(np.where(np.abs(du) > 1e-15, A_AXIS * TS / np.maximum(np.abs(du), 1e-300), np.inf)))
            c = min(c, AM * TS / chord)
            half = math.asin(min(chord / 2, 1.0))
            tan = math.tan(half) if chord < 2 - 1e-12 else math.inf
            c = min(c, LM_MM / (TS * tan) if tan > 0 else math.inf)
        cap[i] = c
    cap[-1] = 0.0
    end = cap.copy()
    for k in range(n - 1, 0, -1):
        end[k - 1] = min(end[k - 1], math.sqrt(end[k] ** 2 + 2 * aseg[k] * L[k]))
    t = 0.0
    v0 = 0.0
    for k in range(n):
        a, l = aseg[k], L[k]
        end[k] = min(end[k], math.sqrt(v0 * v0 + 2 * a * l))
        v1 = end[k]
        peak = min(vseg[k], math.sqrt((2 * a * l + v0 * v0 + v1 * v1) / 2))
        ramps = (2 * peak * peak - v0 * v0 - v1 * v1) / (2 * a)
        t += (peak - v0) / a + (peak - v1) / a + max(l - ramps, 0.0) / peak
        v0 = v1
    return t


# ---------------------------------------------------------------- smooth curve, TOPP-RA
def toppra_piece_s(pts):
    """Time-optimal time from rest to rest along the cubic spline through `pts` (chord-length
    parameter), per-axis box constraints and the path speed F."""
    d = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    ss = np.concatenate([[0.0], np.cumsum(d)])
    if len(pts) == 2:
        # A straight chord: exact trapezoid.
        u = np.abs(pts[1] - pts[0]) / ss[-1]
        v = min(FEED, np.min(V_AXIS / u[u > 1e-12]))
        a = min(np.min(A_AXIS / u[u > 1e-12]), A_PATH)
        l = ss[-1]
        if v * v / a >= l:
            return 2 * math.sqrt(l / a)
        return l / v + v / a
    # The path speed |q'|·ṡ ≤ F as a fourth coordinate: the arc length of the spline
    # through the points, with speed limit F and no acceleration limit.
    spline = CubicSpline(ss, pts, axis=0)
    fine = np.linspace(0.0, ss[-1], 20 * len(ss) + 1)
    speed = np.linalg.norm(spline.derivative()(fine), axis=1)
    arc = np.concatenate([[0.0], np.cumsum((speed[1:] + speed[:-1]) / 2 * np.diff(fine))])
    arc_at = np.interp(ss, fine, arc)
    # With a path acceleration, a fifth coordinate linear in the (chord-length) parameter
    # carries it: its second derivative is s̈ alone (the spline's arc length, interpolated,
    # is too noisy in its second derivative for the solver).
    cols = [pts, arc_at] + ([ss] if math.isfinite(A_PATH) else [])
    path = ta.SplineInterpolator(ss, np.column_stack(cols))
    for spacing in (0.02, 0.017, 0.023, 0.013, 0.029):
        n_grid = int(min(max(ss[-1] / spacing, 200), 60000))
        t = toppra_grid_s(path, np.linspace(0.0, ss[-1], n_grid + 1))
        if t is not None:
            return t
        print(f"  (TOPP-RA failed on a grid of {spacing} mm over {ss[-1]:.1f} mm, retrying)", flush=True)
    # The solver fails on an axis that barely moves (a pass at z ≈ 1e-3 mm of rounded
    # coordinates): flatten such axes (their constraint cannot bind) and solve again.
    span = pts.max(axis=0) - pts.min(axis=0)
    flat = (span > 0) & (span < 0.01)
    if flat.any():
        print(f"  (flattening axes {np.nonzero(flat)[0]} of span {span[flat]} mm)", flush=True)
        pts = pts.copy()
        pts[:, flat] = pts[0, flat]
        return toppra_piece_s(pts)
    raise RuntimeError("TOPP-RA found no parameterization")


def toppra_grid_s(path, grid):
    v_lim = [[-V_AXIS, V_AXIS]] * 3 + [[-FEED, FEED]]
    a_lim = [[-A_AXIS, A_AXIS]] * 3 + [[-1e6, 1e6]]
    if math.isfinite(A_PATH):
        v_lim.append([-1e6, 1e6])
        a_lim.append([-A_PATH, A_PATH])
    cons = [
        constraint.JointVelocityConstraint(np.array(v_lim)),
        constraint.JointAccelerationConstraint(np.array(a_lim)),
    ]
    inst = algo.TOPPRA(cons, path, gridpoints=grid, solver_wrapper="seidel")
    res = inst.compute_parameterization(0, 0)
    sd = res[1]
    if sd is None:
        return None
    sd = np.maximum(sd, 0.0)
    ds = np.diff(grid)
    v = sd[:-1] + sd[1:]
    return float(np.sum(np.where(v > 1e-12, 2 * ds / np.maximum(v, 1e-12), 0.0)))


def smooth_s(pts, flags):
    total = 0.0
    start = 0
    for i, corner in enumerate(flags):
        if corner:
            total += toppra_piece_s(pts[start : i + 2])
            start = i + 1
    if start < len(pts) - 1:
        total += toppra_piece_s(pts[start:])
    return total


def main():
    global A_PATH
    args = sys.argv[1:]
    table = "reference.tsv"
    if args[:1] == ["--path-accel"]:
        A_PATH = float(args[1])
        table = f"reference-a{A_PATH:g}.tsv"
        args = args[2:]
    out_dir = os.path.join(HERE, "paths")
    os.makedirs(out_dir, exist_ok=True)
    only = set(args)
    rows = []
    for key, title, gen in PATHS:
        if only and key not in only:
            continue
        pts, flags, text = to_program(gen())
        if table == "reference.tsv":
            with open(os.path.join(out_dir, f"{key}.nc"), "w") as f:
                f.write(text)
        ex = exact_polyline_s(pts)
        sm = smooth_s(pts, flags)
        length = float(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1)))
        rows.append((key, len(pts) - 1, length, ex, sm, max(ex, sm), title))
        print(f"{key:10s} {len(pts) - 1:6d} blocks {length:9.2f} mm  exact {ex:8.4f} s  smooth {sm:8.4f} s", flush=True)
    if only:
        return
    with open(os.path.join(HERE, table), "w") as f:
        f.write("# name\tblocks\tlength_mm\texact_s\tsmooth_s\tlimit_s\ttitle\n")
        for r in rows:
            f.write(f"{r[0]}\t{r[1]}\t{r[2]:.4f}\t{r[3]:.5f}\t{r[4]:.5f}\t{r[5]:.5f}\t{r[6]}\n")


if __name__ == "__main__":
    main()
