#!/usr/bin/env bash
# Browser HMI benchmark (not a test; figures in docs/hmi.md): a release cncd on the simulated
# machine and headless Chromium; tests/browser/bench.py measures page load, DRO update rate and
# latency (against a native gRPC client's view of the same snapshots), the preview of a
# 1 M-block program, and browser memory after a status run of MINUTES (default 10).
#   tests/browser/bench.sh [MINUTES]        (CNC_BENCH_PARTS=memory for the memory run alone)
set -euo pipefail
cd "$(dirname "$0")/../.."
. tests/browser/lib.sh

install_browser
if ! "$VENV/bin/python" -c 'import grpc, grpc_tools' 2>/dev/null; then
  "$VENV/bin/pip" install --quiet grpcio grpcio-tools
fi
start_cncd release
mkdir -p "$WORK/stubs"
"$VENV/bin/python" -m grpc_tools.protoc -I proto/proto --python_out="$WORK/stubs" \
  --grpc_python_out="$WORK/stubs" proto/proto/cnc/v1/cnc.proto
CNC_HMI_URL="http://127.0.0.1:$HMI_PORT/" CNC_ADDR="127.0.0.1:$API_PORT" CNC_TOKEN="$TOKEN" \
  CNC_MINUTES="${1:-10}" PYTHONPATH="$WORK/stubs" "$VENV/bin/python" tests/browser/bench.py
