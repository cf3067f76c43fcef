# tests/lib.sh: helpers for shell tests; results use cmocka's line format so the runner counts them.
#   . tests/lib.sh; check "name" command args...; ...; finish
B=${B:-build}
BIN=$B/bin
_ok=0; _bad=0
check() {
    _name=$1; shift
    echo "[ RUN      ] $_name"
    if "$@"; then echo "[       OK ] $_name"; _ok=$((_ok + 1))
    else echo "[  FAILED  ] $_name"; _bad=$((_bad + 1)); fi
}
# Wait up to $1 seconds for a command to succeed.
wait_for() {
    _t=$1; shift
    _end=$(( $(date +%s) + _t ))
    while ! "$@" 2>/dev/null; do
        [ "$(date +%s)" -ge "$_end" ] && return 1
        sleep 0.1
    done
}
finish() {
    echo "[  PASSED  ] $_ok test(s)."
    [ "$_bad" -eq 0 ] || { echo "[  FAILED  ] $_bad test(s)."; exit 1; }
    exit 0
}
