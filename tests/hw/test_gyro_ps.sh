#!/bin/sh
# test-light
# test_gyro_ps: marie-gyro under marie-am against the virtual gyro on an emulated CAN bus: a
# normal start raises no fault event; with the device frozen marie ps says degraded; thawed,
# the driver configures it again and says running.
. tests/lib.sh
T=$(mktemp -d /tmp/marie-test-gyrops.XXXXXX)
export MARIE_KEY=$T/key MARIE_SEQ_FILE=$T/seq
M="$BIN/marie"
OUT=$T
cleanup() { [ -n "$pid_dev" ] && kill -CONT "$pid_dev" 2>/dev/null; "$M" down > /dev/null 2>&1; stop_started; rm -rf "$T"; }
trap cleanup EXIT

cat > "$T/sys.yaml" <<EOS
system: gyrops
hosts: [alpha]
components:
  gyro:
    exec: $(cd "$BIN" && pwd)/marie-gyro
    host: alpha
    heartbeat_timeout: 3
    params: {can: "emu:$T/can", node: 32, degraded_after: 0.8}
EOS
is_state() { [ "$(ps_field gyro state)" = "$1" ]; }
log() { cat "$T/am/logs/gyro.log" 2>/dev/null; }
configured() { log | grep -c 'event gyro_configured'; }

"$M" keygen "$T/key"
start bus "$BIN/marie-canbus" "$T/can"
wait_for 5 test -S "$T/can"
start dev "$BIN/marie-vcan-devices" --can "emu:$T/can" --left 0 --right 0 --gyro 32
start am "$BIN/marie-am" --host alpha --state-dir "$T/am"
sleep 0.5
check "marie up starts the gyro driver" "$M" --timeout 15 up "$T/sys.yaml"
check "the gyro is configured" wait_for 10 sh -c "grep -q 'event gyro_configured' $T/am/logs/gyro.log"
check "marie ps: running while samples flow" wait_for 10 is_state running
sleep 1
log
check "a normal start raises no gyro_offline event" sh -c "! grep -q gyro_offline $T/am/logs/gyro.log"
pid=$(ps_field gyro pid)
check "the driver has a pid" test "${pid:-0}" -gt 0
kill -STOP "$pid_dev"
check "marie ps: degraded while the device is frozen" wait_for 10 is_state degraded
"$M" ps
check "the frozen device is reported offline" wait_for 5 sh -c "grep -q gyro_offline $T/am/logs/gyro.log"
kill -CONT "$pid_dev"
reconfigured() { [ "$(configured)" -ge 2 ]; }
check "configured again once the device is back" wait_for 15 reconfigured
check "marie ps: running again once samples flow" wait_for 15 is_state running
log
check "the same process throughout" test "$(ps_field gyro pid)" = "$pid"
finish
