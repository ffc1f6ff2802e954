#!/usr/bin/env bash
# Runs every test of the project on a fresh machine: installs what the suites need, then the
# Rust workspace tests, then the suites that need more than cargo (vcan in a VM, foreign
# clients; with CNC_SYSTEMD_VM=1 also the Debian package in a systemd VM). Exits non-zero if
# anything failed.
set -euo pipefail
cd "$(dirname "$0")/.."

echo "== cargo test --workspace"
cargo test --workspace --locked

if [ -x tests/vcan/run.sh ]; then
  echo "== vcan suite (CANopen on a real Linux CAN stack)"
  tests/vcan/run.sh
fi

# Opt-in until its time on a fresh CI machine (release build, root filesystem, emulated boot)
# has been measured on a clean clone.
if [ "${CNC_SYSTEMD_VM:-0}" = 1 ] && [ -x tests/systemd-vm/run.sh ]; then
  echo "== systemd VM suite (the Debian package under a real systemd)"
  tests/systemd-vm/run.sh
fi

if [ -x tests/python/run.sh ]; then
  echo "== Python gRPC client"
  tests/python/run.sh
fi
echo "== all test suites passed"
