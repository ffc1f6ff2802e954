#!/usr/bin/env bash
# Runs the vcan suite (tests/tests/vcan_*.rs): the CANopen master, the daemon and the drive
# simulators on a real Linux CAN stack.
#
# - Installs what it needs when missing (Debian packages, virtme-ng).
# - Builds the test binaries and the cncd, cncctl, sim-can binaries on the host.
# - Runs them directly when this kernel can create vcan0; otherwise boots a small VM with
#   Debian's kernel (virtme-ng, software emulation) and runs them there.
# - Prints the cargo test result lines; exits non-zero if a test failed or did not run.
set -euo pipefail
cd "$(dirname "$0")/../.."
ROOT=$PWD
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$ROOT/target}"

log() { echo "vcan: $*"; }

# --- what we need -------------------------------------------------------------------------
install_missing() {
    local pkgs=()
    command -v ip >/dev/null || pkgs+=(iproute2)
    command -v python3 >/dev/null || pkgs+=(python3)
    if [ "${#pkgs[@]}" -gt 0 ]; then
        log "installing ${pkgs[*]}"
        apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${pkgs[@]}"
    fi
}

install_vm_tools() {
    local pkgs=()
    command -v qemu-system-x86_64 >/dev/null || pkgs+=(qemu-system-x86)
    compgen -G "/boot/vmlinuz-*" >/dev/null || pkgs+=(linux-image-amd64)
    dpkg -s busybox-static >/dev/null 2>&1 || pkgs+=(busybox-static)
    command -v candump >/dev/null || pkgs+=(can-utils)
    command -v pip >/dev/null || command -v pip3 >/dev/null || pkgs+=(python3-pip)
    if [ "${#pkgs[@]}" -gt 0 ]; then
        log "installing ${pkgs[*]}"
        apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${pkgs[@]}"
    fi
    if ! command -v vng >/dev/null; then
        log "installing virtme-ng"
        pip install -q virtme-ng 2>/dev/null || pip install -q --break-system-packages virtme-ng
    fi
}

install_missing

# --- build on the host ---------------------------------------------------------------------
log "building simulator, daemon and test binaries"
# scripts/test-all.sh built them (CNC_PREBUILT_BINS=1) with the workspace's test features.
[ "${CNC_PREBUILT_BINS:-}" = 1 ] || cargo build --locked -q -p sim -p daemon --bins
mapfile -t TESTS < <(
    cargo test --locked -q --workspace --no-run --message-format=json |
        python3 -c '
import json, sys, os
for line in sys.stdin:
    try:
        m = json.loads(line)
    except ValueError:
        continue
    if m.get("reason") == "compiler-artifact" and m.get("executable") \
            and m["target"]["kind"] == ["test"] and m["target"]["name"].startswith("vcan_"):
        print(m["executable"])
'
)
if [ "${#TESTS[@]}" -eq 0 ]; then
    log "no vcan test binaries were built"
    exit 1
fi
log "test binaries: ${TESTS[*]}"

WORK=$(mktemp -d /tmp/cnc-vcan.XXXXXX)
OUT="$WORK/output.txt"
: >"$OUT"

# The guest (or this host) runs this script: create vcan0, run each binary, record exit codes.
cat >"$WORK/suite.sh" <<EOF
#!/bin/sh
export CNC_REQUIRE_VCAN=1 CNC_PREBUILT_BINS=1 RUST_BACKTRACE=1 TMPDIR="$WORK"
ip link show vcan0 >/dev/null 2>&1 || {
    modprobe vcan 2>/dev/null
    ip link add dev vcan0 type vcan && ip link set up vcan0
}
ip link show vcan0 >/dev/null 2>&1 || { echo "VCAN-SUITE no vcan0"; exit 1; }
rc=0
for t in ${TESTS[*]}; do
    echo "VCAN-SUITE running \$t"
    "\$t" --test-threads=1 --nocapture || rc=1
done
echo "VCAN-SUITE-EXIT \$rc"
EOF
chmod +x "$WORK/suite.sh"

T0=$(date +%s)
if ip link show vcan0 >/dev/null 2>&1 ||
    { modprobe vcan 2>/dev/null; ip link add dev vcan0 type vcan 2>/dev/null && ip link set up vcan0; }; then
    log "this kernel has vcan: running directly"
    "$WORK/suite.sh" 2>&1 | tee "$OUT" || true
else
    log "this kernel has no vcan: running in a VM (Debian kernel, software emulation)"
    install_vm_tools
    KERNEL=$(ls /boot/vmlinuz-* | sort -V | tail -n 1)
    # The guest sees the host filesystem read-only, except the work dir (test output, temp
    # files) and the target dir (nothing is built there, but tests may write logs).
    vng --run "$KERNEL" --disable-kvm --cpus 2 --memory 2G \
        --rwdir "$WORK" --rwdir "$CARGO_TARGET_DIR" --cwd "$ROOT" \
        --exec "$WORK/suite.sh > $OUT 2>&1" >"$WORK/vng.log" 2>&1 </dev/null ||
        { log "vng exited with $?; its last lines:"; tail -n 20 "$WORK/vng.log"; }
    # The VM's console goes to its own log: vng/qemu reopen their standard output, which
    # truncated the caller's log file when it was a regular file.
    cat "$OUT"
fi
T1=$(date +%s)

echo
log "results ($((T1 - T0)) s):"
grep -E "^test result:" "$OUT" || true
results=$(grep -cE "^test result:" "$OUT" || true)
if ! grep -q "VCAN-SUITE-EXIT 0" "$OUT"; then
    log "FAILED (a test failed, or the suite did not run to its end)"
    exit 1
fi
if [ "$results" -ne "${#TESTS[@]}" ]; then
    log "FAILED: ${#TESTS[@]} test binaries, $results result lines"
    exit 1
fi
if grep -q "SKIPPED" "$OUT"; then
    log "FAILED: tests were skipped although vcan0 exists"
    exit 1
fi
log "all vcan tests passed"
rm -rf "$WORK"
