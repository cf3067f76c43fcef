#!/bin/sh
# test-group: vm-managers
# test_am: one marie-am supervising test components: dependency order, respawn after kill -9,
# restart of a hung component, give-up, stop/start by group, logs, refused orders (unsigned,
# forged, replayed, stale, far-future, floods), bad keys and system files, and a restarted
# manager bringing its components back and refusing orders captured before.
. tests/lib.sh
# marie-test-comp, named bare by the system files in tests/data/managers
export PATH="$(pwd)/$B/tests/bin:$PATH"
T=$(mktemp -d /tmp/marie-test-am.XXXXXX)
export MARIE_KEY=$T/key MARIE_SEQ_FILE=$T/seq MARIE_TEST_TRACE=$T/trace
M="$BIN/marie"
AM_PID=
cleanup() { [ -n "$AM_PID" ] && kill "$AM_PID" 2>/dev/null; sleep 0.3; rm -rf "$T"; }
trap cleanup EXIT

# marie-am runs from its own directory, which also holds the test component: a bare
# `exec: marie-test-comp` must be found there
mkdir "$T/bin"
cp "$BIN/marie-am" "$BIN/marie" "$B/tests/bin/marie-test-comp" "$T/bin/"
start_am() { "$T/bin/marie-am" --host alpha --state-dir "$T/am" >> "$T/am.log" 2>&1 & AM_PID=$!; }
# field NAME KEY: a component's field from marie --json ps
field() {
    "$M" --json ps --window 0.7 2>/dev/null | python3 -c '
import json, sys
d = json.load(sys.stdin)
for h in d["hosts"]:
    for c in h["components"]:
        if c["name"] == sys.argv[1]:
            print(c[sys.argv[2]])' "$1" "$2"
}
is_state() { [ "$(field "$1" state)" = "$2" ]; }
pid_changed() { p=$(field "$1" pid); [ -n "$p" ] && [ "$p" != 0 ] && [ "$p" != "$2" ] && is_state "$1" running; }
trace_line() { grep -n " $1 $2 " "$T/trace" | head -1 | cut -d: -f1; }
now_us() { date +%s%6N; }
refused_count() { "$M" --json ps --window 0.7 | python3 -c 'import json, sys; print(json.load(sys.stdin)["hosts"][0]["orders_refused"])'; }
last_line() { grep -n " $1 $2 " "$T/trace" | tail -1 | cut -d: -f1; }

"$M" keygen "$T/key"
start_am
sleep 0.3

# -- bad system files are refused before anything starts
bad_refused() {
    out=$("$M" up tests/data/managers/bad.yaml 2>&1); rc=$?
    echo "$out"
    [ $rc -eq 2 ] && echo "$out" | grep -q 'bad.yaml:7:[0-9]*: .*sometimes' &&
        echo "$out" | grep -q 'bad.yaml:10:[0-9]*: .*nowhere' && [ ! -s "$T/trace" ]
}
check "bad system file refused with file:line:col" bad_refused
cycle_refused() {
    out=$("$M" up tests/data/managers/cycle.yaml 2>&1); rc=$?
    echo "$out"; [ $rc -eq 2 ] && echo "$out" | grep -q 'cycle.yaml:[0-9]*:[0-9]*: .*dependency cycle'
}
check "dependency cycle refused" cycle_refused
am_bad_refused() {
    "$BIN/marie-am" --host alpha --state-dir "$T/am2" --system tests/data/managers/bad.yaml > "$T/am2.log" 2>&1
    rc=$?; cat "$T/am2.log"; [ $rc -eq 2 ] && grep -q 'bad.yaml:7:' "$T/am2.log" && [ ! -s "$T/trace" ]
}
check "marie-am refuses a bad --system file" am_bad_refused
# -- a key is never overwritten, and the refusal says why (the errno of the failed open)
keygen_keeps_key() {
    before=$(cat "$T/key")
    out=$("$M" keygen "$T/key" 2>&1); rc=$?
    echo "$out"
    [ $rc -eq 1 ] && echo "$out" | grep -q "key: File exists" && [ "$(cat "$T/key")" = "$before" ]
}
check "keygen refuses an existing key, saying why" keygen_keeps_key
# a key given but unusable: exit 2 at once with the reason, never a manager refusing everything
bad_key() {   # bad_key FILE WHY [marie-am options]: exit 2 naming the file and the reason
    f=$1; why=$2; shift 2
    timeout 10 "$BIN/marie-am" --host alpha --state-dir "$T/am3" "$@" > "$T/am3.log" 2>&1
    rc=$?; cat "$T/am3.log"; [ $rc -eq 2 ] && grep -q "key file $f.*$why" "$T/am3.log"
}
printf 'not a key\n' > "$T/badkey"; chmod 600 "$T/badkey"
check "marie-am --key FILE missing: exit 2" bad_key "$T/nosuchkey" "No such file" --key "$T/nosuchkey"
check "marie-am --key FILE malformed: exit 2" bad_key "$T/badkey" "expected 64 hex digits" --key "$T/badkey"
check "marie-am --max-skew not a number: exit 2" sh -c "timeout 10 $BIN/marie-am --max-skew nan --state-dir $T/am3 > $T/skew.log 2>&1; rc=\$?; grep -q 'not a number of seconds' $T/skew.log && [ \$rc -eq 2 ]"
bad_env_key() { ( export MARIE_KEY="$T/badkey"; bad_key "$T/badkey" "expected 64 hex digits" ); }
check "marie-am with \$MARIE_KEY malformed: exit 2" bad_env_key

bad_profile() { out=$("$M" up tests/data/managers/single.yaml --profile nosuch 2>&1); [ $? -eq 2 ] && echo "$out" | grep -q "single.yaml:[0-9]*:[0-9]*: no profile 'nosuch'"; }
check "unknown profile refused with file:line:col" bad_profile
hashes() {
    out=$("$M" hash tests/data/managers/single.yaml --profile sim --profile robot); echo "$out"
    echo "$out" | grep -q '^a  *same' && echo "$out" | grep -q '^c  *differs'
}
check "hash: shared components configured the same in sim and robot" hashes

# -- up: dependency order a -> b -> c
check "up returns when everything runs" "$M" up tests/data/managers/single.yaml
dep_order() {
    cat "$T/trace"
    ar=$(trace_line a running); be=$(trace_line b exec); br=$(trace_line b running); ce=$(trace_line c exec)
    [ -n "$ar" ] && [ -n "$be" ] && [ -n "$br" ] && [ -n "$ce" ] && [ "$ar" -lt "$be" ] && [ "$br" -lt "$ce" ]
}
check "components start in dependency order" dep_order
check "ps shows all running" sh -c "$M ps | grep -c ' running ' | grep -qx 3"
recorded() { h=$("$M" hash tests/data/managers/single.yaml | awk '$1 == "b" {print $2}'); grep -q "^b $h " "$T/am/config-hashes" && [ "$(field b config_hash)" = "$h" ]; }
check "manager records each component's configuration hash" recorded

# -- kill -9 gets a component restarted
B_PID=$(field b pid)
kill -9 "$B_PID"
check "kill -9 restarts the component" wait_for 10 pid_changed b "$B_PID"
restart_counted() { [ "$(field b restarts)" -ge 1 ]; }
check "restart counted" restart_counted

# -- a hung component (alive, no heartbeat) is restarted
C_PID=$(field c pid)
kill -USR1 "$C_PID"
check "hung component restarted" wait_for 15 pid_changed c "$C_PID"
check "old hung process is gone" sh -c "! kill -0 $C_PID 2>/dev/null"

# -- output capture
check "logs: last lines of stdout" sh -c "$M logs -n 5 c | grep -q 'out line [0-9]* from c'"
check "logs: stderr captured separately" sh -c "grep -q ' err warning [0-9]* from c' $T/am/logs/c.log"
follow() {
    timeout 2 "$M" logs -f -n 0 c > "$T/follow.out" 2>&1
    grep -q 'out line [0-9]* from c' "$T/follow.out"
}
check "logs -f follows live output" follow

# -- stop/start by group
check "stop a group" "$M" stop base --wait
group_stopped() { [ "$(field a pid)" = 0 ] && [ "$(field b pid)" = 0 ] && [ "$(field c state)" = running ]; }
check "group members stopped, others run on" group_stopped
check "start a group" "$M" start base --wait
check "pause" "$M" pause c
check "paused" wait_for 5 is_state c paused
check "resume" "$M" resume c
check "running again" wait_for 5 is_state c running
check "unknown name refused (exit 1)" sh -c "$M start nosuch; [ \$? -eq 1 ]"

# -- orders that are not authentic never start anything
"$M" stop c --wait > /dev/null
OT="$B/tests/bin/marie-test-order"
check "unsigned order refused, answer lists no hosts" sh -c "$OT -m unsigned start c | grep -qx 'refused: unsigned hosts=0'"
check "forged order refused, answer lists no hosts" sh -c "$OT -m forged start c | grep -qx 'refused: forged hosts=0'"
check "a signed order's answer lists the hosts" sh -c "$OT -k $T/key ping | grep -qx 'ok hosts=1'"
c_stopped() { [ "$(field c pid)" = 0 ]; }
sleep 0.5
check "refused orders started nothing" c_stopped
replay() {
    # the same signed order twice: obeyed once, then refused
    s=$(now_us)
    "$OT" -k "$T/key" -S replayer@test -s "$s" -r 2 stop c > "$T/replay.out"
    cat "$T/replay.out"
    sed -n 1p "$T/replay.out" | grep -q '^ok' && grep -q 'refused: replayed' "$T/replay.out" &&
        "$OT" -k "$T/key" -S replayer@test -s $((s - 1)) start c | grep -q 'refused: replayed'
}
check "replayed order refused" replay
# orders signed long ago, dated 1970 or 2100, or with a huge seq: refused, remembered for nothing
check "order signed 1000 s ago refused" sh -c "$OT -k $T/key -S old@test -A 1000 start c | grep -q 'refused: stale'"
check "order with utime 0 refused" sh -c "$OT -k $T/key -S old@test -u 0 start c | grep -q 'refused: stale'"
check "order dated 2100 refused" sh -c "$OT -k $T/key -S old@test -u 4102444800000000 start c | grep -q 'refused: future'"
check "order with seq INT64_MAX refused" sh -c "$OT -k $T/key -S max@test -s 9223372036854775807 start c | grep -q 'refused: future'"
sleep 0.3
check "refused orders started nothing" c_stopped
check "seq INT64_MAX locks nobody out" sh -c "$OT -k $T/key -S max@test ping | grep -q '^ok'"
check "INT64_MAX never written down" sh -c "! grep -q 9223372036854775807 $T/am/order-seq"
# clocks apart by less than the skew (5 s): accepted either way (behind: once the manager has
# been up longer than the lag, or it could be an order from before its start)
check "order from a clock 3 s ahead accepted" sh -c "$OT -k $T/key -S ahead@test -A -3 ping | grep -q '^ok'"
check "order from a clock 8 s behind accepted" wait_for 15 sh -c "$OT -k $T/key -S behind@test -A 8 ping | grep -q '^ok'"
check "order from a clock 7 s ahead refused" sh -c "$OT -k $T/key -S ahead@test -A -7 ping | grep -q 'refused: future'"
# a flood of unsigned orders: every one counted, few answered or announced
flood() {
    before=$(refused_count)
    out=$("$OT" -m unsigned -F 300 start c); echo "$out"
    set -- $out; replies=$4; events=$6
    # the manager's budget: a burst of 10, then 5 a second (one more second for slack)
    most=$(echo "$8" | awk '{ printf "%d", 10 + 5 * ($1 + 1) }')
    after=$(refused_count); echo "refused $before -> $after, at most $most answers"
    [ "$replies" -ge 1 ] && [ "$replies" -le "$most" ] && [ "$events" -ge 1 ] && [ "$events" -le "$most" ] &&
        [ $((after - before)) -ge 100 ] && [ $((after - before)) -gt $((replies * 4)) ]
}
check "a flood of unsigned orders is counted, answers and events rate-limited" flood
sleep 0.3
check "the flood started nothing" c_stopped
check "signed orders still obeyed after the flood" sh -c "$OT -k $T/key ping | grep -q '^ok'"
check "refusals counted in status" sh -c "$M --json ps | grep -q '\"orders_refused\":[1-9]'"
garbage() {
    "$OT" -m garbage -r 600 x && sleep 0.5 && kill -0 "$AM_PID" && "$M" ps > /dev/null
}
check "malformed messages do not crash the manager" garbage
insecure_key() {
    cp "$T/key" "$T/key644"; chmod 644 "$T/key644"
    "$M" --key "$T/key644" start c; [ $? -eq 4 ]
}
check "group-readable key refused (exit 4)" insecure_key
check "start again" "$M" start c --wait

# -- a manager killed with -9 takes its components down; restarted, it brings them back
CAP=$(now_us)
check "an order to capture obeyed" sh -c "$OT -k $T/key -S cap@test -s $CAP ping | grep -q '^ok'"
A_PID=$(field a pid)
C_PID=$(field c pid)
kill -USR1 "$C_PID"          # c hangs at once: its SIGTERM is never acted on
sleep 0.5
kill -9 "$AM_PID"; wait "$AM_PID" 2>/dev/null
check "components go with their manager" wait_for 5 sh -c "! kill -0 $A_PID 2>/dev/null"
check "a hung component outlives its manager" kill -0 "$C_PID"
rm -f "$T/am/order-seq"     # the replay file is lost too: orders from before stay refused
start_am
back() { [ "$(field a state)" = running ] && [ "$(field c state)" = running ] && [ "$(field a pid)" != "$A_PID" ] && [ "$(field c pid)" != "$C_PID" ]; }
check "restarted manager brings them back" wait_for 15 back
check "restarted manager ended the leftover" wait_for 5 sh -c "! kill -0 $C_PID 2>/dev/null"
captured() { out=$("$OT" -k "$T/key" -S cap@test -s "$CAP" ping); echo "$out"; echo "$out" | grep -q 'refused: replayed\|refused: stale'; }
check "order captured before the manager restarted refused" captured
check "after a restart, seq INT64_MAX still locks nobody out" sh -c "$OT -k $T/key -S max@test ping | grep -q '^ok'"

# -- down, then a crashing component is given up after max_failures
check "down stops everything" "$M" down
# reverse dependency order: c (needs b) ends before b, b (needs a) before a
down_order() {
    ax=$(last_line a exit); bx=$(last_line b exit); cx=$(last_line c exit)
    [ -n "$ax" ] && [ -n "$bx" ] && [ -n "$cx" ] && [ "$cx" -lt "$bx" ] && [ "$bx" -lt "$ax" ]
}
check "down stops in reverse dependency order" down_order
none_left() { for p in $(cut -d" " -f4 "$T/trace" | sort -u); do kill -0 "$p" 2>/dev/null && return 1; done; return 0; }
check "nothing left running" wait_for 5 none_left
# up waits for everything to run: a component that fails before it ever runs makes it exit 1
# (a program that exists, so that the checks before start let it through, and fails at once)
up_fails() {
    printf 'system: broken\nhosts: [alpha]\ncomponents:\n  ghost:\n    exec: /bin/false\n    host: alpha\n    restart: {policy: never}\n' > "$T/broken.yaml"
    "$T/bin/marie" up --wait-timeout 20 "$T/broken.yaml"; rc=$?; echo "exit $rc"
    "$M" down > /dev/null
    [ $rc -eq 1 ]
}
check "up with a component that cannot start: exit 1" up_fails
# marie checks the programs where it is installed: beside marie-am, as on a robot
"$T/bin/marie" up --no-wait tests/data/managers/crash.yaml > /dev/null
check "gives up after max_failures" wait_for 10 is_state crasher failed
check "policy never: failed component stays failed" wait_for 5 is_state once failed
two_restarts() { [ "$(field crasher restarts)" = 2 ]; }
check "restarts before giving up" two_restarts
check "bare exec name found next to marie-am" grep -q " crasher exec " "$T/trace"
check "shell component runs through sh" wait_for 5 sh -c "grep -q 'from the shell: hello sh' $T/am/logs/sh.log"
drops() { [ "$(field chatty log_drops)" -gt 0 ] && grep -q -- '-- [0-9]* lines dropped (rate limit)' "$T/am/logs/chatty.log"*; }
check "output beyond log_rate is dropped and counted" wait_for 10 drops
rotated() { [ -f "$T/am/logs/chatty.log.1" ] && [ ! -f "$T/am/logs/chatty.log.3" ] && [ "$(stat -c %s "$T/am/logs/chatty.log")" -le 8192 ]; }
check "log files rotate at log_max_bytes, log_keep kept" wait_for 15 rotated
check "down again" "$M" down
# everything down: ps --json still lists every component, each stopped (or failed)
all_stopped() {
    "$M" --json ps --window 0.7 | python3 -c '
import json, sys
cs = [c for h in json.load(sys.stdin)["hosts"] for c in h["components"]]
print([(c["name"], c["state"]) for c in cs])
sys.exit(0 if len(cs) >= 3 and all(c["state"] in ("stopped", "failed") for c in cs) else 1)'
}
check "ps --json after down: every component listed, none running" all_stopped

# CPU% and RSS per component against a known load: one spins with 200 MiB touched, one sleeps;
# the spinner's CPU% agrees with what the kernel counted for it over the same seconds
cat > "$T/load.yaml" <<'EOF2'
system: load
hosts: [alpha]
components:
  spinner:
    exec: 'exec python3 -c "import itertools; b = bytearray([1]) * (200 << 20); any(itertools.repeat(0))"'
    shell: true
    host: alpha
    heartbeat_timeout: 0
    stop_timeout: 0.5
  sleeper:
    exec: exec sleep 60
    shell: true
    host: alpha
    heartbeat_timeout: 0
    stop_timeout: 0.5
EOF2
# One window of about 4 s: the kernel's count for the spinner over it and six ps answers in it
# (ps answers at once with the manager's last sample: one 0.5 s status period, which ended up to
# 0.5 s before; the first a second after the kernel's count starts, so that they cover the
# periods it counts). Prints "KERNEL_PCT" and writes ps1..ps6.json.
usage_window() {
    t0=$(date +%s%N); c0=$(awk '{print $14 + $15}' /proc/$sp/stat)
    sleep 1
    for i in 1 2 3 4 5 6; do "$M" --json ps --window 1.1 > "$T/ps$i.json"; sleep 0.5; done
    t1=$(date +%s%N); c1=$(awk '{print $14 + $15}' /proc/$sp/stat)
    echo "$t0 $t1 $c0 $c1" > "$T/window"
}
usage() {
    "$M" up "$T/load.yaml" > /dev/null || return 1
    sp=$(field spinner pid)
    wait_for 20 sh -c "[ \$(awk '{print \$24}' /proc/$sp/stat) -gt 50000 ]"    # 200 MiB touched (pages)
    sleep 2
    # What is checked is ps against the kernel's count for the same seconds, and a busy
    # component told from an idle one. A window in which the kernel gave the spinner under 25 %
    # of a CPU (other work held the cores: once 0.5 %) shows neither: its share then moves from
    # one half second to the next, and ps's periods, which start up to 0.5 s before the
    # kernel's count, do not average it out (once ps 5.0 % against the kernel's 14.6 %). It is
    # measured again, up to five windows; the check is made on the last one.
    for w in 1 2 3 4 5; do
        usage_window
        set -- $(cat "$T/window")
        [ $(( ($4 - $3) * 100 * 1000000000 / $(getconf CLK_TCK) / ($2 - $1) )) -ge 25 ] && break
        echo "window $w: the spinner had under 25 % of a CPU; measuring again"
    done
    set -- $(cat "$T/window")
    python3 - "$T" "$1" "$2" "$3" "$4" "$(getconf CLK_TCK)" <<'PY'
import json, sys
T, t0, t1, c0, c1, hz = sys.argv[1], *map(int, sys.argv[2:])
kernel = 100.0 * (c1 - c0) / hz / ((t1 - t0) / 1e9)
rows = []
for i in range(1, 7):
    cs = {c["name"]: c for h in json.load(open("%s/ps%d.json" % (T, i)))["hosts"] for c in h["components"]}
    rows.append(cs)
cpu = sum(r["spinner"]["cpu"] for r in rows) / len(rows)
idle = max(r["sleeper"]["cpu"] for r in rows)
rss, idle_rss = rows[-1]["spinner"]["rss"] / 2**20, rows[-1]["sleeper"]["rss"] / 2**20
print("spinner: ps %.1f%% CPU, kernel %.1f%%; RSS %.0f MiB; sleeper %.1f%% CPU, RSS %.1f MiB" % (cpu, kernel, rss, idle, idle_rss))
ok = (kernel * 0.7 - 5 <= cpu <= kernel * 1.3 + 5 and cpu > idle + 2 and idle < 2
      and 200 <= rss <= 320 and 0 < idle_rss < 20)
sys.exit(0 if ok else 1)
PY
    rc=$?
    "$M" down > /dev/null
    return $rc
}
check "ps: CPU% and RSS of a known load (spinner, 200 MiB) and of an idle component" usage
dispatch() {
    mkdir -p "$T/path"
    printf '#!/bin/sh\necho "hello $*"\n' > "$T/path/marie-hello"; chmod +x "$T/path/marie-hello"
    [ "$(PATH="$T/path:$PATH" "$M" hello a b)" = "hello a b" ]
}
check "marie X runs marie-X" dispatch
check "unknown command: exit 2" sh -c "$M nosuchcommand 2>/dev/null; [ \$? -eq 2 ]"
kill "$AM_PID"; wait "$AM_PID"
check "SIGTERM: manager exits cleanly" [ $? -eq 0 ]
AM_PID=
tail -30 "$T/am.log"
finish
