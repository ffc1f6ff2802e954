#!/bin/sh
# Side by side with LinuxCNC 2.9 (issue #32): runs the reference paths of
# scripts/planner-reference/paths on a headless simulated LinuxCNC (Debian's linuxcnc-uspace,
# trivkins, loopback feedback, 1 ms servo, HAL sampler on the servo thread) and prints its
# time, axis accelerations and path deviation beside the planner's (kernel bench, the
# configuration cncd builds). Not part of CI (minutes per path); the table goes into
# docs/planner.md. Usage: scripts/linuxcnc-compare/run.sh [names...]   (as root)
# PATH_ACCEL=500 scripts/linuxcnc-compare/run.sh: LinuxCNC's nearest counterpart of a
# constants file with R52 = R236 = R237 = 500 mm/s² (the defaults): its trajectory
# acceleration ([TRAJ] MAX_LINEAR_ACCELERATION, which alone left every time unchanged to the
# millisecond) and every axis's MAX_ACCELERATION at 500; writes linuxcnc-a500.tsv, without
# the bench. (Per axis 500 lets a diagonal accelerate at up to 707 mm/s² along the path.)
# ARCS=1 scripts/linuxcnc-compare/run.sh: the arc-fitted programs (planner-reference/arcs,
# G2/G3) instead, without the bench; the table goes into that directory. DIR=fast: the programs
# of planner-reference/fast (fast.py) likewise (ARCS=1 is DIR=arcs).
set -eu
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
HERE=$ROOT/scripts/linuxcnc-compare
PATHS=$ROOT/scripts/planner-reference/paths
if [ -n "${ARCS:-}" ]; then DIR=arcs; fi
if [ -n "${DIR:-}" ]; then PATHS=$ROOT/scripts/planner-reference/$DIR; fi
export DIR
WORK=$ROOT/target/linuxcnc-compare
NAMES=${*:-$(cd "$PATHS" && ls *.nc | sed 's/\.nc$//' | tr '\n' ' ')}

if ! command -v linuxcnc >/dev/null; then
    apt-get update
    apt-get install -y linuxcnc-uspace
fi
VENV=$WORK/venv
if [ ! -x "$VENV/bin/python" ]; then
    python3 -m venv "$VENV"
    "$VENV/bin/pip" install -q numpy
fi

rm -rf "$WORK/config" "$WORK/programs" "$WORK/out"
mkdir -p "$WORK/config" "$WORK/programs" "$WORK/out"
cp "$HERE/config/sim.hal" "$HERE/config/sim.tbl" "$WORK/config/"
: > "$WORK/config/sim.var"
sed "s|@DISPLAY@|$HERE/driver.py $WORK/programs $WORK/out $NAMES|" \
    "$HERE/config/sim.ini.in" > "$WORK/config/sim.ini"
if [ -n "${PATH_ACCEL:-}" ]; then
    sed -i -e "s#^\(DEFAULT\|MAX\)_LINEAR_ACCELERATION = .*#\1_LINEAR_ACCELERATION = $PATH_ACCEL#" \
        -e "s#^MAX_ACCELERATION = .*#MAX_ACCELERATION = $PATH_ACCEL#" "$WORK/config/sim.ini"
fi

# The same paths as LinuxCNC programs: G64 P0.008 (the planner's Lm), no N words.
for n in $NAMES; do
    {
        echo "G21 G90 G91.1 G17 G94 G64 P0.008"
        sed 's/^G23 //' "$PATHS/$n.nc"
        echo "M2"
    } > "$WORK/programs/$n.ngc"
done

# rtapi_app as root needs an unprivileged user, and its master socket (RTAPI_FIFO_PATH, a
# file) in a world-writable directory that user can reach.
RTAPI_UID=$(id -u nobody)
RTAPI_FIFO_PATH=/tmp/planner-compare-rtapi-$$
export RTAPI_UID RTAPI_FIFO_PATH
rm -f /tmp/linuxcnc.lock
echo "running LinuxCNC on: $NAMES"
# (on a pseudo terminal the launcher writes its messages to our log, not to temporary files)
(cd "$WORK/config" && script -qec "linuxcnc sim.ini" /dev/null < /dev/null) > "$WORK/linuxcnc.log" 2>&1 || {
    echo "linuxcnc failed, see $WORK/linuxcnc.log" >&2
    tail -20 "$WORK/linuxcnc.log" >&2
    exit 1
}
cat "$WORK/out/driver.log"

if [ -n "${PATH_ACCEL:-}${DIR:-}" ]; then
    : > "$WORK/ours.md"
else
    echo "running the planner bench (reference table)"
    (cd "$ROOT" && cargo bench -q -p kernel --bench plan -- reference) > "$WORK/ours.md"
fi
"$VENV/bin/python" "$HERE/analyze.py" "$PATHS" "$WORK/out" "$WORK/ours.md" $NAMES | tee "$WORK/table.md"
