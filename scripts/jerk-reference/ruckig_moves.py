#!/usr/bin/env python3
"""Time-optimal jerk-limited moves by Ruckig (issue #49), independent of the planner.

Each move of moves.tsv is a straight line from rest to rest. Along it the path is one degree
of freedom with the limits a constants file gives a machine (SPEC §7.3, §7.4): speed F (and
the axes' speeds), acceleration min(A, a_k/|u_k|), jerk min(J, j_k/|u_k|), J = 0.0305·P
(jerk_from_p: 4·P/(60·1.478²)). Ruckig (PyPI) computes the time-optimal profile under those
limits in continuous time. Output (committed): ruckig-<rek>.tsv. Run: run.sh.

Machine: 3 axes of 20000 mm/min, 1000 mm/s², jerk 50·a = 50000 mm/s³ (the reference machine,
scripts/planner-reference, with cncd's axis jerk rule).
"""

import math
import os
import sys

from ruckig import InputParameter, Result, Ruckig, Trajectory

HERE = os.path.dirname(os.path.abspath(__file__))
V_AXIS = 20000.0 / 60.0
A_AXIS = 1000.0
J_AXIS = 50.0 * A_AXIS

# Each constants file: the set's path acceleration A and jerk J (∞: the axes' alone).
FILES = {
    # Set 1 in use: P = 150000, A = 600 mm/s².
    "parabolic-set": (600.0, 4.0 * 150000.0 / (60.0 * 1.478 * 1.478)),
    # Only the profile: R236 → R52 = 500 mm/s² (default), no set, the axes' jerk.
    "parabolic-default": (500.0, math.inf),
}


def moves():
    with open(os.path.join(HERE, "moves.tsv")) as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            name, x, y, z, feed, _ = line.rstrip("\n").split("\t")
            yield name, [float(x), float(y), float(z)], float(feed)


def duration(d, v, a, j):
    otg = Ruckig(1)
    inp = InputParameter(1)
    inp.current_position = [0.0]
    inp.current_velocity = [0.0]
    inp.current_acceleration = [0.0]
    inp.target_position = [d]
    inp.target_velocity = [0.0]
    inp.target_acceleration = [0.0]
    inp.max_velocity = [v]
    inp.max_acceleration = [a]
    inp.max_jerk = [j]
    traj = Trajectory(1)
    result = otg.calculate(inp, traj)
    assert result in (Result.Working, Result.Finished), result
    return traj.duration


def main():
    for rek, (set_a, set_j) in FILES.items():
        rows = []
        for name, delta, feed in moves():
            length = math.sqrt(sum(x * x for x in delta))
            u = [abs(x) / length for x in delta]
            v = min([feed / 60.0] + [V_AXIS / c for c in u if c > 0])
            a = min([set_a] + [A_AXIS / c for c in u if c > 0])
            j = min([set_j] + [J_AXIS / c for c in u if c > 0])
            t = duration(length, v, a, j)
            rows.append((name, length, v, a, j, t))
            print(f"{rek:18s} {name:9s} {length:8.3f} mm  v {v:7.2f}  a {a:7.1f}  j {j:8.1f}  {t:.4f} s")
        with open(os.path.join(HERE, f"ruckig-{rek}.tsv"), "w") as f:
            f.write("# name\tlength_mm\tv_mm_s\ta_mm_s2\tj_mm_s3\truckig_s\n")
            for r in rows:
                f.write(f"{r[0]}\t{r[1]:.6f}\t{r[2]:.6f}\t{r[3]:.3f}\t{r[4]:.3f}\t{r[5]:.6f}\n")


if __name__ == "__main__":
    sys.exit(main())
