#!/bin/sh
# Regenerates the independent reference of the planner (issue #32): the paths
# (paths/*.nc) and their limit times (reference.tsv), with TOPP-RA from PyPI in a venv under
# target/; then what 4 ms setpoints on the polyline allow (ticks*.tsv, plain Python) and what
# jerk-limited ones near it allow (jerk-ticks.tsv, scipy's linear programs). Minutes;
# the results are committed. Usage: scripts/planner-reference/run.sh
set -eu
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
VENV=$ROOT/target/planner-ref/venv
if [ ! -x "$VENV/bin/python" ]; then
    python3 -m venv "$VENV"
fi
"$VENV/bin/python" -c "import toppra, scipy, numpy" 2>/dev/null ||
    "$VENV/bin/pip" install -q toppra numpy scipy
cd "$ROOT/scripts/planner-reference"
"$VENV/bin/python" reference.py "$@"
"$VENV/bin/python" reference.py --path-accel 500 "$@"
"$VENV/bin/python" ticks.py "$@"
# The same under the path accelerations of machine-default.rek and machine-above.rek.
"$VENV/bin/python" ticks.py --path-accel 500 "$@"
"$VENV/bin/python" ticks.py --path-accel 5000 "$@"
# Jerk-limited setpoints within Lm/2 of the path, under machine-parabolic.rek (jerk-ticks.tsv).
"$VENV/bin/python" jerk_ticks.py "$@"
"$VENV/bin/python" jerk_ticks.py --dir arcs "$@"
