#!/usr/bin/env python3
"""What the zone budgets of issue #32 are worth if they follow the ticks' speed.

hold_estimate.py gives the ticks that touch a junction J (the zone [J - c*Ts, J + c*Ts], c
the junction's cap, held there as a ceiling) what the turn leaves *at c*. A tick slower than
c carries less of the turn: its second difference weighs J's turn by at most its step v*Ts.
This estimate gives the zone what the turn leaves at the local speed v,
min_k (a_k - v*|du_k|/Ts)/|u_k|, by integrating v*dv/dx = a(x, v) on a grid of 2 um (forward
and backward, from rest to rest); every other point takes the chord's full path acceleration.
Columns: the zone at full acceleration ("zones at c" of hold_estimate.py, as a check of the
grid), and at shares 1 and 0.85 of the axis for the turn, the zone budget at c and at the
local speed. Estimates, not bounds, with the caveats of hold_estimate.py. No planner code.

Usage: target/planner-ref/venv/bin/python scripts/planner-reference/follow_estimate.py
[path ...]   (default: splines arcs helix surface; about 5 s per path and column)
"""

import math
import sys

import numpy as np

from hold_estimate import chords, junction_caps, limits_s, load
from machine import A_AXIS, TS

DX_MM = 0.002


def grid(name, share):
    """Per grid point: ceiling, the chord's acceleration, and the zone's turn per axis
    (|du_k|/Ts, largest tangent component; 0 outside every zone)."""
    u, vseg, aseg, s = chords(load(name))
    caps = junction_caps(u, vseg, share)
    n = int(math.ceil(s[-1] / DX_MM)) + 1
    x = np.linspace(0.0, s[-1], n)
    chord = np.minimum(np.searchsorted(s, x, side="right") - 1, len(u) - 1)
    ceiling, accel = vseg[chord].copy(), aseg[chord].copy()
    turn, along = np.zeros((n, 3)), np.zeros((n, 3))
    for i in np.flatnonzero(np.isfinite(caps)):
        at, c = s[i + 1], caps[i]
        lo, hi = np.searchsorted(x, at - c * TS), np.searchsorted(x, at + c * TS, side="right")
        ceiling[lo:hi] = np.minimum(ceiling[lo:hi], c)
        k = min(np.searchsorted(x, at), n - 1)
        ceiling[k] = min(ceiling[k], c)
        turn[lo:hi] = np.maximum(turn[lo:hi], np.abs(u[i + 1] - u[i]) / TS)
        along[lo:hi] = np.maximum(along[lo:hi], np.maximum(np.abs(u[i]), np.abs(u[i + 1])))
    return ceiling, accel, turn, along


def time_s(name, share, zone):
    """Machining time with the zone acceleration `zone`: "full", "cap" or "local"."""
    ceiling, accel, turn, along = grid(name, share)
    n = len(ceiling)
    zoned = turn.max(axis=1) > 0.0

    def a_at(j, v):
        if zone == "full" or not zoned[j]:
            return accel[j]
        w = ceiling[j] if zone == "cap" else v
        best = accel[j]
        for k in range(3):
            if along[j, k] > 1e-12:
                best = min(best, (A_AXIS - w * turn[j, k]) / along[j, k])
        return max(best, 1e-6)

    back = ceiling.copy()
    back[-1] = 0.0
    for j in range(n - 2, -1, -1):
        w = back[j + 1]
        back[j] = min(back[j], math.sqrt(w * w + 2.0 * a_at(j, w) * DX_MM))
    fwd = back.copy()
    fwd[0] = 0.0
    for j in range(1, n):
        w = fwd[j - 1]
        fwd[j] = min(fwd[j], math.sqrt(w * w + 2.0 * a_at(j - 1, w) * DX_MM))
    mean = np.maximum((fwd[1:] + fwd[:-1]) / 2.0, 1e-9)
    return float(np.sum(DX_MM / mean))


def main():
    limits = limits_s()
    runs = ((1.0, "full"), (1.0, "cap"), (1.0, "local"), (0.85, "cap"), (0.85, "local"))
    print("path       limit   " + "   ".join(f"{z} {s}" for s, z in runs))
    for name in sys.argv[1:] or ["splines", "arcs", "helix", "surface"]:
        lim = limits[name]
        cols = [time_s(name, s, z) for s, z in runs]
        print(f"{name:10s} {lim:6.3f}  " + "  ".join(f"{t:.3f} ({t / lim:.3f})" for t in cols),
              flush=True)


if __name__ == "__main__":
    main()
