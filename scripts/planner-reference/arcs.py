#!/usr/bin/env python3
"""Arc-fitted paths (issue #49): what CAM posts when it fits arcs to a contour, tangent G2/G3
arcs turning either way, in the CNC836 dialect (I J relative to the arc's start).

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


PATHS = {
    # Contours fitted with arcs of 3-30 mm radius, 1-6 mm long.
    "arcfit": (49, 60, (3.0, 30.0), (1.0, 6.0)),
    # Small features: 0.5-5 mm radius, 0.2-1.5 mm long.
    "arcfit-small": (50, 200, (0.5, 5.0), (0.2, 1.5)),
}


def main():
    os.makedirs(os.path.join(HERE, "arcs"), exist_ok=True)
    for name, (seed, count, radii, lengths) in PATHS.items():
        with open(os.path.join(HERE, "arcs", f"{name}.nc"), "w") as f:
            f.write("\n".join(arc_chain(seed, count, radii, lengths)) + "\n")


if __name__ == "__main__":
    main()
