#!/usr/bin/env python3
"""LinuxCNC's canonical calls (as `rs274` prints them) → moves in machine coordinates, mm.

Standard library only. Subcommands:

  tables DATA OUT     TAB0.KOR and work_offsets.txt of DATA (mm) → OUT/tool.tbl (the same
                      tools in LinuxCNC's format), OUT/tool_r0.tbl (the same with diameter 0)
                      and OUT/rs274.var (the work offsets as parameters 5221…).
  convert FULL PLAIN  one program's canonical calls, FULL printed with every digit and PLAIN
                      as rs274 prints them (%.4f), → JSON lines on stdout, one per move.

Why the units look odd: the standalone interpreter of LinuxCNC 2.9 (saicanon.cc) reports its
"user" length unit as 0.03937007874016 per mm (GET_EXTERNAL_LENGTH_UNITS), so the tool table
and the parameter file are read in inches whatever the program's G20/G21. The tables are
written here in that unit with the interpreter's own factor, so they read back as the mm
values of TAB0.KOR and work_offsets.txt.

What the calls mean (LinuxCNC emccanon.cc, rotate_and_offset_pos): positions of
STRAIGHT_TRAVERSE, STRAIGHT_FEED and ARC_FEED are program coordinates in the units of the
last USE_LENGTH_UNITS; the machine position adds the G92 offset, the G5x offset and the tool
length offset (SET_G92_OFFSET, SET_G5X_OFFSET, USE_TOOL_LENGTH_OFFSET, each given in the
units in force when it was called). ARC_FEED(first_end, second_end, first_centre,
second_centre, rotation, axis_end, a, b, c) names the plane's axes in the order X,Y (G17),
Z,X (G18), Y,Z (G19); rotation > 0 is counterclockwise (G3), |rotation| - 1 full turns more.
SET_FEED_RATE is in units per minute (per revolution after SET_FEED_MODE(_, 1)); inverse
time (G93) arrives already converted by the interpreter to units per minute of each move.
"""

import json
import re
import sys

# LinuxCNC 2.9 saicanon.cc GET_EXTERNAL_LENGTH_UNITS(): tables are read as value / this (mm).
EXT_PER_MM = 0.03937007874016
INCH = 25.4

# G54 … G59.3 and the first parameter (X) of each in LinuxCNC's parameter file.
SYSTEMS = ["G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3"]
AXES = "XYZ"

LINE = re.compile(r"^\s*\d+ (N\.\.\.\.\. |N(\d*)\s*)([A-Z_0-9.]+)\((.*)\)\s*$")


def read_kor(path):
    """{tool: (radius, z length)} of a TAB0.KOR file (only R and Z are used here)."""
    tools = {}
    in_table = False
    with open(path, encoding="utf-8") as f:
        for raw in f:
            line = raw.split(";")[0].strip()
            if not in_table:
                in_table = line.startswith("$KOR")
                continue
            if not line:
                continue
            num, rest = line.split(":", 1)
            vals = dict(kv.split("=") for kv in rest.split())
            tools[int(num)] = (float(vals.get("R", 0)), float(vals.get("Z", 0)))
    return tools


def read_work_offsets(path):
    """{system: (x, y, z)} of work_offsets.txt (`G54 X10 Y20 Z-5`, `#` comments)."""
    out = {}
    with open(path, encoding="utf-8") as f:
        for raw in f:
            line = raw.split("#")[0].split()
            if not line:
                continue
            vals = {w[0].upper(): float(w[1:]) for w in line[1:]}
            out[line[0].upper()] = tuple(vals.get(a, 0.0) for a in AXES)
    return out


def ext(mm):
    return repr(mm * EXT_PER_MM)


def tables(data, out):
    tools = read_kor(f"{data}/TAB0.KOR")
    for name, zero_d in (("tool.tbl", False), ("tool_r0.tbl", True)):
        with open(f"{out}/{name}", "w", encoding="utf-8") as f:
            for t, (r, z) in sorted(tools.items()):
                d = 0.0 if zero_d else 2 * r
                f.write(f"T{t} P{t} Z{ext(z)} D{ext(d)} ;TAB0.KOR entry {t:02}\n")
    offs = read_work_offsets(f"{data}/work_offsets.txt")
    with open(f"{out}/rs274.var", "w", encoding="utf-8") as f:
        f.write("5220\t1\n")  # G54 in force
        for k, name in enumerate(SYSTEMS):
            for a, v in zip(range(3), offs.get(name, (0.0, 0.0, 0.0))):
                f.write(f"{5221 + 20 * k + a}\t{ext(v)}\n")


def parse(path):
    """[(name, args text, N or None)] of a canonical listing."""
    calls = []
    with open(path, encoding="utf-8", errors="replace") as f:
        for raw in f:
            m = LINE.match(raw.rstrip("\n"))
            if m:
                n = int(m.group(2)) if m.group(2) else None
                calls.append((m.group(3), m.group(4), n))
    return calls


def numbers(args):
    return [float(x) for x in re.split(r"[,\s]+", args.strip()) if x]


NUMERIC = {
    "STRAIGHT_TRAVERSE", "STRAIGHT_FEED", "STRAIGHT_PROBE", "ARC_FEED", "DWELL", "SET_FEED_RATE",
    "SET_FEED_MODE", "SET_G5X_OFFSET", "SET_G92_OFFSET", "USE_TOOL_LENGTH_OFFSET",
    "SET_XY_ROTATION",
}
UNSUPPORTED = {"RIGID_TAP", "NURBS_G5_FEED", "NURBS_G6_FEED",
               "SPINDLE_RETRACT_TRAVERSE"}


def cross_check(full, plain):
    """The digits shim changed nothing but the digits: same calls, same values to %.4f."""
    if [c[0] for c in full] != [c[0] for c in plain]:
        sys.exit("full-precision and plain runs made different calls")
    for (name, a, _), (_, b, _) in zip(full, plain):
        if name not in NUMERIC:
            continue
        for x, y in zip(numbers(a), numbers(b)):
            if abs(x - y) > 0.5e-4 + 1e-9 * abs(x):
                sys.exit(f"{name}: {x} printed as {y}")


def num(v):
    v = round(v, 10)
    return 0.0 if v == 0 else v


def convert(full_path, plain_path):
    full = parse(full_path)
    cross_check(full, parse(plain_path))
    unit = 1.0
    g5x = [0.0] * 3
    g92 = [0.0] * 3
    tool = [0.0] * 3
    plane = "XY"
    per_rev = False
    feed = 0.0
    out = []

    def machine(p):
        return [p[k] * unit + g92[k] + g5x[k] + tool[k] for k in range(3)]

    def xyz(v):
        return {a: num(v[k]) for k, a in enumerate(AXES)}

    def feed_field(move):
        move["feed_mm_rev" if per_rev else "feed_mm_min"] = num(feed)

    for name, args, n in full:
        if name in UNSUPPORTED:
            sys.exit(f"{name}: not a motion of the subset")
        v = numbers(args) if name in NUMERIC else []
        move = None
        if name == "USE_LENGTH_UNITS":
            unit = INCH if "INCHES" in args else 1.0
        elif name == "SET_G5X_OFFSET":
            g5x = [x * unit for x in v[1:4]]
            if any(v[4:7]):
                sys.exit("SET_G5X_OFFSET: rotary axis offset")
        elif name == "SET_G92_OFFSET":
            g92 = [x * unit for x in v[0:3]]
            if any(v[3:6]):
                sys.exit("SET_G92_OFFSET: rotary axis offset")
        elif name == "USE_TOOL_LENGTH_OFFSET":
            tool = [x * unit for x in v[0:3]]
            if any(v[3:]):
                sys.exit("USE_TOOL_LENGTH_OFFSET: rotary or UVW offset")
        elif name == "SET_XY_ROTATION":
            if v[0] != 0:
                sys.exit("SET_XY_ROTATION: rotated coordinate system")
        elif name == "SELECT_PLANE":
            plane = args.rsplit("_", 1)[-1]
        elif name == "SET_FEED_MODE":
            per_rev = v[1] == 1
        elif name == "SET_FEED_RATE":
            feed = v[0] * unit
        elif name in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED", "STRAIGHT_PROBE"):
            if any(v[3:6]):
                sys.exit(f"{name}: rotary axis moves")
            move = {"kind": "rapid" if name == "STRAIGHT_TRAVERSE" else "feed",
                    "end": xyz(machine(v[0:3]))}
            # A probing move is a feed move to its target (rs274 has no probe: it reports
            # the target, untripped, as cncd's pass without a machine does).
            if name != "STRAIGHT_TRAVERSE":
                feed_field(move)
        elif name == "ARC_FEED":
            fe, se, fc, sc, rot, ae = v[0:6]
            if any(v[6:9]):
                sys.exit("ARC_FEED: rotary axis moves")
            if abs(rot) != 1:
                sys.exit(f"ARC_FEED: {abs(rot) - 1:g} full turns more")
            # Plane axes (first, second) and the helix axis, as indices into X Y Z.
            first, second, third, g = {"XY": (0, 1, 2, "G17"), "XZ": (2, 0, 1, "G18"),
                                       "YZ": (1, 2, 0, "G19")}[plane]
            end = [0.0] * 3
            end[first], end[second], end[third] = fe, se, ae
            centre = [0.0] * 3
            centre[first], centre[second] = fc, sc
            end_m, centre_m = machine(end), machine(centre)
            move = {"kind": "arc", "end": xyz(end_m),
                    "centre": {AXES[k]: num(centre_m[k]) for k in sorted((first, second))},
                    "plane": g, "dir": "ccw" if rot > 0 else "cw"}
            feed_field(move)
        elif name == "DWELL":
            move = {"kind": "dwell", "seconds": num(v[0])}
        if move is not None:
            if n is not None:
                move["n"] = n
            out.append(move)
    for m in out:
        print(json.dumps(m, separators=(",", ":")))


def main(argv):
    if len(argv) == 4 and argv[1] == "tables":
        tables(argv[2], argv[3])
    elif len(argv) == 4 and argv[1] == "convert":
        convert(argv[2], argv[3])
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main(sys.argv)
