#!/bin/sh
# test-light
# test_ps: marie ps asks the managers for their status and each answers at once: with managers
# that report only every 10 s, ps still shows every host and component within its window; a
# flood of requests is answered within the managers' rate limit; a silent host is shown lost
# after the whole window; a manager that does not answer requests (an older one) still appears
# through its periodic status; managers without a system are all listed.
. tests/lib.sh
T=$(mktemp -d /tmp/marie-test-ps.XXXXXX)
export MARIE_KEY=$T/key MARIE_SEQ_FILE=$T/seq
M="$BIN/marie"
ST="$B/tests/bin/marie-test-status"
AMS=
OLD=
cleanup() {
    for p in $AMS; do kill -CONT "$p" 2>/dev/null; kill "$p" 2>/dev/null; done
    [ -n "$OLD" ] && kill "$OLD" 2>/dev/null
    sleep 1
    rm -rf "$T"
}
trap cleanup EXIT
ms_now() { date +%s%3N; }

# start_am HOST OPTIONS...: a manager reporting every 10 s (its pid in $T/HOST.pid)
start_am() {
    h=$1; shift
    "$BIN/marie-am" --host "$h" --state-dir "$T/state-$h" --status-hz 0.1 "$@" >> "$T/$h.log" 2>&1 &
    echo $! > "$T/$h.pid"
    AMS="$AMS $!"
}
# system FILE HOSTS...: one test component per host, c1 on the first host and so on
system() {
    f=$1; shift
    { echo "system: ps"; echo "hosts: [$(echo "$@" | sed 's/ /, /g')]"; echo "components:"
      i=1
      for h in "$@"; do
          case $h in old*) continue ;; esac
          printf '  c%d:\n    exec: %s/tests/bin/marie-test-comp\n    host: %s\n    heartbeat_timeout: 2.5\n    stop_timeout: 1\n' \
              "$i" "$(pwd)/$B" "$h"
          i=$((i + 1))
      done; } > "$f"
}
# ps_json FILE [OPTIONS]: marie --json ps into FILE; its exit status
ps_json() { f=$1; shift; "$M" --json ps "$@" > "$f" 2> "$f.err"; }
# shows FILE HOST:COMPONENT:STATE... : the table has exactly these hosts (a host with no
# component: HOST:-:-, a lost one HOST:lost), each with these components in these states
shows() {
    f=$1; shift
    python3 - "$f" "$@" << 'EOF'
import json, sys
d = json.load(open(sys.argv[1]))
got = set()
for h in d["hosts"]:
    if h["lost"]:
        got.add(h["host"] + ":lost")
    elif not h["components"]:
        got.add(h["host"] + ":-:-")
    for c in h["components"]:
        got.add("%s:%s:%s" % (h["host"], c["name"], c["state"]))
want = set(sys.argv[2:])
print("table:", sorted(got))
sys.exit(0 if got == want else 1)
EOF
}

"$M" keygen "$T/key" > /dev/null
for h in h1 h2 h3; do start_am "$h"; done
sleep 0.5

# -- before any system: each manager names no host but itself; ps lists all that answered
no_system() {
    ps_json "$T/ps0.json"; rc=$?; cat "$T/ps0.json.err"
    [ $rc -eq 0 ] && shows "$T/ps0.json" h1:-:- h2:-:- h3:-:-
}
check "managers without a system: ps lists every one" no_system

system "$T/s1.yaml" h1 h2 h3
setup "marie up on three hosts" "$M" up "$T/s1.yaml"
sleep 1     # the statuses that follow the start are over; the next periodic ones are 10 s away

# -- ps does not wait for the periodic status: three in a row, each complete within its 1.2 s
# window, while every manager reports only every 10 s (none of them could come from that)
quick() {
    t0=$(ms_now)
    for k in 1 2 3; do
        ps_json "$T/ps$k.json"; rc=$?; cat "$T/ps$k.json.err"
        [ $rc -eq 0 ] && shows "$T/ps$k.json" h1:c1:running h2:c2:running h3:c3:running || return 1
    done
    el=$(($(ms_now) - t0)); echo "three ps in $el ms"
    [ "$el" -lt 10000 ]
}
check "ps gets every host at once though managers report every 10 s" quick

# -- a flood of requests: every manager answers a burst of 10, then 5 a second
sleep 2.5   # a full budget again
flood() {
    out=$("$ST" flood 300 h1); echo "$out"
    set -- $out; [ "$1" = sent ] || return 1
    n=$4
    # the burst, 5 a second for the flood and the listening after it (plus one second of
    # slack), and the 10 s periodic status
    most=$(echo "$6" | awk '{ printf "%d", 10 + 5 * ($1 + 1) + 2 }')
    echo "h1 published $n statuses during 300 requests (at most $most allowed)"
    [ "$n" -ge 10 ] && [ "$n" -le "$most" ] && grep -q 'status requests beyond 5 a second' "$T/h1.log"
}
check "a flood of status requests is answered within the rate limit" flood
all_three() { ps_json "$T/psf.json" && shows "$T/psf.json" h1:c1:running h2:c2:running h3:c3:running; }
check "after the flood, ps is answered again" wait_for 10 all_three

# -- a silent manager: shown lost, after the whole window
AM3=$(cat "$T/h3.pid")
kill -STOP "$AM3"
silent() {
    t0=$(ms_now)
    ps_json "$T/psl.json" --window 1.5; rc=$?
    el=$(($(ms_now) - t0)); cat "$T/psl.json.err"; echo "exit $rc after $el ms"
    [ $rc -eq 3 ] && shows "$T/psl.json" h1:c1:running h2:c2:running h3:lost && [ "$el" -ge 1500 ]
}
check "a silent manager's host is lost after the whole window (exit 3)" silent
kill -CONT "$AM3"
check "the manager back: ps complete again" wait_for 10 all_three
setup "marie down" "$M" down

# -- an older manager that only reports every 0.5 s and never answers a request: ps waits for
# its periodic status, since the other managers' system names its host
for h in h1 h2 h3; do kill "$(cat "$T/$h.pid")"; done
for h in h1 h2 h3; do while kill -0 "$(cat "$T/$h.pid")" 2>/dev/null; do sleep 0.1; done; done
AMS=
system "$T/s2.yaml" h1 h2 old1
start_am h1 --system "$T/s2.yaml"
start_am h2 --system "$T/s2.yaml"
"$ST" old old1 60 h1 h2 old1 &
OLD=$!
both_running() { ps_json "$T/pso.json"; shows "$T/pso.json" h1:c1:running h2:c2:running old1:legacy:running; }
setup "components of the new managers running" wait_for 15 both_running
old_shown() {
    for k in 1 2 3; do
        ps_json "$T/pso$k.json"; rc=$?; cat "$T/pso$k.json.err"
        [ $rc -eq 0 ] && shows "$T/pso$k.json" h1:c1:running h2:c2:running old1:legacy:running || return 1
    done
}
check "a manager that does not answer requests appears by its periodic status" old_shown
"$M" down > /dev/null 2>&1
finish
