#!/bin/sh
# test-light
# test_lms200_ps: marie-lms200 under marie-am; while its (virtual) LMS200 is frozen, marie ps
# says degraded and the manager leaves the process alone; scans again: running.
. tests/lib.sh
T=$(mktemp -d /tmp/marie-test-lms200ps.XXXXXX)
export MARIE_KEY=$T/key MARIE_SEQ_FILE=$T/seq
M="$BIN/marie"
OUT=$T
cleanup() { [ -n "$pid_emu" ] && kill -CONT "$pid_emu" 2>/dev/null; "$M" down > /dev/null 2>&1; stop_started; rm -rf "$T"; }
trap cleanup EXIT

cat > "$T/sys.yaml" <<EOS
system: lms200ps
hosts: [alpha]
components:
  laser:
    exec: $(cd "$BIN" && pwd)/marie-lms200
    host: alpha
    heartbeat_timeout: 3
    params: {device: $T/ttyLMS, baud: 38400, resolution: 1, degraded_ms: 800}
EOS
is_state() { [ "$(ps_field laser state)" = "$1" ]; }

"$M" keygen "$T/key"
start emu "$BIN/marie-vlms200" --link "$T/ttyLMS" --rate 20
start am "$BIN/marie-am" --host alpha --state-dir "$T/am"
wait_for 5 test -e "$T/ttyLMS"
sleep 0.3
check "marie up starts the laser driver" "$M" --timeout 15 up "$T/sys.yaml"
check "marie ps: running while scans flow" wait_for 10 is_state running
pid=$(ps_field laser pid)
check "the driver has a pid" test "${pid:-0}" -gt 0
# Both read YAML (the system file, the parameters) only while starting: the library is let go.
check "the running driver holds no YAML library" sh -c "! grep -q libfyaml /proc/$pid/maps"
check "the manager holds no YAML library after up" sh -c "! grep -q libfyaml /proc/$pid_am/maps"
kill -STOP "$pid_emu"
check "marie ps: degraded while the device is frozen" wait_for 10 is_state degraded
"$M" ps
sleep 2
check "the manager leaves a degraded driver alone" test "$(ps_field laser pid)" = "$pid"
check "no restart counted" test "$(ps_field laser restarts)" = 0
kill -CONT "$pid_emu"
check "marie ps: running again once scans flow" wait_for 15 is_state running
check "the same process throughout" test "$(ps_field laser pid)" = "$pid"
finish
