#!/usr/bin/env python3
"""What the rest of issue #32 is worth: the exact polyline bound of reference.py with each
junction's cap also held over the ticks that touch it.

A planner whose setpoints stay on the polyline cannot pass a junction J at its exact bound c
and accelerate on both sides of it at full rate: the ticks whose steps touch J carry its turn
in their second difference. This reruns the reference's exact continuous pass (intervals of
constant ceiling and acceleration, as `exact_polyline_s` does over chords) with c as a ceiling
over [J - c*Ts, J + c*Ts], and there either
- the chord's full acceleration ("zones at c"), or
- only what the turn leaves at c, min_k (a_k - c*|du_k|/Ts)/|u_k| (nothing where the per-axis
  term sets c: the ticks hold c), with the per-axis term at the whole axis and at 0.8 of it
  (the planner's BOX_NORMAL_SHARE).
Every other stretch takes the chord's full path acceleration. These are estimates, not bounds:
like the exact bound they weigh each turn alone where junctions lie closer than a step, and
where R384/R385 set c the ticks beside J may run faster than c. No planner code is used.

Usage (numpy, as in the venv run.sh makes): target/planner-ref/venv/bin/python
scripts/planner-reference/hold_estimate.py [path ...]   (default: all paths)
"""

import math
import os
import re
import sys

import numpy as np

# The daemon's configuration of issue #32 (machine.py).
from machine import A_AXIS, AM, FEED, LM_MM, TS, V_AXIS  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
PATHS = ["line", "circle", "zigzag", "pocket", "lissajous", "pentagram", "splines", "arcs",
         "surface", "helix"]


def load(name):
    """The program's points, from the origin (reference.py writes absolute G1 X Y Z)."""
    pts = [np.zeros(3)]
    with open(os.path.join(HERE, "paths", f"{name}.nc")) as f:
        for line in f:
            words = dict(re.findall(r"([XYZ])(-?[0-9.]+)", line))
            if words:
                pts.append(np.array([float(words.get(a, pts[-1]["XYZ".index(a)])) for a in "XYZ"]))
    return np.array(pts)


def junction_caps(u, vseg, share):
    """Per junction the exact bound of reference.py, its per-axis term at `share` of the
    axis (inf where the path runs straight on)."""
    caps = np.full(len(u) - 1, np.inf)
    for i in range(len(u) - 1):
        du = u[i + 1] - u[i]
        chord = np.linalg.norm(du)
        if chord <= 1e-12:
            continue
        c = min(vseg[i], vseg[i + 1], AM * TS / chord)
        turning = np.abs(du) > 1e-15
        if turning.any():
            c = min(c, share * np.min(A_AXIS * TS / np.abs(du[turning])))
        tan = math.tan(math.asin(min(chord / 2, 1.0))) if chord < 2 - 1e-12 else math.inf
        caps[i] = min(c, LM_MM / (TS * tan) if tan > 0 else math.inf)
    return caps


def zone_accel(u0, u1, cap):
    """Path acceleration the turn leaves the ticks touching the junction at `cap`, per axis
    a_k - cap*|du_k|/Ts along the larger tangent component (0: they hold the speed; a tiny
    floor keeps the pass finite)."""
    du, d = np.abs(u1 - u0), np.maximum(np.abs(u0), np.abs(u1))
    left = A_AXIS - cap * du / TS
    moving = d > 1e-12
    return max(float(np.min(left[moving] / d[moving])), 1e-6)


def chords(pts):
    """The polyline's chords: unit tangents, per chord the speed ceiling min(F, v_k/|u_k|)
    and the full path acceleration min a_k/|u_k|, and the arc length at each point."""
    d = np.diff(pts, axis=0)
    length = np.linalg.norm(d, axis=1)
    d, length = d[length > 1e-9], length[length > 1e-9]
    u = d / length[:, None]
    with np.errstate(divide="ignore"):
        vseg = np.minimum(FEED, np.min(np.where(np.abs(u) > 1e-12, V_AXIS / np.abs(u), np.inf), axis=1))
        aseg = np.min(np.where(np.abs(u) > 1e-12, A_AXIS / np.abs(u), np.inf), axis=1)
    return u, vseg, aseg, np.concatenate([[0.0], np.cumsum(length)])


def intervals(pts, share, hold, budget):
    """Intervals of constant ceiling and acceleration: (lengths, ceilings, accelerations,
    caps at their ends)."""
    u, vseg, aseg, s = chords(pts)
    caps = junction_caps(u, vseg, share)
    at = s[1:-1]
    half = np.where(np.isfinite(caps), caps * TS, 0.0) if hold else np.zeros(len(caps))
    bp = np.unique(np.clip(np.concatenate([s, at - half, at + half]), 0.0, s[-1]))
    chord = np.minimum(np.searchsorted(s, (bp[1:] + bp[:-1]) / 2, side="right") - 1, len(u) - 1)
    ceiling, accel = vseg[chord].copy(), aseg[chord].copy()
    end_cap = np.full(len(bp), np.inf)
    for i in np.flatnonzero(np.isfinite(caps)):
        lo, hi = np.searchsorted(bp, at[i] - half[i]), np.searchsorted(bp, at[i] + half[i])
        ceiling[lo:hi] = np.minimum(ceiling[lo:hi], caps[i])
        if budget:
            accel[lo:hi] = np.minimum(accel[lo:hi], zone_accel(u[i], u[i + 1], caps[i]))
        k = np.searchsorted(bp, at[i])
        end_cap[k] = min(end_cap[k], caps[i])
    ends = np.minimum(end_cap[1:], np.minimum(ceiling, np.append(ceiling[1:], 0.0)))
    ends[-1] = 0.0
    return np.diff(bp), ceiling, accel, ends


def time_s(pts, share, hold, budget):
    """Forward/backward pass in continuous time over the intervals, from rest to rest."""
    length, ceiling, accel, end = intervals(pts, share, hold, budget)
    for k in range(len(length) - 1, 0, -1):
        end[k - 1] = min(end[k - 1], math.sqrt(end[k] ** 2 + 2 * accel[k] * length[k]))
    t, v0 = 0.0, 0.0
    for k in range(len(length)):
        a, l = accel[k], length[k]
        end[k] = min(end[k], math.sqrt(v0 * v0 + 2 * a * l))
        v1 = end[k]
        peak = min(ceiling[k], math.sqrt((2 * a * l + v0 * v0 + v1 * v1) / 2))
        ramps = (2 * peak * peak - v0 * v0 - v1 * v1) / (2 * a)
        t += (peak - v0) / a + (peak - v1) / a + max(l - ramps, 0.0) / peak
        v0 = v1
    return t


def limits_s():
    """Per path the limit of reference.tsv, max(exact, smooth), s."""
    limits = {}
    with open(os.path.join(HERE, "reference.tsv")) as f:
        for row in f:
            if not row.startswith("#"):
                cols = row.split("\t")
                limits[cols[0]] = float(cols[5])
    return limits


def main():
    limits = limits_s()
    runs = ((1.0, False, False), (1.0, True, False), (1.0, True, True), (0.8, True, True))
    print("path          limit    exact   zones at c (/limit)   + budget at c (/limit)   "
          "share 0.8 + budget (/limit)")
    for name in sys.argv[1:] or PATHS:
        pts = load(name)
        lim = limits[name]
        t = [time_s(pts, *r) for r in runs]
        print(f"{name:10s} {lim:8.3f} {t[0]:8.3f} {t[1]:10.3f} ({t[1] / lim:.3f}) "
              f"{t[2]:14.3f} ({t[2] / lim:.3f}) {t[3]:19.3f} ({t[3] / lim:.3f})", flush=True)


if __name__ == "__main__":
    main()
