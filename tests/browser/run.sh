#!/usr/bin/env bash
# Browser HMI suite (issue #30): real headless Chromium (Debian's chromium and chromium-driver,
# installed with apt when missing) driven by Selenium (pip, in a venv under target/) against
# a cargo-built cncd on the simulated machine, through its HMI origin. A temporary
# configuration: temporary data directory, free loopback ports, an operator token, a 5 mm
# following window on the simulated drives (a rapid move faults: the alarm test). Saves the
# Run and Preview screenshots to docs/images/hmi_run.png and hmi_preview.png.
# Exits non-zero on failure; the last line is "N passed, M failed".
set -euo pipefail
cd "$(dirname "$0")/../.."
ROOT=$PWD

if ! command -v chromium >/dev/null || ! command -v chromedriver >/dev/null; then
  echo "installing chromium chromium-driver"
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium chromium-driver >/dev/null
fi

TARGET_DIR=$(cargo metadata --format-version 1 --no-deps |
  python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')
VENV="$TARGET_DIR/browser-venv"
if ! "$VENV/bin/python" -c 'import selenium' 2>/dev/null; then
  echo "installing selenium in $VENV"
  python3 -m venv "$VENV"
  "$VENV/bin/pip" install --quiet selenium
fi

echo "building cncd"
cargo build --quiet -p daemon --bin cncd
CNCD="$TARGET_DIR/debug/cncd"

WORK=$(mktemp -d -t cnc-browser-XXXXXX)
CNCD_PID=""
cleanup() {
  if [ -n "$CNCD_PID" ] && kill -0 "$CNCD_PID" 2>/dev/null; then
    kill -TERM "$CNCD_PID" 2>/dev/null || true
    wait "$CNCD_PID" 2>/dev/null || true
  fi
  rm -rf "$WORK"
}
trap cleanup EXIT

free_port() {
  python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'
}
API_PORT=$(free_port)
HMI_PORT=$(free_port)
TOKEN="hmi-operator-$RANDOM$RANDOM"
HASH=$(python3 -c 'import hashlib,sys; print(hashlib.sha256(sys.argv[1].encode()).hexdigest())' "$TOKEN")
cat > "$WORK/cncd.toml" <<TOML
[api]
listen = "127.0.0.1:$API_PORT"
unix_socket = ""

[[api.tokens]]
name = "browser-operator"
role = "operator"
sha256 = "$HASH"

[hmi]
listen = "127.0.0.1:$HMI_PORT"

[sim]
following_window_mm = 5

[storage]
dir = "$WORK/data"
TOML

"$CNCD" --config "$WORK/cncd.toml" --log stderr > "$WORK/cncd.log" 2>&1 &
CNCD_PID=$!
for _ in $(seq 1 300); do
  if python3 -c "import socket,sys; socket.create_connection(('127.0.0.1',$HMI_PORT),1)" 2>/dev/null; then
    break
  fi
  kill -0 "$CNCD_PID" 2>/dev/null || { cat "$WORK/cncd.log"; exit 1; }
  sleep 0.1
done

mkdir -p docs/images "$TARGET_DIR/browser"
set +e
CNC_HMI_URL="http://127.0.0.1:$HMI_PORT/" CNC_TOKEN="$TOKEN" CNC_SHOTS="$ROOT/docs/images" \
  CNC_FAIL_SHOTS="$TARGET_DIR/browser" "$VENV/bin/python" tests/browser/hmi_test.py
RC=$?
set -e
if [ $RC -ne 0 ]; then
  echo "--- cncd log (last 30 lines); failure screenshots in $TARGET_DIR/browser"
  tail -n 30 "$WORK/cncd.log" || true
fi
exit $RC
