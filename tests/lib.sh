# tests/lib.sh: helpers for shell tests; results use cmocka's line format so the runner counts them.
#   . tests/lib.sh; check "name" command args...; ...; finish
# A case that truly cannot run here says so: `skip "name" "reason"` prints
# "[  SKIPPED ] name: reason", which scripts/run-tests.sh counts as skipped (a program that
# runs no case and skips none is a failure there, so never just exit 0).
B=${B:-build}
BIN=$B/bin
_ok=0; _bad=0
check() {
    _name=$1; shift
    echo "[ RUN      ] $_name"
    if "$@"; then echo "[       OK ] $_name"; _ok=$((_ok + 1))
    else echo "[  FAILED  ] $_name"; _bad=$((_bad + 1)); fi
}
skip() {
    echo "[  SKIPPED ] $1: $2"
}
# A step the cases need but that proves nothing by itself (start a server, a browser): not a
# case; when it fails the program stops with one failure naming it.
setup() {
    _name=$1; shift
    "$@" && return 0
    echo "[  FAILED  ] setup: $_name"
    _bad=$((_bad + 1))
    finish
}
# json FILE KEY: a top-level value of a JSON file; le A B / lt A B: A <= B / A < B as numbers.
json() { python3 -c "import json,sys; print(json.load(open(sys.argv[1]))[sys.argv[2]])" "$1" "$2"; }
le() { python3 -c "import sys; sys.exit(0 if float(sys.argv[1]) <= float(sys.argv[2]) else 1)" "$1" "$2"; }
lt() { python3 -c "import sys; sys.exit(0 if float(sys.argv[1]) < float(sys.argv[2]) else 1)" "$1" "$2"; }
# Wait up to $1 seconds for a command to succeed.
wait_for() {
    _t=$1; shift
    _end=$(( $(date +%s) + _t ))
    while ! "$@" 2>/dev/null; do
        [ "$(date +%s)" -ge "$_end" ] && return 1
        sleep 0.1
    done
}
# start NAME CMD...: run CMD in the background, output to $OUT/NAME.log, its pid in $pid_NAME.
# stop_started kills everything started so (call it from the test's exit trap).
pids=""
start() {
    _n=$1; shift
    "$@" > "$OUT/$_n.log" 2>&1 &
    pids="$pids $!"
    eval "pid_$_n=$!"
}
stop_started() {
    for _p in $pids; do kill "$_p" 2>/dev/null; done
    for _p in $pids; do wait "$_p" 2>/dev/null; done
}
# ps_field NAME KEY: a component's field from `marie --json ps` ($M, else $BIN/marie).
ps_field() {
    "${M:-$BIN/marie}" --json ps --window 0.7 2>/dev/null | python3 -c '
import json, sys
d = json.load(sys.stdin)
for h in d["hosts"]:
    for c in h["components"]:
        if c["name"] == sys.argv[1]:
            print(c[sys.argv[2]])' "$1" "$2"
}
finish() {
    echo "[  PASSED  ] $_ok test(s)."
    [ "$_bad" -eq 0 ] || { echo "[  FAILED  ] $_bad test(s)."; exit 1; }
    exit 0
}
