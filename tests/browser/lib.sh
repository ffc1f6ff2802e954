# Shared by run.sh (the suite) and bench.sh: installs Chromium, chromedriver and Selenium when
# missing, builds cncd and starts it on the simulated machine with a temporary configuration.
# Sourced from the repository root; sets TARGET_DIR, VENV, WORK, TOKEN, API_PORT, HMI_PORT,
# ADMIN_TOKEN, CNCD_PID and removes WORK and stops cncd on exit.

install_browser() {
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
}

free_port() {
  python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'
}

# start_cncd PROFILE: builds cncd (dev or release) and starts it; waits for the HMI port.
start_cncd() {
  local profile=$1 dir=debug
  echo "building cncd ($profile)"
  if [ "$profile" = release ]; then
    cargo build --quiet --release -p daemon --bin cncd
    dir=release
  elif [ "${CNC_PREBUILT_BINS:-}" != 1 ]; then
    cargo build --quiet -p daemon --bin cncd
  fi
  WORK=$(mktemp -d -t cnc-browser-XXXXXX)
  CNCD_PID=""
  trap stop_cncd EXIT
  API_PORT=$(free_port)
  HMI_PORT=$(free_port)
  TOKEN="hmi-operator-$RANDOM$RANDOM"
  # An admin token too: the I/O tests force outputs and set simulated inputs.
  ADMIN_TOKEN="hmi-admin-$RANDOM$RANDOM"
  local hash admin_hash
  hash=$(python3 -c 'import hashlib,sys; print(hashlib.sha256(sys.argv[1].encode()).hexdigest())' "$TOKEN")
  admin_hash=$(python3 -c 'import hashlib,sys; print(hashlib.sha256(sys.argv[1].encode()).hexdigest())' "$ADMIN_TOKEN")
  # A 5 mm following window on the simulated drives: a rapid move faults (the alarm test).
  cat > "$WORK/cncd.toml" <<TOML
[api]
listen = "127.0.0.1:$API_PORT"
unix_socket = ""

[[api.tokens]]
name = "browser-operator"
role = "operator"
sha256 = "$hash"

[[api.tokens]]
name = "browser-admin"
role = "admin"
sha256 = "$admin_hash"

[hmi]
listen = "127.0.0.1:$HMI_PORT"

[sim]
following_window_mm = 5

[probe]
search_feed_mm_min = 1200

[storage]
dir = "$WORK/data"
TOML
  "$TARGET_DIR/$dir/cncd" --config "$WORK/cncd.toml" --log stderr > "$WORK/cncd.log" 2>&1 &
  CNCD_PID=$!
  for _ in $(seq 1 600); do
    if python3 -c "import socket; socket.create_connection(('127.0.0.1',$HMI_PORT),1)" 2>/dev/null; then
      return 0
    fi
    if ! kill -0 "$CNCD_PID" 2>/dev/null; then
      cat "$WORK/cncd.log"
      return 1
    fi
    sleep 0.1
  done
  echo "cncd did not open the HMI port"
  return 1
}

stop_cncd() {
  if [ -n "${CNCD_PID:-}" ] && kill -0 "$CNCD_PID" 2>/dev/null; then
    kill -TERM "$CNCD_PID" 2>/dev/null || true
    wait "$CNCD_PID" 2>/dev/null || true
  fi
  [ -n "${WORK:-}" ] && rm -rf "$WORK"
}
