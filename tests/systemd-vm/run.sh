#!/usr/bin/env bash
# The systemd VM suite (issue #21): boots a small Debian VM with systemd as init, installs the
# cncd Debian package built from this checkout, and checks the deployment under a real
# service manager (tests/systemd-vm/guest.sh lists the checks).
#
# - Installs what it needs when missing (qemu-system-x86, mmdebstrap, e2fsprogs).
# - Builds the package (deploy/build-deb.sh, release build) and the drive simulator sim-can
#   (the vcan suite's dev build, reused).
# - Builds the VM's root filesystem once from Debian's packages (mmdebstrap: bookworm, systemd,
#   the Debian kernel linux-image-amd64 and its initramfs, rt-tests) in the background while
#   the release build runs, and caches it in target/systemd-vm/ under a hash of its recipe
#   (the variables below): a change of the recipe builds a new one, nothing else does.
# - Boots it with QEMU (software emulation; CNC_VM_KVM=1 uses KVM when /dev/kvm works), the
#   disk as a throw-away snapshot; the guest mounts this run's work directory over 9p, runs
#   guest.sh, writes its results there and powers off.
# - Prints `systemd-vm: N passed, M failed`; exits non-zero on any failure or if the guest did
#   not finish.
#
# Options (environment): CNC_VM_ONLY_IMAGE=1 builds the image and stops; CNC_VM_TIMEOUT_S
# (default 900) bounds the VM run; CNC_VM_KEEP=1 keeps the work directory.
set -euo pipefail
cd "$(dirname "$0")/../.."
ROOT=$PWD
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$ROOT/target}"
CACHE="$CARGO_TARGET_DIR/systemd-vm"
SUITE="$ROOT/tests/systemd-vm"
MIRROR="${CNC_VM_MIRROR:-http://deb.debian.org/debian}"
SUITE_NAME=bookworm

log() { echo "systemd-vm: $*"; }
T_START=$(date +%s)

# --- what we need on the host --------------------------------------------------------------
install_tools() {
    local pkgs=()
    command -v qemu-system-x86_64 >/dev/null || pkgs+=(qemu-system-x86)
    command -v mmdebstrap >/dev/null || pkgs+=(mmdebstrap)
    command -v mke2fs >/dev/null || pkgs+=(e2fsprogs)
    command -v dpkg-deb >/dev/null || pkgs+=(dpkg)
    command -v strip >/dev/null || pkgs+=(binutils)
    command -v python3 >/dev/null || pkgs+=(python3)
    if [ "${#pkgs[@]}" -gt 0 ]; then
        log "installing ${pkgs[*]}"
        apt-get update -qq
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${pkgs[@]}"
    fi
}

# --- the root filesystem ------------------------------------------------------------------
# Everything that shapes the image is in these variables: their hash names the cached image.
# rt-tests: cyclictest measures how late the VM wakes a 4 ms thread (the bus allowance).
GUEST_PKGS="systemd-sysv,udev,dbus,kmod,iproute2,procps,rt-tests,linux-image-amd64"
# The guest's side of the runner: mounts this run's work directory and runs guest.sh once
# multi-user is up (Type=simple so that boot completes; guest.sh waits for it).
RUNNER_UNIT='[Unit]
Description=cnc systemd-vm suite runner
ConditionKernelCommandLine=cnc.suite
After=systemd-journald.service systemd-udevd.service
[Service]
Type=simple
ExecStart=/bin/sh -c "modprobe 9pnet_virtio; mkdir -p /mnt/suite && mount -t 9p -o trans=virtio,version=9p2000.L suite /mnt/suite && exec /bin/sh /mnt/suite/guest.sh"
StandardOutput=tty
StandardError=tty
TTYPath=/dev/ttyS0
[Install]
WantedBy=multi-user.target'
# The VM has no network card: nothing can bring a link "online", so wait-online (enabled
# together with systemd-networkd) would hold network-online.target, and cncd with it, for
# 2 minutes. A real controller has its Ethernet link for that.
CUSTOMIZE='set -e
echo cnc-vm > "$1/etc/hostname"
printf "%s\n" "$RUNNER_UNIT" > "$1/etc/systemd/system/cnc-vm-suite.service"
chroot "$1" systemctl enable cnc-vm-suite.service
chroot "$1" systemctl mask systemd-networkd-wait-online.service serial-getty@ttyS0.service getty@tty1.service
chroot "$1" passwd -d root
echo "/dev/vda / ext4 rw,relatime 0 1" > "$1/etc/fstab"
# Keep the image small: modules no VM needs (the initramfs is already built).
for d in sound drivers/gpu drivers/media drivers/infiniband drivers/net/wireless drivers/staging drivers/bluetooth drivers/usb drivers/hid drivers/iio drivers/input net/wireless net/bluetooth; do
    rm -rf "$1"/usr/lib/modules/*/kernel/$d
done
for m in "$1"/usr/lib/modules/*; do chroot "$1" depmod -a "$(basename "$m")"; done
rm -rf "$1"/var/cache/apt/archives/*.deb "$1"/var/lib/apt/lists/*'
IMAGE_KEY=$(printf '%s\n' "$SUITE_NAME" "$GUEST_PKGS" "$RUNNER_UNIT" "$CUSTOMIZE" |
    sha256sum | cut -c1-16)
IMAGE="$CACHE/rootfs-$IMAGE_KEY.ext4"
KERNEL="$CACHE/vmlinuz-$IMAGE_KEY"
INITRD="$CACHE/initrd-$IMAGE_KEY"

build_image() {
    log "building the VM root filesystem (mmdebstrap $SUITE_NAME: $GUEST_PKGS)"
    mkdir -p "$CACHE"
    local dir="$CACHE/rootfs-build"
    rm -rf "$dir" "$CACHE"/rootfs-*.ext4 "$CACHE"/vmlinuz-* "$CACHE"/initrd-*
    export RUNNER_UNIT
    mmdebstrap --quiet --mode=root --variant=minbase --include="$GUEST_PKGS" \
        --customize-hook="$CUSTOMIZE" \
        "$SUITE_NAME" "$dir" "$MIRROR"
    cp "$(ls "$dir"/boot/vmlinuz-* | sort -V | tail -n 1)" "$KERNEL.tmp"
    cp "$(ls "$dir"/boot/initrd.img-* | sort -V | tail -n 1)" "$INITRD.tmp"
    # An ext4 image made from the directory (no loop device, no mount).
    mke2fs -q -t ext4 -L cnc-vm -d "$dir" "$IMAGE.tmp" 2G
    rm -rf "$dir"
    mv "$KERNEL.tmp" "$KERNEL"
    mv "$INITRD.tmp" "$INITRD"
    mv "$IMAGE.tmp" "$IMAGE"
    log "image $(du -h --apparent-size "$IMAGE" | cut -f1) ($(du -h "$IMAGE" | cut -f1) used)"
}

install_tools
# The root filesystem (downloads, dpkg in a chroot, the initramfs: mostly waiting on the
# network and the disk) is built in the background while the release build keeps the CPUs
# busy: on a fresh machine the two together take about as long as the longer of them.
T0=$(date +%s)
IMAGE_PID=
if [ -f "$IMAGE" ] && [ -f "$KERNEL" ] && [ -f "$INITRD" ]; then
    log "cached root filesystem $IMAGE"
else
    mkdir -p "$CACHE"
    IMAGE_LOG="$CACHE/rootfs-build.log"
    log "building the root filesystem in the background (log: $IMAGE_LOG)"
    (
        build_image
        echo "image ready after $(($(date +%s) - T0)) s"
    ) >"$IMAGE_LOG" 2>&1 &
    IMAGE_PID=$!
fi
wait_image() {
    [ -z "$IMAGE_PID" ] && return 0
    if ! wait "$IMAGE_PID"; then
        log "building the root filesystem failed; its log:"
        tail -n 40 "$IMAGE_LOG"
        exit 1
    fi
    IMAGE_PID=
    cat "$IMAGE_LOG"
}
if [ "${CNC_VM_ONLY_IMAGE:-0}" = 1 ]; then
    wait_image
    log "image ready ($(($(date +%s) - T0)) s)"
    exit 0
fi

# --- the package and the simulator ---------------------------------------------------------
# sim-can is the dev build the vcan suite already made: the same cargo invocation as there
# (the same packages, so the same unified features), nothing to compile when it ran first.
# The package is the release build a machine gets.
T1=$(date +%s)
log "building the Debian package (${CNC_DEB_PROFILE:-release}) and sim-can"
DEB=$(deploy/build-deb.sh | tail -n 1)
[ "${CNC_PREBUILT_BINS:-}" = 1 ] || cargo build --locked -q -p sim -p daemon --bins
T_BUILD=$(($(date +%s) - T1))
IMAGE_BUILT=${IMAGE_PID:+built}
wait_image
T_IMAGE=$(($(date +%s) - T0))
[ -n "$IMAGE_BUILT" ] && IMAGE_NOTE="image built in parallel, ready after $T_IMAGE s" || IMAGE_NOTE="image cached"
WORK=$(mktemp -d /tmp/cnc-systemd-vm.XXXXXX)
cp "$DEB" "$WORK/cncd-a.deb"
# A second package with a higher version: the guest upgrades to it and rolls back.
version=$(dpkg-deb -f "$DEB" Version)
DEB_B=$(CNC_DEB_VERSION="$version+1" deploy/build-deb.sh --no-build "$WORK/b" | tail -n 1)
mv "$DEB_B" "$WORK/cncd-b.deb"
rm -rf "$WORK/b"
cp "$CARGO_TARGET_DIR/debug/sim-can" "$WORK/sim-can"
cp "$SUITE/guest.sh" "$WORK/guest.sh"
log "package $(basename "$DEB") ($(du -h "$DEB" | cut -f1)), built in $T_BUILD s"

# --- boot ----------------------------------------------------------------------------------
ACCEL=tcg
CPU=max
if [ "${CNC_VM_KVM:-0}" = 1 ] && [ -w /dev/kvm ]; then
    ACCEL=kvm
    CPU=host
fi
CONSOLE="$WORK/console.log"
T0=$(date +%s)
log "booting the VM ($ACCEL; console in $CONSOLE)"
# The root filesystem is a snapshot: the cached image is never written.
timeout "${CNC_VM_TIMEOUT_S:-900}" qemu-system-x86_64 \
    -accel "$ACCEL" -cpu "$CPU" -smp 2 -m 1536 \
    -kernel "$KERNEL" -initrd "$INITRD" \
    -append "root=/dev/vda rw console=ttyS0 quiet systemd.show_status=false cnc.suite" \
    -drive "file=$IMAGE,if=virtio,format=raw,snapshot=on" \
    -virtfs "local,path=$WORK,mount_tag=suite,security_model=none,id=suite" \
    -nic none -display none -no-reboot \
    -serial "file:$CONSOLE" -monitor none </dev/null >"$WORK/qemu.log" 2>&1 ||
    log "qemu exited with $? (timeout: ${CNC_VM_TIMEOUT_S:-900} s)"
T_VM=$(($(date +%s) - T0))

# --- results -------------------------------------------------------------------------------
RESULTS="$WORK/results.txt"
echo
grep -E '^(ok|not ok|#)' "$RESULTS" 2>/dev/null || true
passed=$(grep -c '^ok ' "$RESULTS" 2>/dev/null || true)
failed=$(grep -c '^not ok ' "$RESULTS" 2>/dev/null || true)
T_ALL=$(($(date +%s) - T_START))
log "$IMAGE_NOTE; package $T_BUILD s, VM $T_VM s, total $T_ALL s"
if ! grep -q '^GUEST-DONE' "$RESULTS" 2>/dev/null; then
    log "the guest did not finish; last console lines:"
    tail -n 40 "$CONSOLE" 2>/dev/null || true
    failed=$((${failed:-0} + 1))
fi
echo "systemd-vm: ${passed:-0} passed, ${failed:-0} failed"
if [ "${failed:-0}" -ne 0 ] || [ "${passed:-0}" -eq 0 ]; then
    log "work directory kept: $WORK"
    exit 1
fi
[ "${CNC_VM_KEEP:-0}" = 1 ] && log "work directory: $WORK" || rm -rf "$WORK"
