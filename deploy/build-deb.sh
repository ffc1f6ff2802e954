#!/bin/sh
# Builds the Debian package of the controller: deploy/build-deb.sh [--no-build] [OUTDIR]
#
#   cncd_<version>_<arch>.deb in OUTDIR (default target/debian/): cncd and cncctl (release
#   build, stripped), the unit, sysusers.d and tmpfiles.d files, /etc/cncd/cncd.toml as a
#   conffile, the documentation and the network examples. Prints the package's path last.
#
# Made with dpkg-deb from the files in deploy/ (no debhelper, no cargo-deb: nothing to install
# or compile on the build machine beyond the Rust toolchain and dpkg). The version is the
# workspace version plus the commit time and hash, so every commit's package upgrades the one
# before (`+git202611232045.abc1234`); CNC_DEB_VERSION overrides it.
# --no-build packages the binaries already in target/release/. CNC_DEB_PROFILE=debug packages
# the dev build instead (quicker to iterate on the VM suite; never for a machine).
set -eu
cd "$(dirname "$0")/.."
ROOT=$PWD
BUILD=1
if [ "${1:-}" = --no-build ]; then
    BUILD=0
    shift
fi
TARGET="${CARGO_TARGET_DIR:-$ROOT/target}"
PROFILE="${CNC_DEB_PROFILE:-release}"
case "$PROFILE" in
release) BIN="$TARGET/release" PROFILE_FLAG=--release ;;
debug) BIN="$TARGET/debug" PROFILE_FLAG= ;;
*) echo "build-deb: CNC_DEB_PROFILE must be release or debug" >&2; exit 2 ;;
esac
OUT="${1:-$TARGET/debian}"

if [ "$BUILD" = 1 ]; then
    cargo build $PROFILE_FLAG --locked -q -p daemon --bin cncd --bin cncctl
fi
for b in cncd cncctl; do
    [ -x "$BIN/$b" ] || { echo "build-deb: $BIN/$b missing" >&2; exit 1; }
done

base=$(sed -n '/^\[workspace.package\]/,/^\[/s/^version *= *"\(.*\)"/\1/p' Cargo.toml)
if [ -n "${CNC_DEB_VERSION:-}" ]; then
    version=$CNC_DEB_VERSION
elif git rev-parse --git-dir >/dev/null 2>&1; then
    version="$base+git$(TZ=UTC git log -1 --date=format-local:%Y%m%d%H%M --format=%cd).$(git rev-parse --short=7 HEAD)"
else
    version=$base
fi
arch=$(dpkg --print-architecture)

pkg=$(mktemp -d "${TMPDIR:-/tmp}/cncd-deb.XXXXXX")
trap 'rm -rf "$pkg"' EXIT
umask 022
doc=$pkg/usr/share/doc/cncd

install -d "$pkg/DEBIAN" "$pkg/usr/bin" "$pkg/usr/lib/systemd/system" \
    "$pkg/usr/lib/sysusers.d" "$pkg/usr/lib/tmpfiles.d" "$pkg/etc/cncd" \
    "$doc/docs" "$doc/examples/network"
for b in cncd cncctl; do
    # Without the line tables of the release profile: the package is a fifth of the size.
    strip --strip-debug -o "$pkg/usr/bin/$b" "$BIN/$b"
    chmod 0755 "$pkg/usr/bin/$b"
done
# The unit of deploy/ names the paths of a manual install under /usr/local.
sed -e 's|/usr/local/bin/cncd|/usr/bin/cncd|' \
    -e 's|/usr/local/share/doc/cncd/|/usr/share/doc/cncd/|' \
    -e 's|^# Install: /etc/systemd/system/cncd.service; binary|# Installed by the cncd package: binary|' \
    -e 's|user from deploy/sysusers.d/cncd.conf|user from /usr/lib/sysusers.d/cncd.conf|' \
    deploy/cncd.service >"$pkg/usr/lib/systemd/system/cncd.service"
install -m 0644 deploy/sysusers.d/cncd.conf "$pkg/usr/lib/sysusers.d/cncd.conf"
install -m 0644 deploy/tmpfiles.d/cncd.conf "$pkg/usr/lib/tmpfiles.d/cncd.conf"
# The conffile: 0644 in the archive (the user cncd does not exist yet when dpkg unpacks);
# the post-install applies tmpfiles.d/cncd.conf (0640 root:cncd).
install -m 0644 deploy/cncd.toml "$pkg/etc/cncd/cncd.toml"
install -m 0644 deploy/README.md "$doc/README.md"
install -m 0644 README.md "$doc/README.project.md"
for d in api buses files; do
    install -m 0644 "docs/$d.md" "$doc/docs/$d.md"
done
install -m 0644 deploy/network/*.network deploy/network/*.netdev deploy/network/*.link \
    "$doc/examples/network/"
install -m 0755 deploy/network/can-up.sh "$doc/examples/network/can-up.sh"
cat >"$doc/copyright" <<EOF
Format: https://www.debian.org/doc/packaging-manuals/copyright-format/1.0/
Upstream-Name: cnc
License: MIT OR Apache-2.0

Files: *
License: MIT OR Apache-2.0
EOF

# The oldest glibc symbol version the binaries need.
glibc=$(objdump -T "$pkg/usr/bin/cncd" "$pkg/usr/bin/cncctl" |
    sed -n 's/.*GLIBC_\([0-9.]*\).*/\1/p' | sort -uV | tail -n 1)
size=$(du -sk --exclude=DEBIAN "$pkg" | cut -f1)
cat >"$pkg/DEBIAN/control" <<EOF
Package: cncd
Version: $version
Architecture: $arch
Maintainer: cnc project <cnc@localhost>
Installed-Size: $size
Depends: libc6 (>= $glibc), libgcc-s1, systemd (>= 247)
Suggests: can-utils, rt-tests
Section: misc
Priority: optional
Description: CNC motion controller daemon (cncd) and client (cncctl)
 cncd runs a 4 ms real-time loop driving servo axes over CANopen CiA 402
 (SocketCAN), a serial link, or a built-in simulated machine, under systemd
 (Type=notify, watchdog, real-time limits without root). cncctl is its gRPC
 client. Installing creates the user cncd and enables nothing: see
 /usr/share/doc/cncd/README.md.
EOF
echo /etc/cncd/cncd.toml >"$pkg/DEBIAN/conffiles"
install -m 0755 deploy/debian/postinst deploy/debian/prerm deploy/debian/postrm "$pkg/DEBIAN/"

mkdir -p "$OUT"
deb="$OUT/cncd_${version}_${arch}.deb"
dpkg-deb --root-owner-group -Zxz --build "$pkg" "$deb" >/dev/null
echo "$deb"
