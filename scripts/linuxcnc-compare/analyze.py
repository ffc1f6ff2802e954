#!/usr/bin/env python3
"""Reads LinuxCNC's servo-period samples (commanded X Y Z and path speed every 1 ms) and the
planner bench's reference table, and prints both side by side (markdown).

Usage: analyze.py <paths dir> <samples dir> <bench output> names...
Time = servo periods from the last period at rest before motion to the last period that moves.
Axis acceleration = second differences of the commanded positions at 1 ms, and at 4 ms (every
4th sample, the planner's tick) relative to 1000 mm/s². Deviation = largest distance of a
commanded position from the programmed polyline.
"""

import os
import sys

import numpy as np

A_AXIS = 1000.0
SERVO_S = 0.001
IDLE_GAP_S = 0.3
# A nearest distance beyond this in the search window is looked for on the whole path.
LOST_MM = 0.05


def polyline(nc_path):
    """The programmed path as a polyline: its G1 points, its G2/G3 arcs drawn in 5 µm chords
    (ticks.py's reading, plain geometry)."""
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "../planner-reference"))
    from ticks import read_polyline

    return np.array(read_polyline(nc_path))


def deviation_mm(samples, pts):
    """Largest distance of the samples from the polyline; samples progress along it, so the
    nearest segment is searched in a window ahead of the last one."""
    a = pts[:-1]
    d = pts[1:] - pts[:-1]
    l2 = np.maximum((d * d).sum(axis=1), 1e-30)
    k = 0
    worst = 0.0
    n = len(a)
    for p in samples:
        lo, hi = max(k - 5, 0), min(k + 400, n)
        t = np.clip(((p - a[lo:hi]) * d[lo:hi]).sum(axis=1) / l2[lo:hi], 0.0, 1.0)
        dist = np.linalg.norm(a[lo:hi] + d[lo:hi] * t[:, None] - p, axis=1)
        j = int(np.argmin(dist))
        if dist[j] > LOST_MM:
            # Lost in the window (a slow run's samples lag the search): the whole path.
            t = np.clip(((p - a) * d).sum(axis=1) / l2, 0.0, 1.0)
            dist = np.linalg.norm(a + d * t[:, None] - p, axis=1)
            lo, j = 0, int(np.argmin(dist))
        k = lo + j
        worst = max(worst, float(dist[j]))
    return worst


def linuxcnc_figures(samples_file, pts):
    # (halsampler reports FIFO overruns of the idle time before the run as text lines)
    rows = [list(map(float, l.split())) for l in open(samples_file) if l.strip() and l[0] in "-0123456789"]
    s = np.array(rows)
    pos = s[:, :3]
    moving = np.nonzero(np.abs(np.diff(pos, axis=0)).max(axis=1) > 1e-9)[0]
    # The sampler's FIFO still holds the return to the origin after the program before: the
    # program is the last motion after an idle gap of at least IDLE_GAP_S.
    gaps = np.nonzero(np.diff(moving) > IDLE_GAP_S / SERVO_S)[0]
    start = moving[gaps[-1] + 1] if len(gaps) else moving[0]
    first, last = start, moving[-1] + 1
    seg = pos[first : last + 1]
    time_s = (last - first) * SERVO_S
    acc1 = np.abs(np.diff(seg, 2, axis=0)).max() / SERVO_S**2 / A_AXIS
    dec = seg[::4]
    acc4 = np.abs(np.diff(dec, 2, axis=0)).max() / (4 * SERVO_S) ** 2 / A_AXIS
    return time_s, acc1, acc4, deviation_mm(seg, pts)


def ours_table(bench_out):
    out = {}
    for line in open(bench_out):
        f = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(f) == 9 and f[1].isdigit():
            out[f[0]] = dict(blocks=int(f[1]), limit=float(f[4]), time=float(f[5]), acc=float(f[7]), off=float(f[8]))
    return out


def write_tsv(rows):
    """LinuxCNC's figures beside this script (linuxcnc.tsv, or linuxcnc-a<A>.tsv with
    PATH_ACCEL; committed): the planner's test plan_reference holds the planner to be faster
    on every path."""
    here = os.path.dirname(os.path.abspath(__file__))
    if os.environ.get("DIR"):
        here = os.path.join(here, "../planner-reference", os.environ["DIR"])
    accel = os.environ.get("PATH_ACCEL")
    name = f"linuxcnc-a{accel}.tsv" if accel else "linuxcnc.tsv"
    traj = f", [TRAJ] MAX_LINEAR_ACCELERATION and every axis's MAX_ACCELERATION = {accel}" if accel else ""
    with open(os.path.join(here, name), "w") as f:
        f.write(
            "# LinuxCNC 2.9 on the reference paths (run.sh: headless simulated machine, 1 ms servo, "
            f"G64 P0.008{traj}); analyze.py writes this file.\n"
        )
        f.write("# name\ttime_s\tmax_axis_a_1ms\tmax_axis_a_4ms\tmax_deviation_um\n")
        for name, t, a1, a4, dev in rows:
            f.write(f"{name}\t{t:.3f}\t{a1:.2f}\t{a4:.2f}\t{dev * 1000:.1f}\n")


def main():
    paths_dir, samples_dir, bench_out, names = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4:]
    ours = ours_table(bench_out)
    rows = []
    print("| path | blocks | limit s | planner s | planner / limit | planner max axis a / limit | planner off path mm | LinuxCNC 2.9 s | LinuxCNC / limit | LinuxCNC max axis a / limit (1 ms; 4 ms) | LinuxCNC max deviation µm | LinuxCNC / planner |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for name in names:
        pts = polyline(f"{paths_dir}/{name}.nc")
        t, a1, a4, dev = linuxcnc_figures(f"{samples_dir}/{name}.samples", pts)
        rows.append((name, t, a1, a4, dev))
        o = ours.get(name)
        if o is None:
            print(f"| {name} | | | | | | | {t:.3f} | | {a1:.2f}; {a4:.2f} | {dev * 1000:.1f} | |", flush=True)
            continue
        print(
            f"| {name} | {o['blocks']} | {o['limit']:.3f} | {o['time']:.3f} | {o['time'] / o['limit']:.3f} | {o['acc']:.3f} | {o['off']:.0e} "
            f"| {t:.3f} | {t / o['limit']:.3f} | {a1:.2f}; {a4:.2f} | {dev * 1000:.1f} | {t / o['time']:.3f} |",
            flush=True,
        )
    if sorted(names) == sorted(ours) or ((os.environ.get("PATH_ACCEL") or os.environ.get("DIR")) and not ours):
        write_tsv(rows)


if __name__ == "__main__":
    main()
