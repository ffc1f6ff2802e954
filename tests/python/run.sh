#!/usr/bin/env bash
# Python gRPC client acceptance test (issue #8): generates Python stubs from proto/ with
# grpcio-tools, starts a cargo-built cncd with a temporary configuration (temporary data
# directory, a free loopback port, an operator token) and runs tests/python/client_test.py,
# which runs a program to its end, edits an offset and reads it back, and reads AKRR cells.
# Exits non-zero on failure; the last line is "N passed, M failed".
set -euo pipefail
cd "$(dirname "$0")/../.."

PY=${PYTHON:-python3}
if ! "$PY" -c 'import grpc, grpc_tools' 2>/dev/null; then
  echo "installing grpcio grpcio-tools"
  "$PY" -m pip install --quiet grpcio grpcio-tools
fi

WORK=$(mktemp -d -t cnc-python-XXXXXX)
CNCD_PID=""
cleanup() {
  if [ -n "$CNCD_PID" ] && kill -0 "$CNCD_PID" 2>/dev/null; then
    kill -TERM "$CNCD_PID" 2>/dev/null || true
    wait "$CNCD_PID" 2>/dev/null || true
  fi
  rm -rf "$WORK"
}
trap cleanup EXIT

mkdir -p "$WORK/stubs"
"$PY" -m grpc_tools.protoc -I proto/proto --python_out="$WORK/stubs" \
  --grpc_python_out="$WORK/stubs" proto/proto/cnc/v1/cnc.proto

echo "building cncd"
# scripts/test-all.sh built it already (CNC_PREBUILT_BINS=1): no second debug build.
[ "${CNC_PREBUILT_BINS:-}" = 1 ] || cargo build --quiet -p daemon --bin cncd
TARGET_DIR=$(cargo metadata --format-version 1 --no-deps |
  "$PY" -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')
CNCD="$TARGET_DIR/debug/cncd"

PORT=$("$PY" -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
TOKEN="py-operator-$RANDOM$RANDOM"
HASH=$("$PY" -c 'import hashlib,sys; print(hashlib.sha256(sys.argv[1].encode()).hexdigest())' "$TOKEN")
cat > "$WORK/cncd.toml" <<TOML
[api]
listen = "127.0.0.1:$PORT"
local_role = "observer"

[hmi]
listen = "127.0.0.1:0"

[[api.tokens]]
name = "python-client"
role = "operator"
sha256 = "$HASH"

[storage]
dir = "$WORK/data"
TOML

"$CNCD" --config "$WORK/cncd.toml" --log stderr > "$WORK/cncd.log" 2>&1 &
CNCD_PID=$!

set +e
CNC_ADDR="127.0.0.1:$PORT" CNC_TOKEN="$TOKEN" PYTHONPATH="$WORK/stubs" \
  "$PY" tests/python/client_test.py
RC=$?
set -e
if [ $RC -ne 0 ]; then
  echo "--- cncd log (last 30 lines)"
  tail -n 30 "$WORK/cncd.log" || true
fi
exit $RC
