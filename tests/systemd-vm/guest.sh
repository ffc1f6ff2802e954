#!/bin/bash
[ -z "${BASH_VERSION:-}" ] && exec /bin/bash "$0" "$@"
# Runs inside the systemd VM (tests/systemd-vm/run.sh boots it): the checks of issue #21 against
# the installed Debian package under the real systemd (PID 1). /mnt/suite is the host's work
# directory: the packages (cncd-a.deb, and cncd-b.deb with a higher version), sim-can; the
# results go to results.txt there, one `ok - ...` / `not ok - ...` line per check and `# ...`
# lines with figures.
set -u
S=/mnt/suite
RES=$S/results.txt
: >"$RES"
PASS=0
FAIL=0
export PATH=/usr/sbin:/usr/bin:/sbin:/bin
SOCK=unix:/run/cncd/cncd.sock

say() { echo "$*" | tee -a "$RES"; }
ok() { say "ok - $*"; PASS=$((PASS + 1)); }
bad() { say "not ok - $*"; FAIL=$((FAIL + 1)); }
info() { say "# $*"; }
# check NAME COMMAND...: one result line.
check() {
    local name=$1
    shift
    if "$@"; then ok "$name"; else bad "$name"; fi
}
# wait_until SECONDS COMMAND...: polls every 0.2 s.
wait_until() {
    local end=$((SECONDS + $1))
    shift
    until "$@"; do
        [ "$SECONDS" -ge "$end" ] && return 1
        sleep 0.2
    done
}
prop() { systemctl show -P "$1" cncd.service; }
# A time span property of the unit (e.g. TimeoutStartUSec, printed as "1min") in µs.
# (The µs line reads "μs:" or "us:" depending on the locale.)
prop_us() { systemd-analyze timespan "$(prop "$1")" 2>/dev/null | sed -n 's/^ *[^ ]*s: *\([0-9][0-9]*\)$/\1/p'; }
is_state() { [ "$(prop ActiveState)" = "$1" ]; }
mono_us() { awk '{printf "%d\n", $1 * 1000000}' /proc/uptime; }
ctl() { timeout 120 cncctl --addr "$SOCK" "$@"; }
# The journal of cncd (and of systemd about cncd) since monotonic time $1 (µs).
journal_since() {
    journalctl -b -u cncd.service -o short-monotonic --no-pager |
        awk -v t="$1" '{ ts = $0; sub(/^\[ */, "", ts); sub(/\].*/, "", ts); if (ts * 1000000 >= t) print }'
}

export -f wait_until journal_since

finish() {
    journalctl -b --no-pager -o short-monotonic >"$S/journal.txt" 2>&1
    say "systemd-vm-guest: $PASS passed, $FAIL failed"
    echo "GUEST-DONE" >>"$RES"
    sync
    systemctl poweroff --no-block
    exit 0
}

state=$(systemctl is-system-running --wait)
info "boot: $state; $(systemd-analyze time 2>/dev/null | head -n 1)"
info "kernel $(uname -r), $(systemctl --version | head -n 1)"

# --- the package --------------------------------------------------------------------------
inst=$(dpkg -i "$S/cncd-a.deb" 2>&1)
check "dpkg -i installs the package" [ $? -eq 0 ]
echo "$inst" | sed 's/^/#   /'
check "post-install created the system user cncd (home /var/lib/cncd, group dialout)" \
    bash -c 'getent passwd cncd | grep -q ":/var/lib/cncd:" && id -nG cncd | grep -qw dialout'
check "installing enables nothing: cncd disabled and inactive" \
    bash -c '[ "$(systemctl is-enabled cncd)" = disabled ] && [ "$(systemctl is-active cncd)" = inactive ]'
check "post-install tells the admin how to enable it" grep -q "systemctl enable --now cncd" <<<"$inst"
check "/etc/cncd/cncd.toml is a conffile, mode 0640 root:cncd" \
    bash -c 'dpkg-query -W -f="\${Conffiles}" cncd | grep -q "/etc/cncd/cncd.toml" &&
             [ "$(stat -c "%a %U %G" /etc/cncd/cncd.toml)" = "640 root cncd" ]'
check "the example configuration passes cncd --check-config" \
    cncd --check-config --config /etc/cncd/cncd.toml
check "the unit, sysusers, tmpfiles and docs are installed" \
    test -f /usr/lib/systemd/system/cncd.service -a -f /usr/lib/sysusers.d/cncd.conf \
    -a -f /usr/lib/tmpfiles.d/cncd.conf -a -f /usr/share/doc/cncd/README.md
check "systemd-analyze verify accepts the installed unit" \
    bash -c '[ -z "$(systemd-analyze verify cncd.service 2>&1)" ]'

# --- vcan0 from the networkd files ----------------------------------------------------------
cp /usr/share/doc/cncd/examples/network/80-vcan0.netdev \
    /usr/share/doc/cncd/examples/network/80-vcan0.network /etc/systemd/network/
systemctl restart systemd-networkd
check "systemd-networkd brings vcan0 up from deploy/network/80-vcan0.*" \
    wait_until 120 bash -c 'ip link show vcan0 2>/dev/null | grep -q "[<,]UP[,>]"'
info "$(ip -details link show vcan0 | head -n 3 | tr -s ' ' | tr '\n' ' ')"

# --- how late this VM wakes a 4 ms real-time thread (a figure for the results) -------------
# Emulation on a loaded host wakes periodic threads late, and cncd and sim-can both run here.
# A first version derived the bus timeouts from this probe (10 x (4 ms + 2 x max)); under a
# load of 18 on the 2-core host a 31 ms probe maximum gave 680 ms, and a later stall faulted
# the drives: a 10 s sample does not bound the stalls of a 5-minute run. So this suite takes
# the bus timeouts out of play instead (below) and only reports the probe.
probe=$(cyclictest -q -m -p 80 -i 4000 -D 10 2>&1)
late_us=$(sed -n 's/.*Max: *\([0-9]*\).*/\1/p' <<<"$probe" | sort -n | tail -n 1)
info "VM wake-up lateness of a 4 ms SCHED_FIFO thread (cyclictest 10 s): max ${late_us:-?} us"

# The admin's configuration: three CiA 402 drives on vcan0 (the conffile, edited).
cat >/etc/cncd/cncd.toml <<'CONF'
# edited by the systemd VM suite
[[axes]]
name = "X"
node_id = 1
increments_per_mm = 10000
[[axes]]
name = "Y"
node_id = 2
increments_per_mm = 10000
[[axes]]
name = "Z"
node_id = 3
increments_per_mm = 10000
[bus]
kind = "can"
interface = "vcan0"
# Bus fault detection is the vcan suite's subject, not this one's: here the bus timeouts are
# set beyond any stall the emulation shows (60 s, the most the drives' 16-bit consumer time
# holds rounded down), so no check depends on how late the emulated threads run.
tpdo_missing_ticks = 15000
heartbeat_timeout_ms = 60000
drive_consumer_timeout_ms = 60000
boot_timeout_ms = 60000
enable_timeout_ms = 60000
sdo_timeout_ms = 60000
[api]
listen = "127.0.0.1:50051"
unix_socket = "/run/cncd/cncd.sock"
[storage]
dir = "/var/lib/cncd"
[rt]
priority = 80
lock_memory = true
CONF
check "the vcan configuration passes --check-config" \
    cncd --check-config --config /etc/cncd/cncd.toml

# The watchdog is off in this VM except in its own check below. Why: cncd pings WATCHDOG=1 every
# 1.5 s only if the real-time thread made at least half of the 4 ms ticks due in that time
# (daemon/src/runtime/systemd.rs); a tick that wakes more than a period late skips its deadline.
# Software emulation on a loaded host runs the vCPUs in bursts (the cyclictest probe above
# shows wake-ups late by tens to hundreds of ms), so cncd could rightly judge itself stalled
# and systemd would restart it in the middle of the other checks. A drop-in WatchdogSec=0
# turns it off; the watchdog check drops that line, i.e. runs with the unit's 3 s.
mkdir -p /etc/systemd/system/cncd.service.d
# The start-up of three drives over the emulated bus took 54 s once under load: the VM gives
# the start 5 minutes instead of the unit's 60 s (the same drop-in).
vm_dropin() { printf '[Service]\nWatchdogSec=0\nTimeoutStartSec=300\n' >/etc/systemd/system/cncd.service.d/50-vm.conf; }
vm_dropin
systemctl daemon-reload

# --- start: active only after READY=1, i.e. once the drives are operational ----------------
# Waits for a start are bounded by the unit's TimeoutStartSec (the VM's): beyond it systemd gives up.
start_us=$(prop_us TimeoutStartUSec)
start_s=$((${start_us:-60000000} / 1000000))
info "the unit's TimeoutStartSec: ${start_s} s"
systemctl start --no-block cncd
check "without drives on the bus cncd stays activating, status 'enabling drives'" \
    wait_until "$start_s" bash -c '[ "$(systemctl show -P StatusText cncd)" = "enabling drives" ] &&
                           [ "$(systemctl show -P ActiveState cncd)" = activating ]'
sleep 2
check "still activating 2 s later (no READY=1 without operational drives)" is_state activating
systemd-run --quiet --unit=sim-can --property=Type=exec \
    "$S/sim-can" --iface vcan0 --node 1 --node 2 --node 3
sim_at=$(systemctl show -P ExecMainStartTimestampMonotonic sim-can.service)
check "cncd becomes active (running) once sim-can's drives are operational" \
    wait_until "$start_s" is_state active
active_at=$(prop ActiveEnterTimestampMonotonic)
check "active only after the drives appeared (active at ${active_at} us > sim-can start ${sim_at} us)" \
    [ "$active_at" -gt "$sim_at" ]
check "READY=1 came with the status line of the running machine" \
    bash -c 'systemctl show -P StatusText cncd | grep -q "^axes XYZ on bus can on vcan0, API on"'
check "the journal says 'drives operational' before systemd's 'Started'" \
    bash -c 'journalctl -b -u cncd -o cat --no-pager | grep -m1 -e "drives operational" -e "^Started cncd" |
             grep -q "drives operational"'
pid=$(prop MainPID)
sleep 6
check "cncd stays up (same process 6 s later, no restart)" \
    [ "$(prop MainPID)" = "$pid" -a "$(prop NRestarts)" = 0 ]

# --- real-time scheduling through the unit's limits, not root -------------------------------
pid=$(prop MainPID)
rt_tid=$(grep -lx cnc-rt /proc/"$pid"/task/*/comm 2>/dev/null | head -n 1 | cut -d/ -f5)
check "cncd runs as user cncd without capabilities" \
    bash -c "[ \"\$(stat -c %U /proc/$pid)\" = cncd ] &&
             grep -q '^CapEff:[[:space:]]*0000000000000000' /proc/$pid/status"
sched=$(chrt -p "${rt_tid:-0}" 2>&1)
info "cnc-rt thread $rt_tid: $(echo "$sched" | tr '\n' ' ')"
check "the real-time thread cnc-rt runs SCHED_FIFO at priority 80" \
    bash -c "grep -q 'policy: SCHED_FIFO' <<<\"$sched\" && grep -q 'priority: 80' <<<\"$sched\""
check "the journal says the memory is locked and SCHED_FIFO is on" \
    bash -c 'journalctl -b -u cncd -o cat --no-pager | grep -q "memory locked" &&
             journalctl -b -u cncd -o cat --no-pager | grep -q "SCHED_FIFO"'

# --- a program on vcan0 against the drive simulator -----------------------------------------
printf 'N10 G90 G1 F3000 X10 Y5 Z-1\nN20 X12.5 Y0\nN30 G0 X0 Y0 Z0\n' >/root/part.nc
run_out=$(ctl run --quiet /root/part.nc 2>&1)
check "cncctl run: a program runs to its end on vcan0 ($run_out)" [ $? -eq 0 ]
check "the machine is idle afterwards" bash -c "cncctl --addr $SOCK status | grep -qi idle"

# --- stop with a status stream open ---------------------------------------------------------
cncctl --addr "$SOCK" --json status --watch --rate 10 >/root/watch.jsonl 2>/root/watch.err &
watch_pid=$!
wait_until 120 test -s /root/watch.jsonl
t0=$(mono_us)
systemctl stop cncd
t1=$(mono_us)
stop_ms=$(((t1 - t0) / 1000))
info "systemctl stop with a status stream open: ${stop_ms} ms (TimeoutStopSec=$(prop TimeoutStopUSec))"
# The unit's own TimeoutStopSec (systemd prints it as a time span), not a guess.
stop_limit_us=$(prop_us TimeoutStopUSec)
stop_within_limit() { [ -n "$stop_limit_us" ] && [ "$((stop_ms * 1000))" -lt "$stop_limit_us" ]; }
check "systemctl stop ends within the unit's TimeoutStopSec (${stop_limit_us:-?} us)" stop_within_limit
check "cncd exited by itself with status 0 (Result=success)" \
    bash -c '[ "$(systemctl show -P Result cncd)" = success ] &&
             [ "$(systemctl show -P ExecMainStatus cncd)" = 0 ]'
check "the journal of the stop is there (Stopping ... Stopped)" \
    bash -c "journal_since $t0 | grep -q 'Stopped cncd'"
check "no SIGKILL and no stop timeout in the journal" \
    bash -c "! journal_since $t0 | grep -Ei 'sigkill|timed out|killing'"
check "the open status stream ended with the stop" \
    wait_until 120 bash -c "! kill -0 $watch_pid 2>/dev/null"
wait "$watch_pid"
watch_rc=$?
info "cncctl status --watch: exit $watch_rc, $(wc -l </root/watch.jsonl) status lines, stderr: $(head -c 300 /root/watch.err)"
check "... cleanly: cncctl status --watch exited 0" [ "$watch_rc" -eq 0 ]
rest_exit=$(journal_since "$t0" | awk '
    { ts = $0; sub(/^\[ */, "", ts); sub(/\].*/, "", ts) }
    /axis at rest/ { rest = ts }
    /cncd stopped/ { if (rest) printf "%d", (ts - rest) * 1000 }')
info "from the axes at rest to 'cncd stopped': ${rest_exit:-?} ms (emulated; the API drains 500 ms at most)"
# What the stop must show, without a timing: cncd exits after the axes are at rest, and the
# open stream ended because SIGTERM ended it, not because the API cut it at the drain time.
check "cncd stopped after every axis was at rest" \
    bash -c "journal_since $t0 | awk '/axis at rest/ && !stopped { n++ } /cncd stopped/ { stopped = 1 } END { exit !(stopped && n >= 3) }'"
check "no API call was still open at the drain time (the stream ended on SIGTERM)" \
    bash -c "journal_since $t0 | grep -q 'cncd stopped' && ! journal_since $t0 | grep -q 'API calls still open after the drain time'"

# --- structured journal fields --------------------------------------------------------------
fields=$(journalctl -u cncd CNC_AXIS=X -o verbose --no-pager 2>&1)
check "journalctl -u cncd CNC_AXIS=X finds the axis events with their fields" \
    bash -c "grep -q 'CNC_AXIS=X' <<<\"\$0\" && grep -q 'MESSAGE=axis at rest' <<<\"\$0\" &&
             ! grep -q 'CNC_AXIS=Y' <<<\"\$0\"" "$fields"
check "events carry the block number (CNC_BLOCK) and job (CNC_JOB)" \
    bash -c '[ -n "$(journalctl -u cncd -F CNC_BLOCK)" ] && [ -n "$(journalctl -u cncd -F CNC_JOB)" ]'

# --- hardening ------------------------------------------------------------------------------
systemctl start cncd
wait_until "$start_s" is_state active
pid=$(prop MainPID)
info "hardening checks on cncd pid $pid"
sec=$(systemd-analyze security cncd.service --no-pager 2>&1)
level=$(sed -n 's/.*Overall exposure level for cncd.service: \([0-9.]*\).*/\1/p' <<<"$sec")
info "systemd-analyze security cncd: exposure ${level:-?}"
grep -E '^✗' <<<"$sec" | sed 's/^/#   /' | tee -a "$RES" >/dev/null
check "exposure level ${level:-?} is at most 2.0" \
    awk -v l="${level:-99}" 'BEGIN { exit !(l <= 2.0) }'
# Inside the service's mount namespace, as its user: writes succeed only in its directories.
as_cncd() { nsenter -t "$pid" -m setpriv --reuid=cncd --regid=cncd --init-groups "$@"; }
for d in /var/lib/cncd /run/cncd /var/log/cncd; do
    check "the service can write in $d" as_cncd sh -c "touch $d/.w && rm $d/.w"
done
# Only meaningful while that process lives (a failed nsenter would look like a refused write).
check "cncd still the same process" [ "$(prop MainPID)" = "$pid" ]
denied=""
for d in /etc /etc/cncd /usr/bin /var/lib /var/cache /run /run/lock /dev/shm /home /root /srv /opt /boot; do
    as_cncd sh -c "touch $d/.cncd-write-test" 2>/dev/null && denied="$denied $d"
    rm -f "$d/.cncd-write-test" 2>/dev/null
done
check "the service cannot write elsewhere (writable:${denied:- none})" [ -z "$denied" ]
ro=""
for d in /etc /usr /var/lib /var/cache; do
    nsenter -t "$pid" -m sh -c "touch $d/.cncd-ro-test" 2>/dev/null && ro="$ro $d"
    rm -f "$d/.cncd-ro-test" 2>/dev/null
done
check "even root in the service's namespace finds /etc /usr /var read-only (writable:${ro:- none})" [ -z "$ro" ]
check "/tmp of the service is private (not the system's /tmp)" \
    bash -c "touch /tmp/.host-side && ! nsenter -t $pid -m test -e /tmp/.host-side; rc=\$?; rm -f /tmp/.host-side; exit \$rc"

# --- watchdog: a stalled real-time thread makes systemd restart cncd -------------------------
# What this proves: with the unit's WatchdogSec=3s, a real-time thread that stops ticking
# (the fault injection knob blocks it inside the bus cycle after 1000 ticks, as a wedged bus
# driver would) makes cncd withhold its pings and say why in the journal, systemd's watchdog
# aborts the process, Restart=on-failure starts it again, and the machine runs a program again.
# What it cannot prove here: that a machine holding its 4 ms period keeps the pings going
# (emulation cannot hold 4 ms; the ping rule is unit-tested without a clock, `judge` in
# daemon/src/runtime/systemd.rs, and the pings against a fake NOTIFY_SOCKET on the host in
# tests/tests/systemd_notify.rs). If emulation falls below half the ticks before the knob fires, the pings
# stop for the same rule and the same path runs; the "# watchdog:" line tells which happened.
restarts0=$(prop NRestarts)
mkdir -p /run/systemd/system/cncd.service.d
# The unit's WatchdogSec=3s again (the VM keeps only its longer start time), and the stall
# 1000 ticks after the start (after READY=1 in
# a fast machine; here emulation may stall it first: the journal line below tells).
printf '[Service]\nTimeoutStartSec=300\n' >/etc/systemd/system/cncd.service.d/50-vm.conf
printf '[Service]\nEnvironment=CNCD_FAULT_STALL_RT_AFTER_TICKS=1000\n' \
    >/run/systemd/system/cncd.service.d/50-stall.conf
systemctl daemon-reload
t0=$(mono_us)
systemctl restart --no-block cncd
check "with the RT thread stalled systemd's watchdog fires" \
    wait_until 120 bash -c "journal_since $t0 | grep -q 'Watchdog timeout'"
# Before the restart (RestartSec=5s): no knob, and the VM's watchdog setting again.
rm /run/systemd/system/cncd.service.d/50-stall.conf
vm_dropin
systemctl daemon-reload
check "cncd said why first: 'real-time thread stalled'" \
    bash -c "journal_since $t0 | grep -B1000 'Watchdog timeout' | grep -q 'real-time thread stalled'"
check "systemd restarted cncd and it is active again" \
    wait_until 120 bash -c "[ \"\$(systemctl show -P NRestarts cncd)\" -gt $restarts0 ] &&
                            [ \"\$(systemctl show -P ActiveState cncd)\" = active ]"
info "watchdog: $(journal_since "$t0" | grep -E 'fault injection|stalled|Watchdog|Main process exited|Scheduled restart' | cut -c1-120 | tr '\n' '|')"
check "after the restart the program runs again" \
    bash -c "timeout 120 cncctl --addr $SOCK run --quiet /root/part.nc >/dev/null"

# --- upgrade, rollback, removal -------------------------------------------------------------
pid=$(prop MainPID)
systemctl enable --quiet cncd
up=$(dpkg -i "$S/cncd-b.deb" 2>&1)
check "upgrade to $(dpkg-query -W -f='${Version}' cncd) installs" [ $? -eq 0 ]
check "the upgrade does not restart a running cncd and says so" \
    bash -c "[ \"\$(systemctl show -P MainPID cncd)\" = $pid ] && grep -q 'systemctl restart cncd' <<<\"\$0\"" "$up"
check "the admin's configuration survives the upgrade" grep -q "edited by the systemd VM suite" /etc/cncd/cncd.toml
check "the service stays enabled across the upgrade" [ "$(systemctl is-enabled cncd)" = enabled ]
down=$(dpkg -i "$S/cncd-a.deb" 2>&1)
check "rollback to the previous package (dpkg -i of the older .deb)" [ $? -eq 0 ]
check "the configuration survives the rollback" grep -q "edited by the systemd VM suite" /etc/cncd/cncd.toml
systemctl restart cncd
check "cncd runs after the rollback" is_state active
touch /var/lib/cncd/TAB0.KOR
dpkg -r cncd >/dev/null 2>&1
check "dpkg -r stops cncd and removes its enable link" \
    bash -c '[ "$(systemctl is-active cncd)" != active ] && [ ! -e /etc/systemd/system/multi-user.target.wants/cncd.service ]'
dpkg -P cncd >/dev/null 2>&1
check "purge removes /etc/cncd/cncd.toml and keeps the machine data in /var/lib/cncd" \
    bash -c '[ ! -e /etc/cncd/cncd.toml ] && [ -e /var/lib/cncd/TAB0.KOR ]'

finish
