#!/bin/sh
# test-light
# test_multihost: four network namespaces (onboard1-3, laptop) on one bridge, LCM with ttl=1,
# a marie-am in each and marie on the laptop: cross-host dependency order, respawn after
# kill -9, a lost host shown by marie ps, and its components back when its manager returns.
. tests/managers/fourhosts.sh

"$BIN/marie" keygen "$T/key"
for h in $HOSTS; do start_am "$h"; done
sleep 0.5

bus_crosses_hosts() {
    # every manager's status reaches the laptop over the bridge
    out=$(M ps 2>&1); echo "$out"
    for h in onboard1 onboard2 onboard3; do echo "$out" | grep -q "^$h " || return 1; done
}
check "laptop hears the onboard managers over the bridge" wait_for 10 bus_crosses_hosts
check "marie up from the laptop" M up tests/data/managers/multi.yaml
order() {
    cat "$T/trace"
    for pair in "drive odom" "gyro odom" "odom loc" "loc planner" "planner viewer"; do
        set -- $pair
        r=$(trace_line "$1" running); e=$(trace_line "$2" exec)
        [ -n "$r" ] && [ -n "$e" ] && [ "$r" -lt "$e" ] || { echo "bad order: $pair"; return 1; }
    done
}
check "cross-host dependency order" order
all_running() { [ "$(M ps | grep -c ' running ')" -eq 6 ]; }
check "ps: six components running on four hosts" all_running
M ps

ODOM=$(field onboard2 odom pid)
kill -9 "$ODOM"
odom_back() { p=$(field onboard2 odom pid); [ -n "$p" ] && [ "$p" != 0 ] && [ "$p" != "$ODOM" ] && [ "$(field onboard2 odom state)" = running ]; }
check "kill -9 on onboard2: restarted there" wait_for 10 odom_back

LOC=$(field onboard3 loc pid)
# a watching marie ps on the laptop, one JSON table a second
nsenter -t "$(cat "$T/laptop.ns")" -n --preserve-credentials "$BIN/marie" --json ps --watch > "$T/watch.json" 2>&1 &
WATCH=$!
sleep 1.5
kill -9 "$(cat "$T/onboard3.am")"
lost() { out=$(M ps); rc=$?; echo "$out"; [ $rc -eq 3 ] && echo "$out" | grep -q '^onboard3 .* lost'; }
# the first ps after the kill (it listens 1.2 s) already shows the host lost
check "killed manager: host lost in the next marie ps" lost
check "its components went down with it" wait_for 5 sh -c "! kill -0 $LOC 2>/dev/null"
watch_lost() { tail -1 "$T/watch.json" | grep -q '"host":"onboard3","lost":true'; }
check "ps --watch shows onboard3 lost" wait_for 10 watch_lost
kill "$WATCH"
start_am onboard3
loc_back() { p=$(field onboard3 loc pid); [ -n "$p" ] && [ "$p" != 0 ] && [ "$p" != "$LOC" ] && [ "$(field onboard3 planner state)" = running ]; }
check "restarted manager: components back" wait_for 15 loc_back
check "ps exit 0 with every host heard" M ps

check "move gyro to onboard2" M move gyro onboard2
gyro_moved() { [ "$(field onboard2 gyro state)" = running ] && [ -z "$(field onboard1 gyro state)" ]; }
check "gyro runs on onboard2 now" wait_for 10 gyro_moved
# the move outlives both managers involved: restarted, onboard2 runs gyro and onboard1 does not
restart_am() { kill "$(cat "$T/$1.am")"; while kill -0 "$(cat "$T/$1.am")" 2>/dev/null; do sleep 0.1; done; start_am "$1"; }
restart_am onboard1
restart_am onboard2
check "move survives restarting both managers" wait_for 20 gyro_moved

# doctor: healthy, every host heard and every check ok; then a real problem, a stuck manager
doctor_ok() {
    out=$(M doctor); rc=$?; echo "$out"
    [ $rc -eq 0 ] || return 1
    for h in $HOSTS; do echo "$out" | grep -q "^ok  *host  *$h: clock" || return 1; done
    ! echo "$out" | grep -q '^FAIL'
}
check "doctor: every host heard, no problem" doctor_ok
AM3=$(cat "$T/onboard3.am")
kill -STOP "$AM3"
doctor_lost() {
    out=$(M doctor); rc=$?; echo "$out"
    [ $rc -eq 1 ] && echo "$out" | grep -q '^FAIL  *host  *onboard3: not heard from' && echo "$out" | grep -q '^1 problem'
}
check "doctor: a stuck manager is reported, exit 1" doctor_lost
kill -CONT "$AM3"

# up: a system naming a host whose manager never answers exits 3 (host unreachable)
sed 's/host: onboard3/host: onboard9/; s/hosts: \[onboard1, onboard2, onboard3, laptop\]/hosts: [onboard1, onboard2, onboard3, laptop, onboard9]/' \
    tests/data/managers/multi.yaml > "$T/unreachable.yaml"
up_unreachable() { M --timeout 5 up "$T/unreachable.yaml"; rc=$?; echo "exit $rc"; [ $rc -eq 3 ]; }
check "down across hosts" M down
check "up with a host nobody manages: exit 3" up_unreachable
M down > /dev/null 2>&1
finish
