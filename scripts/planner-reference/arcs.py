#!/usr/bin/env python3
"""Arc-fitted paths (issue #49): what CAM posts when it fits arcs to a contour, tangent G2/G3
arcs turning either way, and contours of lines whose corners CAM rounds with small tangent
fillets, in the CNC836 dialect (I J relative to the arc's start).

Writes arcs/<name>.nc; ticks.py --dir arcs then finds what 4 ms setpoints on those arcs allow
(it draws each arc in 5 µm chords itself). Deterministic; plain Python.
Run: python3 arcs.py
"""

import math
import os
import random

HERE = os.path.dirname(os.path.abspath(__file__))


def arc_chain(seed, count, radii, lengths):
    """G-code lines of `count` tangent arcs from the origin heading +X."""
    rng = random.Random(seed)
    x, y, heading = 0.0, 0.0, 0.0
    lines = []
    for n in range(count):
        r = rng.uniform(*radii)
        length = rng.uniform(*lengths)
        turn = rng.choice([1, -1])  # +1 counter-clockwise (G3)
        cx = x - turn * r * math.sin(heading)
        cy = y + turn * r * math.cos(heading)
        a1 = math.atan2(y - cy, x - cx) + turn * length / r
        ex, ey = cx + r * math.cos(a1), cy + r * math.sin(a1)
        word = "G3" if turn > 0 else "G2"
        head = "G23 " if n == 0 else ""
        tail = " F6000" if n == 0 else ""
        lines.append(f"{head}{word} X{ex:.6f} Y{ey:.6f} I{cx - x:.6f} J{cy - y:.6f}{tail}")
        # (The next arc starts where this one ends as written, tangent to it.)
        x, y = float(f"{ex:.6f}"), float(f"{ey:.6f}")
        heading += turn * length / r
    return lines


def filleted(seed, count, radii, lengths, turns_deg):
    """G-code lines of a contour of `count` lines from the origin heading +X, each corner
    rounded by a tangent fillet (turning 20-120° either way)."""
    rng = random.Random(seed)
    x, y, heading = 0.0, 0.0, 0.0
    lines = []
    for n in range(count):
        length = rng.uniform(*lengths)
        x = float(f"{x + length * math.cos(heading):.6f}")
        y = float(f"{y + length * math.sin(heading):.6f}")
        head = "G23 " if n == 0 else ""
        tail = " F6000" if n == 0 else ""
        lines.append(f"{head}G1 X{x:.6f} Y{y:.6f}{tail}")
        r = rng.uniform(*radii)
        turn = rng.choice([1, -1]) * math.radians(rng.uniform(*turns_deg))
        side = 1 if turn > 0 else -1
        cx = x - side * r * math.sin(heading)
        cy = y + side * r * math.cos(heading)
        a1 = math.atan2(y - cy, x - cx) + turn
        ex, ey = cx + r * math.cos(a1), cy + r * math.sin(a1)
        word = "G3" if side > 0 else "G2"
        lines.append(f"{word} X{ex:.6f} Y{ey:.6f} I{cx - x:.6f} J{cy - y:.6f}")
        x, y = float(f"{ex:.6f}"), float(f"{ey:.6f}")
        heading += turn
    return lines


PATHS = {
    # Contours fitted with arcs of 3-30 mm radius, 1-6 mm long.
    "arcfit": (arc_chain, 49, 60, (3.0, 30.0), (1.0, 6.0)),
    # Small features: 0.5-5 mm radius, 0.2-1.5 mm long.
    "arcfit-small": (arc_chain, 50, 200, (0.5, 5.0), (0.2, 1.5)),
    # Lines of 1-4 mm with corners rounded by fillets of 0.01-0.05 mm and 0.05-0.2 mm radius:
    # a step at the feed (0.4 mm) crosses a fillet whole.
    "fillet-tiny": (filleted, 51, 80, (0.01, 0.05), (1.0, 4.0)),
    "fillet-small": (filleted, 52, 80, (0.05, 0.2), (1.0, 4.0)),
}


def main():
    os.makedirs(os.path.join(HERE, "arcs"), exist_ok=True)
    for name, (make, seed, count, radii, lengths) in PATHS.items():
        extra = ((20.0, 120.0),) if make is filleted else ()
        with open(os.path.join(HERE, "arcs", f"{name}.nc"), "w") as f:
            f.write("\n".join(make(seed, count, radii, lengths, *extra)) + "\n")


if __name__ == "__main__":
    main()
