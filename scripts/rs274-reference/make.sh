#!/bin/sh
# The independent reference of the ISO dialect (kernel/tests/iso_rs274.rs): LinuxCNC 2.9's own
# standalone interpreter, rs274 of Debian's linuxcnc-uspace, runs every example program that
# LinuxCNC ships and the CAM-style programs of kernel/tests/data/rs274/, and its canonical
# calls become the expected moves. Regenerates, in kernel/tests/data/rs274/:
#   <example>.ngc   copies of /usr/share/linuxcnc/ncfiles/*.ngc (listed in examples.txt)
#   <name>.jsonl    one move per line, machine coordinates, mm (canon_to_moves.py)
#   refusals.txt    the programs outside the subset and where (scan_subset.py)
#   excluded.txt    examples inside the subset that rs274 itself stops on (not compared)
#   notes.txt       programs whose reference needed a word of explanation
#   tool.tbl, rs274.var  TAB0.KOR and work_offsets.txt as rs274 reads them
# The programs of our own (every other .ngc there) are kept; each must run in rs274.
# Not part of CI: the outputs are committed. Usage: scripts/rs274-reference/make.sh (as root
# when linuxcnc-uspace is not installed yet; needs cc for the digits shim).
set -eu
HERE=$(cd "$(dirname "$0")" && pwd)
ROOT=$(cd "$HERE/../.." && pwd)
DATA=$ROOT/kernel/tests/data/rs274
NC=${RS274_NCFILES:-/usr/share/linuxcnc/ncfiles}
WORK=$ROOT/target/rs274-reference
PY=python3

if ! command -v rs274 >/dev/null; then
    apt-get update
    apt-get install -y linuxcnc-uspace
fi
rm -rf "$WORK"
mkdir -p "$WORK/canon"
cc -shared -fPIC -O2 -Wall -o "$WORK/fullprec.so" "$HERE/fullprec.c"

$PY "$HERE/canon_to_moves.py" tables "$DATA" "$WORK"
cp "$WORK/tool.tbl" "$WORK/rs274.var" "$DATA/"

# Start from scratch: the previous copies of the examples and every generated file go.
if [ -f "$DATA/examples.txt" ]; then
    while read -r n; do rm -f "$DATA/$n.ngc"; done < "$DATA/examples.txt"
fi
rm -f "$DATA"/*.jsonl "$DATA/refusals.txt" "$DATA/excluded.txt" "$DATA/notes.txt" \
    "$DATA/examples.txt"
OWN=$(cd "$DATA" && ls *.ngc 2>/dev/null | sed 's/\.ngc$//' | tr '\n' ' ')
for f in "$NC"/*.ngc; do
    n=$(basename "$f" .ngc)
    case " $OWN " in *" $n "*) echo "$n: an example has the name of one of our programs" >&2; exit 1 ;; esac
    cp "$f" "$DATA/$n.ngc"
    echo "$n" >> "$DATA/examples.txt"
done
: > "$DATA/refusals.txt"
: > "$DATA/excluded.txt"
: > "$DATA/notes.txt"

# rs274 TABLE PROGRAM OUT [shim]: the canonical calls in OUT, its complaint (if any) in OUT.err.
# It rewrites its parameter file at the end (a G10 would persist): each run gets a fresh copy.
run() {
    cp "$WORK/rs274.var" "$WORK/run.var"
    set +e
    (cd "$WORK" && env ${4:+LD_PRELOAD=$4} timeout 120 \
        rs274 -g -t "$WORK/$1" -v "$WORK/run.var" "$2" > "$3" 2> "$3.raw" < /dev/null)
    rc=$?
    set -e
    grep -v '^executing$' "$3.raw" | sed 's/executing$//' > "$3.err" || true
    if [ $rc -ne 0 ] && [ ! -s "$3.err" ]; then echo "exit status $rc" > "$3.err"; fi
}

is_example() { grep -qx "$1" "$DATA/examples.txt"; }

# The motion calls of a listing, without the output and N columns.
motion() { sed -n 's/^ *[0-9]* N[^ ]* *\(STRAIGHT_\|ARC_FEED\)/\1/p' "$1"; }

supported=0
refused=0
excluded=0
for f in "$DATA"/*.ngc; do
    n=$(basename "$f" .ngc)
    r=$($PY "$HERE/scan_subset.py" "$f")
    if [ -n "$r" ]; then
        echo "$r" >> "$DATA/refusals.txt"
        refused=$((refused + 1))
        continue
    fi
    c=$WORK/canon/$n
    # The dry run is the programmed path: LinuxCNC compensates the radius inside its
    # interpreter, so the reference runs with every diameter 0 (compensation has no effect
    # there); a second run with the real diameters checks that LinuxCNC takes the program.
    run tool_r0.tbl "$f" "$c.plain"
    run tool_r0.tbl "$f" "$c.full" "$WORK/fullprec.so"
    run tool.tbl "$f" "$c.real" "$WORK/fullprec.so"
    if [ -s "$c.full.err" ]; then
        msg=$(tr '\n' ' ' < "$c.full.err" | sed 's/ *$//')
        if ! is_example "$n"; then
            echo "$n: rs274 stops on our program: $msg" >&2
            exit 1
        fi
        echo "$n $msg" >> "$DATA/excluded.txt"
        rm -f "$f"
        sed -i "/^$n\$/d" "$DATA/examples.txt"
        excluded=$((excluded + 1))
        continue
    fi
    $PY "$HERE/canon_to_moves.py" convert "$c.full" "$c.plain" > "$DATA/$n.jsonl"
    motion "$c.real" > "$c.real.motion"
    if ! motion "$c.full" | cmp -s - "$WORK/canon/$n.real.motion"; then
        if [ -s "$c.real.err" ]; then
            msg=$(tr '\n' ' ' < "$c.real.err" | sed 's/ *$//')
            if ! is_example "$n"; then
                echo "$n: rs274 stops on our program with the real radii: $msg" >&2
                exit 1
            fi
            echo "$n radius compensation: reference at radius 0; with the radii of TAB0.KOR LinuxCNC stops: $msg" >> "$DATA/notes.txt"
        else
            echo "$n radius compensation: reference at radius 0 (LinuxCNC compensates in its interpreter; the dry run is the programmed path)" >> "$DATA/notes.txt"
        fi
    fi
    supported=$((supported + 1))
done
echo "supported $supported, refused $refused, excluded $excluded (see $DATA/excluded.txt)"
