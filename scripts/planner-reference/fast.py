#!/usr/bin/env python3
"""Fast paths (issue #49): reference paths of long lines at F20000, the axes' speed. With the
path accelerations of a constants file (500 mm/s²) braking from their speed takes longer than
the per-axis box proves (64 ticks), so the envelope runs between their corners and hands the
motion over to the box and back: what that costs shows against ticks.py.

Writes fast/<name>-fast.nc from paths/<name>.nc with F20000. Deterministic; plain Python.
Run: python3 fast.py; then python3 ticks.py --dir fast [--path-accel A].
"""

import os

HERE = os.path.dirname(os.path.abspath(__file__))
NAMES = ["line", "pentagram", "pocket"]


def main():
    os.makedirs(os.path.join(HERE, "fast"), exist_ok=True)
    for name in NAMES:
        with open(os.path.join(HERE, "paths", f"{name}.nc")) as f:
            text = f.read().replace("F6000", "F20000")
        with open(os.path.join(HERE, "fast", f"{name}-fast.nc"), "w") as f:
            f.write(text)


if __name__ == "__main__":
    main()
