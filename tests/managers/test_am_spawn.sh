#!/bin/sh
# test-light
# test_am_spawn: what a component gets from marie-am when it starts (its own session and process
# group, stdin /dev/null, output pipes, default signal handling with nothing blocked, its argv and
# environment, none of the manager's close-on-exec descriptors), and a program gone by the time
# it is respawned: the exec error in its log, exit status 127, given up after max_failures.
. tests/lib.sh
T=$(mktemp -d /tmp/marie-test-am-spawn.XXXXXX)
export MARIE_KEY=$T/key MARIE_SEQ_FILE=$T/seq
M="$BIN/marie"
AM_PID=
cleanup() { [ -n "$AM_PID" ] && kill "$AM_PID" 2>/dev/null; sleep 0.3; rm -rf "$T"; }
trap cleanup EXIT

mkdir "$T/bin" "$T/bin2"
cp "$BIN/marie-am" "$T/bin/"
cp "$B/tests/bin/marie-test-comp" "$T/bin2/marie-vanish"
"$M" keygen "$T/key" > /dev/null
# LISTEN_FDS is service plumbing (not passed on); MARIE_TEST_INHERITED is the manager's own
# environment (passed on)
LISTEN_FDS=1 MARIE_TEST_INHERITED=kept "$T/bin/marie-am" --host alpha --state-dir "$T/am" >> "$T/am.log" 2>&1 &
AM_PID=$!
sleep 0.3

# probe: a plain program, looked at from outside while it runs; vanish: a component whose
# program will be removed. vanish comes first, so that its pipes exist when probe starts.
cat > "$T/spawn.yaml" <<EOF
system: spawn
hosts: [alpha]
components:
  vanish:
    exec: $T/bin2/marie-vanish
    host: alpha
    heartbeat_timeout: 2.5
    stop_timeout: 0.5
    restart: {policy: always, backoff_min: 0.05, backoff_max: 0.1, stable_after: 0, max_failures: 3, window: 60}
  probe:
    exec: /bin/sleep
    args: ["60"]
    host: alpha
    heartbeat_timeout: 0
    stop_timeout: 0.5
    env: {PROBE_VAR: hello}
EOF
setup "up" "$M" up --wait-timeout 20 "$T/spawn.yaml"
P=$(ps_field probe pid)
setup "probe running" test -e "/proc/$P/stat"

own_group() {
    set -- $(cut -d')' -f2 "/proc/$P/stat")    # state ppid pgrp session ...
    echo "pid $P parent $2 pgrp $3 session $4 (manager $AM_PID)"
    [ "$2" = "$AM_PID" ] && [ "$3" = "$P" ] && [ "$4" = "$P" ]
}
check "a child of the manager, in its own session and process group" own_group
check "stdin is /dev/null" sh -c "[ \"\$(readlink /proc/$P/fd/0)\" = /dev/null ]"
check "stdout and stderr are pipes" sh -c "readlink /proc/$P/fd/1 | grep -q ^pipe: && readlink /proc/$P/fd/2 | grep -q ^pipe:"
check "no signal blocked" grep -q '^SigBlk:[[:space:]]*0*$' "/proc/$P/status"
# Signals 32 and 33 are glibc's own: its posix_spawn (make's, for one) starts programs with
# them ignored, and glibc refuses to change them; a component may inherit that, nothing else.
not_ignored() {
    ign=$(sed -n 's/^SigIgn:[[:space:]]*//p' "/proc/$P/status")
    echo "SigIgn $ign"
    [ $((0x$ign & ~0x180000000)) -eq 0 ]
}
check "no signal ignored (the manager ignores SIGPIPE)" not_ignored
# Beyond 0, 1 and 2: none of what the manager opened close-on-exec (its log files, its signalfd,
# the other component's pipes). What it inherited, and liblcm's sockets and pipes (opened without
# close-on-exec), are passed on as they always were.
cloexec_fds() {
    for f in /proc/$AM_PID/fdinfo/*; do
        n=${f##*/}
        fl=$(awk '/^flags:/ { print $2 }' "$f")
        [ "$n" -gt 2 ] && [ $((fl & 02000000)) -ne 0 ] && readlink "/proc/$AM_PID/fd/$n"
    done
}
no_manager_fds() {
    ls -l "/proc/$P/fd" | sed 's/.* \([0-9]* -> \)/\1/'
    cloexec_fds > "$T/cloexec"
    echo "close-on-exec in the manager:"; cat "$T/cloexec"
    [ -s "$T/cloexec" ] || return 1
    for f in /proc/$P/fd/*; do
        t=$(readlink "$f")
        # /dev/null is everyone's: the manager's own (kept for stdin) looks like any other
        [ "${f##*/}" -le 2 ] || [ "$t" = /dev/null ] && continue
        grep -qxF "$t" "$T/cloexec" && return 1
    done
    return 0
}
check "none of the manager's close-on-exec descriptors" no_manager_fds
tr '\0' '\n' < "/proc/$P/environ" > "$T/env"
env_has() { grep -qx "$1" "$T/env"; }
check "MARIE_NAME" env_has "MARIE_NAME=probe"
check "MARIE_HOST" env_has "MARIE_HOST=alpha"
check "MARIE_SYSTEM" env_has "MARIE_SYSTEM=$(realpath "$T/spawn.yaml")"
check "MARIE_STATE_DIR" env_has "MARIE_STATE_DIR=$T/am"
check "MARIE_RUN_DIR" env_has "MARIE_RUN_DIR=$T/am/run"
check "MARIE_KEY" env_has "MARIE_KEY=$T/key"
check "the component's env" env_has "PROBE_VAR=hello"
check "the manager's environment passed on" env_has "MARIE_TEST_INHERITED=kept"
check "service plumbing not passed on" sh -c "! grep -q '^LISTEN_FDS=' $T/env"
check "PATH starts with the manager's directory" grep -q "^PATH=$T/bin:" "$T/env"
check "argv as configured" sh -c "[ \"\$(tr '\\0' ' ' < /proc/$P/cmdline)\" = '/bin/sleep 60 ' ]"

# the program is removed while it runs; its respawns cannot exec it
state_is() { [ "$(ps_field "$1" state)" = "$2" ]; }
pid=$(ps_field vanish pid)
rm "$T/bin2/marie-vanish"
kill -9 "$pid"
check "a program gone: given up after max_failures" wait_for 15 state_is vanish failed
check "exit status 127" sh -c "[ \"\$(M=$M; . tests/lib.sh; ps_field vanish last_exit)\" = 127 ]"
check "the exec error in the component's log" \
    grep -q " err marie-am: exec $T/bin2/marie-vanish: No such file or directory$" "$T/am/logs/vanish.log"
check "the manager still answers" "$M" ps
check "the probe runs on, same process" sh -c "[ \"\$(M=$M; . tests/lib.sh; ps_field probe pid)\" = $P ]"

check "down" "$M" down
kill "$AM_PID"; wait "$AM_PID"
check "SIGTERM: manager exits cleanly" [ $? -eq 0 ]
AM_PID=
tail -20 "$T/am.log"
finish
