#!/bin/sh
# test-light
# test_up_check: marie up and marie-am --system refuse, before anything starts, entries their
# programs would reject (the programs describe themselves with --describe, cached per binary),
# missing programs, programs silent on or failing --describe, bad backoff and cycles (also for a
# component run alone); marie hash covers every setting and names the base; a long parse ends on
# SIGTERM or SIGINT.
. tests/lib.sh
# marie-test-comp, named bare by the system files in tests/data/managers
export PATH="$(pwd)/$B/tests/bin:$PATH"
T=$(mktemp -d /tmp/marie-test-upcheck.XXXXXX)
export MARIE_KEY=$T/key MARIE_SEQ_FILE=$T/seq MARIE_TEST_TRACE=$T/trace XDG_CACHE_HOME=$T/cache
M="$BIN/marie"
AM_PID=
cleanup() { [ -n "$AM_PID" ] && kill "$AM_PID" 2>/dev/null; wait 2>/dev/null; rm -rf "$T"; }
trap cleanup EXIT
"$M" keygen "$T/key"
mkdir "$T/bin"
cp "$B/tests/bin/marie-test-comp" "$T/bin/tc"
TC=$T/bin/tc
: > "$T/trace"

cat > "$T/bad.yaml" <<EOF
system: bad
hosts: [alpha]
components:
  fast:
    exec: $TC
    params: {print_hz: fast}
  nan:
    exec: $TC
    params: {exit_after_s: .nan}
  unknown:
    exec: $TC
    params: {colour: red}
  port:
    exec: $TC
    ports: {nosuch: X}
  missing:
    exec: marie-no-such-program
  notexec:
    exec: $(pwd)/tests/data/managers/single.yaml
  splitter:
    exec: marie-ca
    args: [splitter]
    params: {outputs: [B]}
EOF
# started: trace lines of a named component (describing a program runs it without a name)
started() { grep -v '^[0-9]* ? ' "$T/trace"; }
all_reported() {
    f=$T/bad.yaml
    grep -q "$f:6:[0-9]*: print_hz: expected a number, got 'fast'" "$1" &&
    grep -q "$f:9:[0-9]*: exit_after_s: expected a finite number, got '.nan'" "$1" &&
    grep -q "$f:12:[0-9]*: unknown parameter 'colour' for test_comp 'unknown'" "$1" &&
    grep -q "$f:15:[0-9]*: test_comp 'port' has no port 'nosuch'" "$1" &&
    grep -q "$f:17:[0-9]*: component 'missing': program 'marie-no-such-program' not found" "$1" &&
    grep -q "$f:19:[0-9]*: component 'notexec': program '$(pwd)/tests/data/managers/single.yaml' is not an executable" "$1" &&
    grep -q "$f:20:[0-9]*: splitter 'splitter': missing required parameter 'input'" "$1"
}

"$BIN/marie-am" --host alpha --state-dir "$T/am" > "$T/am.log" 2>&1 & AM_PID=$!
# the manager answers before the first up (else an up could pass for lack of a listener)
wait_for 15 "$M" ps --window 0.5 > /dev/null
up_refused() {
    "$M" up --no-wait "$T/bad.yaml" > "$T/up.out" 2>&1; rc=$?
    cat "$T/up.out"; echo "exit $rc"
    [ $rc -eq 2 ] && all_reported "$T/up.out"
}
check "marie up --no-wait: every bad entry refused (exit 2, file:line:col)" up_refused
nothing_started() { sleep 1; ! started; }
check "nothing was started" nothing_started
am_refused() {
    timeout 20 "$BIN/marie-am" --host alpha --state-dir "$T/am2" --system "$T/bad.yaml" > "$T/am2.out" 2>&1; rc=$?
    cat "$T/am2.out"; echo "exit $rc"
    [ $rc -eq 2 ] && all_reported "$T/am2.out" && ! started
}
check "marie-am --system: refused the same way (exit 2)" am_refused

# -- descriptions are cached per binary: a rebuilt (newer) program is described again
describes() { grep -c '^[0-9]* ? exec' "$T/trace"; }
cached() {
    n=$(describes); "$M" up --no-wait "$T/bad.yaml" > /dev/null 2>&1
    [ "$(describes)" = "$n" ] && [ -n "$(ls "$T/cache/marie/describe")" ]
}
check "a second up runs no --describe (cache)" cached
redescribed() {
    n=$(describes); touch -d '+1 second' "$TC"; "$M" up --no-wait "$T/bad.yaml" > /dev/null 2>&1
    [ "$(describes)" = $((n + 1)) ]
}
check "a newer binary is described again" redescribed
damaged_cache() {
    for f in "$T"/cache/marie/describe/*.json; do echo '{"describe": "garbage"' > "$f"; done
    n=$(describes); "$M" up --no-wait "$T/bad.yaml" > "$T/up2.out" 2>&1
    [ "$(describes)" -gt "$n" ] && all_reported "$T/up2.out"
}
check "a damaged cache entry is described again" damaged_cache

# -- a program that looks built on libmarie but never answers --describe, or fails it
printf '#!/bin/sh\n# marie-component-describe/1\nwhile :; do sleep 1; done\n' > "$T/bin/mute"
printf '#!/bin/sh\n# marie-component-describe/1\nexit 3\n' > "$T/bin/fails"
chmod +x "$T/bin/mute" "$T/bin/fails"
cat > "$T/mute.yaml" <<EOF
components:
  mute:
    exec: $T/bin/mute
  fails:
    exec: $T/bin/fails
EOF
mute_refused() {
    start=$(date +%s)
    out=$(timeout 30 "$M" up --no-wait "$T/mute.yaml" 2>&1); rc=$?; echo "$out"
    took=$(($(date +%s) - start)); echo "exit $rc after $took s"
    [ $rc -eq 2 ] && [ $took -ge 5 ] && [ $took -lt 20 ] &&
        echo "$out" | grep -q "mute.yaml:3:[0-9]*: component 'mute': '.*/mute --describe' failed: no answer within 5 s" &&
        echo "$out" | grep -q "mute.yaml:5:[0-9]*: component 'fails': '.*/fails --describe' failed: exit status 3" &&
        ! pgrep -f "$T/bin/mute" > /dev/null
}
check "a program silent on --describe is refused after 5 s (and killed), one that fails with its status" mute_refused

cat > "$T/backoff.yaml" <<EOF
components:
  a:
    exec: $TC
    restart: {policy: always, backoff_min: 4, backoff_max: 2}
EOF
backoff() {
    out=$("$M" up --no-wait "$T/backoff.yaml" 2>&1); rc=$?; echo "$out"
    [ $rc -eq 2 ] && echo "$out" | grep -q "backoff.yaml:4:14: component 'a': restart backoff_min (4 s) is above backoff_max (2 s)"
}
check "backoff_min above backoff_max refused" backoff
alone_cycle() {
    out=$(timeout 10 "$TC" --system tests/data/managers/cycle.yaml --name a 2>&1); rc=$?; echo "$out"
    [ $rc -eq 2 ] && echo "$out" | grep -q 'cycle.yaml:[0-9]*:[0-9]*: .*dependency cycle'
}
check "a component run alone refuses a dependency cycle" alone_cycle

cat > "$T/good.yaml" <<EOF
system: good
hosts: [alpha]
components:
  g:
    exec: $TC
    host: alpha
    params: {print_hz: 2, init_delay_ms: 10}
EOF
check "a good file still comes up" "$M" up "$T/good.yaml"
check "down" "$M" down

# -- the manager checks its programs in a child: a program slow to describe itself does not
# stop the manager's loop (its status goes on, so `marie ps` hears it) while it is checked
printf '#!/bin/sh\n# marie-component-describe/1\n[ "$1" = --describe ] && echo "$(date +%%s.%%N) $PPID $(cat /proc/$PPID/comm)" > "%s/describing.$$" && sleep 3\nexec %s "$@"\n' \
    "$T" "$TC" > "$T/bin/slow"
chmod +x "$T/bin/slow"
cat > "$T/slow.yaml" <<EOF
system: slow
hosts: [alpha]
components:
  s:
    exec: $T/bin/slow
    host: alpha
EOF
slow_check() {
    "$M" --timeout 10 up "$T/slow.yaml" > "$T/slow.out" 2>&1 & up=$!
    # the second --describe is the manager's (the first is marie up's own check)
    wait_for 15 sh -c "[ \$(ls $T/describing.* 2>/dev/null | wc -l) -ge 2 ]" || { echo "no second --describe"; return 1; }
    t0=$(date +%s%N)
    "$M" ps --window 1.2 > "$T/slow.ps" 2>&1; rc=$?
    ms=$(( ($(date +%s%N) - t0) / 1000000 )); cat "$T/slow.ps"
    echo "marie ps at $t0 while the manager checks: exit $rc after $ms ms"
    wait $up; urc=$?; cat "$T/slow.out" "$T"/describing.*
    [ $rc -eq 0 ] && grep -q alpha "$T/slow.ps" && [ $urc -eq 0 ] && "$M" ps | grep -q "^alpha  *s  *running"
}
check "the manager is heard while it checks a program slow to describe itself, then starts it" slow_check
check "down" "$M" down
shipped() {
    for p in "" "--profile sim" "--profile sim-channel" "--profile sim-voice" "--profile explore"; do
        # no manager serves these hosts: anything but 2 means the file passed every check
        "$M" --timeout 0.3 up config/spartacus.yaml $p; rc=$?
        [ $rc -ne 2 ] || return 1
    done
}
check "the shipped system passes the checks in every profile" shipped

# -- marie hash: every setting counts, and the base can be named
hash_of() { "$M" hash "$1" | awk -v n="$2" '$1 == n {print $2}'; }
defaults_restart() {
    sed 's/policy: on-failure, backoff_min: 0.05/policy: always, backoff_min: 0.05/' tests/data/managers/single.yaml > "$T/always.yaml"
    ! cmp -s tests/data/managers/single.yaml "$T/always.yaml" &&
        [ "$(hash_of tests/data/managers/single.yaml a)" != "$(hash_of "$T/always.yaml" a)" ]
}
check "hash: defaults restart changes every component's hash" defaults_restart
verdict() { awk -v n="$2" '$1 == n {print $2, $5}' "$1"; }
sim_vs_base() {
    "$M" hash config/spartacus.yaml --profile sim --base > "$T/h1" 2>&1; rc=$?; cat "$T/h1"
    [ $rc -eq 0 ] || return 1
    # read from the file: the sim profile replaces drives, gyro and laser (other CAN bus and
    # serial link, started after sim), adds sim and vision (the simulator's camera), removes estop,
    # and runs everything on the sim clock, where the real-time sched of the robot's chain
    # (laser, mailbox, behaviours, drives) is not applied
    for c in drives laser; do [ "$(verdict "$T/h1" $c)" = "differs params,depends,sched,clock" ] || return 1; done
    [ "$(verdict "$T/h1" gyro)" = "differs params,depends,clock" ] || return 1
    for c in mailbox behaviours; do [ "$(verdict "$T/h1" $c)" = "differs sched,clock" ] || return 1; done
    for c in odometry localizer planner sharedmap mission; do
        [ "$(verdict "$T/h1" $c)" = "differs clock" ] || return 1
    done
    [ "$(verdict "$T/h1" sim)" = "only-in-a " ] && [ "$(verdict "$T/h1" estop)" = "only-in-b " ] &&
        [ "$(verdict "$T/h1" vision)" = "only-in-a " ] && [ "$(verdict "$T/h1" odometer)" = "only-in-a " ] &&
        [ "$(wc -l < "$T/h1")" = 15 ]
}
check "hash: sim against the real robot (--base) on the shipped system" sim_vs_base
sim_vs_channel() {
    "$M" --json hash config/spartacus.yaml --profile sim --profile sim-channel > "$T/h2" || return 1
    python3 - "$T/h2" <<'EOF'
import json, sys
d = {c["name"]: c for c in json.load(open(sys.argv[1]))["components"]}
same = {"odometry", "localizer", "planner", "mailbox", "behaviours", "sharedmap", "mission"}
assert all(d[n]["verdict"] == "same" for n in same), d
assert d["sim"]["verdict"] == "differs" and d["sim"]["fields"] == ["params"], d["sim"]
assert all(d[n]["verdict"] == "only-in-a" for n in ("drives", "gyro", "laser", "vision", "odometer"))
assert len(d) == 13
EOF
}
check "hash: sim against sim-channel, as JSON" sim_vs_channel
explore_vs_sim() {
    "$M" --json hash config/spartacus.yaml --profile explore --profile sim > "$T/h3" || return 1
    python3 - "$T/h3" <<'EOF'
import json, sys
d = {c["name"]: c for c in json.load(open(sys.argv[1]))["components"]}
# explore extends sim: sim's drivers as they are, the simulator with its camera off (the
# profile's params:), the planner without a map, the mapper and the explorer in place of the
# localizer and the mission
same = {"drives", "gyro", "laser", "odometry", "mailbox", "behaviours", "sharedmap", "odometer"}
assert all(d[n]["verdict"] == "same" for n in same), d
for n in ("sim", "planner"):
    assert d[n]["verdict"] == "differs" and d[n]["fields"] == ["params"], d[n]
assert all(d[n]["verdict"] == "only-in-a" for n in ("mapper", "explore"))
assert all(d[n]["verdict"] == "only-in-b" for n in ("localizer", "mission", "vision"))
assert len(d) == 15
EOF
}
check "hash: explore (extends sim) against sim, as JSON" explore_vs_sim
no_robot() {
    out=$("$M" hash config/spartacus.yaml --profile sim --profile robot 2>&1); rc=$?; echo "$out"
    [ $rc -eq 2 ] && echo "$out" | grep -q -- '--base'
}
check "hash: an unknown profile points at --base" no_robot

# -- a long parse ends promptly on SIGTERM (exit 1) and SIGINT (exit 130)
python3 - "$T/big.yaml" <<'EOF'
import sys
out = ["system: big\nhosts: [h1]\ncomponents:\n"]
size, i = 0, 0
while size < 15_000_000:
    s = f"  c{i}:\n    exec: marie-example-producer\n    host: h1\n    params: {{rate_hz: 10, label: comp{i}}}\n"
    out.append(s); size += len(s); i += 1
open(sys.argv[1], "w").write("".join(out))
EOF
rss_kb() { awk '/^VmRSS/ {print $2}' "/proc/$1/status" 2>/dev/null || echo 0; }
interrupted() {
    sig=$1 want=$2
    "$M" up --no-wait "$T/big.yaml" > /dev/null 2>&1 & p=$!
    # the file is read whole before parsing: wait until it is in memory
    wait_for 20 sh -c "[ \$(awk '/^VmRSS/ {print \$2}' /proc/$p/status) -gt 20000 ]"
    kill -"$sig" $p; t0=$(date +%s%N)
    for i in $(seq 1 50); do kill -0 $p 2>/dev/null || break; sleep 0.1; done
    if kill -0 $p 2>/dev/null; then echo "still parsing 5 s after SIG$sig"; kill -9 $p; wait $p; return 1; fi
    wait $p; rc=$?; ms=$(( ($(date +%s%N) - t0) / 1000000 ))
    echo "SIG$sig: exit $rc after $ms ms"
    [ $rc -eq "$want" ]
}
check "SIGTERM ends a long parse (exit 1)" interrupted TERM 1
check "SIGINT ends a long parse (exit 130)" interrupted INT 130
kill "$AM_PID"; wait "$AM_PID" 2>/dev/null; AM_PID=
finish
