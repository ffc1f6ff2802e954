#!/bin/sh
# Regenerates the jerk-limited reference (issue #49): Ruckig's time-optimal moves under the
# limits of parabolic-set.rek and parabolic-default.rek (ruckig-*.tsv, committed), with
# Ruckig from PyPI in a venv under target/. Seconds. Usage: scripts/jerk-reference/run.sh
set -eu
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
VENV=$ROOT/target/jerk-ref/venv
if [ ! -x "$VENV/bin/python" ]; then
    python3 -m venv "$VENV"
fi
"$VENV/bin/python" -c "import ruckig" 2>/dev/null || "$VENV/bin/pip" install -q ruckig
cd "$ROOT/scripts/jerk-reference"
"$VENV/bin/python" ruckig_moves.py
