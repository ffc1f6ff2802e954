#!/bin/sh
# Runs the cargo-fuzz targets of fuzz/ (the kernel's parsers and the daemon's doors, issues #3
# and #50) for a number of runs each and prints a table: target, runs, seconds, executions per
# second, result. A crash, a hang (-timeout) or a memory blow-up (-rss_limit_mb) fails the
# target; libFuzzer leaves the input in fuzz/artifacts/<target>/.
# Usage: scripts/fuzz.sh [RUNS|SECONDSs] [TARGET...]   (RUNS default 10000000; the compensator
# gets a fifth of it, as each of its inputs is a whole contour; `600s` runs each target for 600
# seconds instead). Needs a nightly toolchain; installs cargo-fuzz when missing.
# Corpora are committed in fuzz/corpus/<target>/ and grow there; with the seeds of
# fuzz/seeds/<target>/ and kernel/tests/corpus/ they start each run.
# `scripts/fuzz.sh merge [TARGET...]` minimizes the corpora in place (libFuzzer's -merge=1:
# the fewest inputs with the same coverage), before they are committed.
# Built without a sanitizer (-s none; the code is safe Rust) and with debug assertions (-a),
# so overflow and the entries' own checks still fail a run.
set -eu
ROOT=$(cd "$(dirname "$0")/.." && pwd)
cd "$ROOT/fuzz"
RUNS=${1:-10000000}
[ $# -gt 0 ] && shift
TARGETS=${*:-program offsets constants comp mtconnect config code_pages grpc_web upload}
command -v cargo-fuzz >/dev/null || cargo install cargo-fuzz --locked
FUZZ="cargo +nightly fuzz"
if [ "$RUNS" = merge ]; then
    mkdir -p "$ROOT/target"
    for t in $TARGETS; do
        [ -d "corpus/$t" ] || continue
        rm -rf "corpus/$t.merged" && mkdir "corpus/$t.merged"
        $FUZZ run -O -a -s none "$t" "corpus/$t.merged" "corpus/$t" -- -merge=1 \
            >"$ROOT/target/fuzz-merge-$t.log" 2>&1
        rm -rf "corpus/$t" && mv "corpus/$t.merged" "corpus/$t"
        echo "$t: $(ls "corpus/$t" | wc -l) inputs"
    done
    exit 0
fi
# A time per target ("600s") or a number of runs.
case $RUNS in
*s) SECONDS_EACH=${RUNS%s} ;;
*) SECONDS_EACH= ;;
esac
LOGS="$ROOT/target/fuzz-logs"
mkdir -p "$LOGS"
for t in $TARGETS; do
    $FUZZ build -O -a -s none "$t" >"$LOGS/$t.build.log" 2>&1
done
printf '| target | runs | seconds | runs/s | result |\n|---|---|---|---|---|\n'
status=0
for t in $TARGETS; do
    if [ -n "$SECONDS_EACH" ]; then
        limit="-max_total_time=$SECONDS_EACH"
    else
        n=$RUNS
        [ "$t" = comp ] && n=$((RUNS / 5))
        limit="-runs=$n"
    fi
    mkdir -p "corpus/$t"
    dirs="corpus/$t"
    [ -d "seeds/$t" ] && dirs="$dirs seeds/$t"
    [ "$t" = program ] && dirs="$dirs $ROOT/kernel/tests/corpus"
    # An upload input is a sequence of calls, each storing through the library: 1 KiB holds
    # hundreds of them, and longer inputs only slow the runs down (about 2.5x at 4 KiB).
    len=
    [ "$t" = upload ] && len=-max_len=1024
    start=$(date +%s)
    if $FUZZ run -O -a -s none "$t" $dirs -- "$limit" $len -timeout=10 -rss_limit_mb=2048 \
        -print_final_stats=1 >"$LOGS/$t.log" 2>&1; then
        result=ok
    else
        result=FAILED
        status=1
    fi
    secs=$(($(date +%s) - start))
    done_runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$LOGS/$t.log" | tail -1)
    printf '| %s | %s | %s | %s | %s |\n' "$t" "${done_runs:-?}" "$secs" \
        "$(( ${done_runs:-0} / (secs > 0 ? secs : 1) ))" "$result"
done
exit $status
