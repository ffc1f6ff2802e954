#!/bin/sh
# The same as the systemd-networkd files, with plain `ip` (iproute2), for machines without
# networkd or for a quick test. Run as root.
#   can-up.sh can0 [BITRATE]   real CAN interface, default 1000000 bit/s
#   can-up.sh vcan0            virtual CAN interface (name starting with "vcan")
set -eu
ifname=${1:-can0}
bitrate=${2:-1000000}

case "$ifname" in
vcan*)
	modprobe vcan 2>/dev/null || true
	ip link show "$ifname" >/dev/null 2>&1 || ip link add dev "$ifname" type vcan
	ip link set "$ifname" up
	;;
*)
	ip link set "$ifname" down
	ip link set "$ifname" type can bitrate "$bitrate" sample-point 0.875 \
		restart-ms 100 berr-reporting on
	ip link set "$ifname" txqueuelen 128
	ip link set "$ifname" up
	;;
esac
ip -details link show "$ifname"
