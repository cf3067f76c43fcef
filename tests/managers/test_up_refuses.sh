#!/bin/sh
# test-light
# test_up_refuses: values that used to pass `marie up` and then crash-loop their components are
# refused before anything starts, each with exit status 2 and its file:line:col: durations that
# overflow or cannot be met, ${VARIABLES} set nowhere, args as one string, bad bus URLs, one
# channel carrying two types (two outputs, or an input of another type), a channel LCM cannot
# send, names with terminal escapes or a right-to-left override, hosts twice or none, a profile
# that extends itself. marie-am refuses them the same way, and a variable only the manager lacks
# makes `marie up` exit 2 with the manager's file:line:col.
. tests/lib.sh
T=$(mktemp -d /tmp/marie-test-refuses.XXXXXX)
export MARIE_KEY=$T/key MARIE_SEQ_FILE=$T/seq XDG_CACHE_HOME=$T/cache MARIE_TEST_TRACE=$T/trace
M="$BIN/marie"
AM_PID=
cleanup() { [ -n "$AM_PID" ] && kill "$AM_PID" 2>/dev/null; wait 2>/dev/null; rm -rf "$T"; }
trap cleanup EXIT
"$M" keygen "$T/key" > /dev/null
: > "$T/trace"
TC=$B/tests/bin/marie-test-comp
HEAD="system: refuses
hosts: [alpha]
components:"
# case_refused NAME LINE PATTERN: marie up refuses $T/NAME.yaml: exit 2, and PATTERN at
# NAME.yaml:LINE:COL (the output shown with cat -v: an escape in it is not obeyed here).
case_refused() {
    f=$T/$1.yaml
    out=$(timeout 20 "$M" up --no-wait "$f" 2>&1); rc=$?
    echo "$out" | cat -v; echo "exit $rc"
    [ $rc -eq 2 ] && echo "$out" | grep -q "^$f:$2:[0-9]*: $3"
}
# one NAME: $T/NAME.yaml is the head above and the components given on stdin
one() { printf '%s\n' "$HEAD" > "$T/$1.yaml"; cat >> "$T/$1.yaml"; }

one hb_huge <<EOF
  a: {exec: $TC, heartbeat_timeout: 1e300}
EOF
check "heartbeat_timeout: 1e300 (overflowed: not_responding after 0.04 s)" \
    case_refused hb_huge 4 "heartbeat_timeout: 0 (no heartbeat) or 0.15 to 86400 s, not 1e+300"
one hb_tiny <<EOF
  a: {exec: $TC, heartbeat_timeout: 1e-6}
EOF
check "heartbeat_timeout: 1e-6" case_refused hb_tiny 4 "heartbeat_timeout: 0 (no heartbeat) or 0.15 to 86400 s"
one stop_huge <<EOF
  a: {exec: $TC, stop_timeout: 1e300, restart: {policy: always, window: 1e300}}
EOF
both() {
    out=$("$M" up --no-wait "$T/stop_huge.yaml" 2>&1); rc=$?; echo "$out"
    [ $rc -eq 2 ] && echo "$out" | grep -q 'stop_timeout: 0 to 86400 s' && echo "$out" | grep -q 'window: 0 to 86400 s'
}
check "stop_timeout and restart settings too" both
one unset <<EOF
  p:
    exec: marie-example-producer
    params: {label: "\${MARIE_TEST_NO_SUCH_VARIABLE}/x", rate_hz: 1}
EOF
check "\${UNSET} in a parameter (before: reported only by the component, at run time)" \
    case_refused unset 6 "label: environment variable MARIE_TEST_NO_SUCH_VARIABLE is not set"
one unset_ok <<EOF
  p:
    exec: marie-example-producer
    env: {MARIE_TEST_GIVEN: here}
    params: {label: "\${MARIE_TEST_GIVEN}/\${MARIE_RUN_DIR}/\${MARIE_TEST_NO_SUCH_VARIABLE:-default}", rate_hz: 1}
EOF
given() {
    out=$(timeout 20 "$M" up --no-wait "$T/unset_ok.yaml" 2>&1); echo "$out"
    ! echo "$out" | grep -q "unset_ok.yaml:[0-9]*:[0-9]*:"
}
check "variables from env:, from the manager (MARIE_RUN_DIR) or with a default pass" given
one args_string <<EOF
  p: {exec: marie-example-producer, args: "--param rate_hz=5"}
EOF
check "args as one string" case_refused args_string 4 "args: a list, one argument an item"
url() { printf 'lcm_url: "%s"\n%s\n  a: {exec: %s}\n' "$2" "$HEAD" "$TC" > "$T/$1.yaml"; }
url url_port "udpm://239.255.76.67:99999?ttl=1"
check "a bad lcm_url: port 99999" case_refused url_port 1 "lcm_url 'udpm://239.255.76.67:99999?ttl=1': the port is 1 to 65535"
url url_group "udpm://10.1.2.3:7667?ttl=1"
check "a bad lcm_url: not a multicast group" case_refused url_group 1 "lcm_url .*: the group must be an IPv4 multicast address"
url url_opt "udpm://239.255.76.67:7667?tll=1"
check "a bad lcm_url: an unknown option" case_refused url_opt 1 "lcm_url .*: unknown option"
url url_provider "udp://239.255.76.67:7667"
check "a bad lcm_url: no such provider" case_refused url_provider 1 "lcm_url .*: no such LCM provider"
one two_outputs <<EOF
  p: {exec: marie-example-producer}
  o:
    exec: marie-odometry
    ports: {odom: EXAMPLE}
EOF
check "two outputs of different types on one channel" case_refused two_outputs 7 \
    "channel 'EXAMPLE': port 'odom' of 'o' publishes marie.odometry_t, but port 'out' of 'p' (line 4) publishes marie.counter_t"
one wrong_input <<EOF
  p: {exec: marie-example-producer}
  c:
    exec: marie-example-consumer
    ports: {notes: EXAMPLE}
EOF
check "an input bound to a channel of another type" case_refused wrong_input 7 \
    "channel 'EXAMPLE': port 'notes' of 'c' reads marie.event_t, but port 'out' of 'p' (line 4) publishes marie.counter_t"
long=$(python3 -c 'print("L" * 309)')
one long_channel <<EOF
  p: {exec: marie-example-producer, ports: {out: $long}}
EOF
check "a 309-character channel (LCM sends 63 at most)" \
    case_refused long_channel 4 "port 'out': channel 'L*\.\.\.' (309 bytes): 1 to 63 bytes"
printf '%s\n  "red\\e[31m\\e]0;owned\\a": {exec: %s}\n' "$HEAD" "$TC" > "$T/escape.yaml"
check "terminal escapes in a component name (shown, not obeyed)" \
    case_refused escape 4 "component 'red.x1b\[31m.x1b\]0;owned.x07': letters, digits"
printf '%s\n  "invoice\\u202Etxt.exe": {exec: %s}\n' "$HEAD" "$TC" > "$T/bidi.yaml"
check "a right-to-left override (U+202E) in a component name" \
    case_refused bidi 4 "component 'invoice.xe2.x80.xaetxt.exe': letters, digits"
printf 'system: refuses\nhosts: [alpha, beta, alpha]\ncomponents:\n  a: {exec: %s, host: alpha}\n' "$TC" > "$T/dup_host.yaml"
check "a host listed twice" case_refused dup_host 2 "hosts: 'alpha' twice (also at line 2)"
printf 'system: refuses\nhosts: []\ncomponents:\n  a: {exec: %s}\n' "$TC" > "$T/no_hosts.yaml"
check "hosts: []" case_refused no_hosts 2 "hosts: empty"
one self_profile <<EOF
  a: {exec: $TC}
profiles:
  sim: {extends: sim, clock: sim}
EOF
check "a profile extending itself (even when not applied)" case_refused self_profile 6 "extends: profile 'sim' extends itself"

# marie-am refuses the same files, and nothing starts
am_refuses() {
    timeout 20 "$BIN/marie-am" --host alpha --state-dir "$T/am-$1" --system "$T/$1.yaml" > "$T/am-$1.out" 2>&1; rc=$?
    cat "$T/am-$1.out"; echo "exit $rc"
    [ $rc -eq 2 ] && grep -q "$T/$1.yaml:[0-9]*:[0-9]*: $2" "$T/am-$1.out"
}
check "marie-am --system refuses heartbeat_timeout: 1e300 (exit 2)" am_refuses hb_huge "heartbeat_timeout"
check "marie-am --system refuses an unset variable (exit 2)" am_refuses unset "label: environment variable"
check "nothing was started" sh -c "! grep -v '^[0-9]* ? ' '$T/trace'"

# A variable `marie up` has but the manager lacks: the manager refuses the file at the up order,
# and marie up exits 2 with its file:line:col.
env -u MARIE_TEST_ONLY_HERE "$BIN/marie-am" --host alpha --state-dir "$T/am" > "$T/am.log" 2>&1 &
AM_PID=$!
wait_for 15 "$M" ps --window 0.5 > /dev/null
one only_here <<EOF
  p:
    exec: marie-example-producer
    host: alpha
    params: {label: "\${MARIE_TEST_ONLY_HERE}", rate_hz: 1}
EOF
manager_refuses() {
    out=$(MARIE_TEST_ONLY_HERE=1 timeout 20 "$M" up --no-wait "$T/only_here.yaml" 2>&1); rc=$?
    echo "$out"; echo "exit $rc"
    [ $rc -eq 2 ] && echo "$out" | grep -q "alpha: system file refused:" &&
        echo "$out" | grep -q "only_here.yaml:7:[0-9]*: label: environment variable MARIE_TEST_ONLY_HERE is not set"
}
check "a variable only the manager lacks: refused by the manager, marie up exits 2" manager_refuses
none_running() { out=$("$M" ps --window 0.5 2>&1); echo "$out"; ! echo "$out" | grep -q " p "; }
check "and nothing runs" none_running
finish
