#!/bin/sh
# test-keep-user
# test_sched: a component's `sched:` as the kernel applies it. Components of one manager get the
# policy, priority and CPUs asked for (read back from /proc: what the kernel does, not what
# marie-am says), a shell component's own child too, and the manager keeps its own; a manager
# without the right (no CAP_SYS_NICE, RLIMIT_RTPRIO 0: root in a default container, or a user)
# and CPUs that do not exist give a warning naming the component and the reason, and the
# component runs; a bad policy name is refused with file:line:col before anything starts. The
# managers run with --rt-priority 10: alpha at SCHED_FIFO 10 while what it starts keeps the
# scheduling its entry asks for (the normal policy without one; one with a short heartbeat_timeout
# starts at 9 and is back at the normal policy once it beats, or 100 ms after its start if it
# computes before it beats: it must not hold a CPU from the rest of the host meanwhile), beta
# refused with a warning. A component flooding its output does not keep alpha busy.
. tests/lib.sh
T=$(mktemp -d /tmp/marie-test-sched.XXXXXX)
export MARIE_KEY=$T/key MARIE_SEQ_FILE=$T/seq MARIE_TEST_TRACE=$T/trace
OUT=$T
M="$BIN/marie"
cleanup() {
    "$M" down > /dev/null 2>&1
    stop_started
    rm -rf "$T"
}
trap cleanup EXIT INT TERM

# The highest CPU this test may use: the one the pinned components are asked to run on.
LAST=$(python3 -c 'import os; print(max(os.sched_getaffinity(0)))')
COMP=$(pwd)/$B/tests/bin/marie-test-comp
cat > "$T/sched.yaml" <<EOF
system: sched
hosts: [alpha, beta]
defaults:
  restart: {policy: never}
components:
  fifo:
    exec: $COMP
    host: alpha
    sched: {policy: fifo, priority: 40, cpus: [$LAST]}
  rr:
    exec: $COMP
    host: alpha
    sched: {policy: rr, priority: 7}
  plain:
    exec: $COMP
    host: alpha
  shell:
    exec: 'sleep 300; :'
    shell: true
    heartbeat_timeout: 0
    host: alpha
    sched: {policy: fifo, priority: 41}
  nocpu:
    exec: $COMP
    host: alpha
    sched: {cpus: [1000]}
  quick:
    exec: $COMP
    host: alpha
    heartbeat_timeout: 0.5
    env: {MARIE_TEST_START_CHILD: 1}
  slow:
    exec: $COMP
    host: alpha
    heartbeat_timeout: 3.9
    env: {MARIE_TEST_START_BUSY_MS: 2000}
  denied:
    exec: $COMP
    host: beta
    sched: {policy: fifo, priority: 40}
EOF
"$M" keygen "$T/key" > /dev/null
start am "$BIN/marie-am" --host alpha --state-dir "$T/alpha" --rt-priority 10
# beta lacks the right: no CAP_SYS_NICE, and a real-time priority limit of 0
start beta prlimit --rtprio=0:0 setpriv --inh-caps=-sys_nice --bounding-set=-sys_nice \
    "$BIN/marie-am" --host beta --state-dir "$T/beta" --rt-priority 10
# both managers on the bus (a loaded machine can take a while to start them)
managers_up() {
    "$M" --json ps --window 0.5 2>/dev/null | python3 -c '
import json, sys
hosts = {h["host"] for h in json.load(sys.stdin)["hosts"]}
sys.exit(0 if {"alpha", "beta"} <= hosts else 1)'
}
setup "both managers answer" wait_for 20 managers_up
setup "up" "$M" up --wait-timeout 20 "$T/sched.yaml"

# sched_of PID: "POLICY RTPRIO CPUS" as the kernel has them: /proc/PID/stat fields 41 (policy:
# 0 other, 1 fifo, 2 rr) and 40 (real-time priority), and the CPUs it may run on.
sched_of() {
    s=$(sed 's/.*) //' "/proc/$1/stat" | awk '{print $39, $38}')
    echo "$s $(sed -n 's/^Cpus_allowed_list:[[:space:]]*//p' "/proc/$1/status")"
}
ALL=$(sed -n 's/^Cpus_allowed_list:[[:space:]]*//p' /proc/self/status)
# is NAME WANT: the component runs and the kernel schedules it as WANT says
is() {
    st=$(ps_field "$1" state); pid=$(ps_field "$1" pid)
    got=$(sched_of "$pid" 2>/dev/null)
    echo "$1: $st, pid $pid, sched '$got' (want '$2')"
    [ "$st" = running ] && [ "$got" = "$2" ]
}
warned() { grep -q "$1" "$2"; }

if chrt -f 1 true 2>/dev/null; then
    check "fifo 40 on CPU $LAST" is fifo "1 40 $LAST"
    check "rr 7 on the manager's CPUs" is rr "2 7 $ALL"
    check "no sched: the normal policy on the manager's CPUs" is plain "0 0 $ALL"
    SH=$(ps_field shell pid)
    kid=$(pgrep -P "$SH" sleep)
    check "a shell component and the program it starts: fifo 41 ($(sched_of "$kid"))" \
        sh -c "[ \"$(sched_of "$SH")\" = '1 41 $ALL' ] && [ \"$(sched_of "$kid")\" = '1 41 $ALL' ]"
    check "the manager at --rt-priority 10: fifo 10 ($(sched_of "$pid_am"))" [ "$(sched_of "$pid_am")" = "1 10 $ALL" ]
    # started at fifo 9 (a short heartbeat_timeout), back to the normal policy once it beats
    QP=$(ps_field quick pid)
    tasks_plain() {
        for t in /proc/"$QP"/task/*; do
            [ "$(sed 's/.*) //' "$t/stat" | awk '{print $39, $38}')" = "0 0" ] || return 1
        done
    }
    check "a component started at the manager's priority runs at the normal policy once it beats" \
        is quick "0 0 $ALL"
    check "every thread of it: the normal policy ($(sched_of "$QP"))" tasks_plain
    # the process it started before its first heartbeat does not keep fifo 9 (it is no thread
    # of it: the manager's return to the normal policy never reaches it)
    QC=$(awk '$2 == "quick" && $3 == "child" {p = $4} END {print p}' "$T/trace")
    child_plain() { [ -n "$QC" ] && [ "$(sched_of "$QC")" = "0 0 $ALL" ]; }
    check "a process it started meanwhile: the normal policy ($(sched_of "$QC"))" child_plain
    # One that computes 2 s before it beats (an interpreter's start, a map loaded first): at the
    # normal policy once 100 ms have passed, while it still computes, not at fifo 9 until its
    # first heartbeat (which held a CPU from everything else for as long as it computed)
    old=$(ps_field slow pid)
    "$M" restart slow > /dev/null 2>&1
    # the pid of slow's newest exec (the test component writes one line per exec to the trace)
    slow_pid() { awk '$2 == "slow" && $3 == "exec" {p = $4} END {print p}' "$T/trace"; }
    new_slow() { [ -n "$(slow_pid)" ] && [ "$(slow_pid)" != "$old" ]; }
    computing_normal() {
        pid=$(slow_pid)
        got=$(sched_of "$pid")
        # after the read, still computing: no "running" line of it yet (2 s of margin)
        ran=$(awk -v p="$pid" '$2 == "slow" && $3 == "running" && $4 == p' "$T/trace")
        echo "slow, pid $pid, 0.4 s after its exec: sched '$got', beating yet: '${ran:-no}'"
        [ -z "$ran" ] && [ "$got" = "0 0 $ALL" ]
    }
    wait_for 20 new_slow
    sleep 0.4
    check "a component computing before its first heartbeat: the normal policy after 100 ms" computing_normal
else
    skip "fifo, rr, plain, shell, manager" "this user may not use real-time scheduling here (chrt -f 1 refused)"
fi
check "CPUs that do not exist: a warning naming the component" \
    warned "sched_refused: nocpu: sched other cpus 1000: CPUs refused (Invalid argument): it runs on the manager's CPUs" "$T/am.log"
check "and it runs on the manager's CPUs" is nocpu "0 0 $ALL"
check "without the right: a warning naming the component and the reason" \
    warned "sched_refused: denied: sched fifo 40: policy refused (Operation not permitted): it runs at the normal policy" "$T/beta.log"
check "a manager refused --rt-priority says so and runs" \
    warned "rt-priority 10 refused (Operation not permitted): running at the normal policy" "$T/beta.log"
check "and it runs, at the normal policy" is denied "0 0 $ALL"
"$M" down > /dev/null 2>&1

# A component that prints without pause, beyond its rate limit: the manager at fifo 10 read it
# all as it came, 92 % of a core for 3 s (the host's other work had 5 % of that core). What is
# over the limit is still dropped and counted; the manager reads little of the rest.
cat > "$T/flood.yaml" <<EOF
system: flood
hosts: [alpha]
components:
  chatty:
    exec: 'exec yes "a line from a component that prints without pause"'
    shell: true
    heartbeat_timeout: 0
    host: alpha
EOF
"$M" up --wait-timeout 20 "$T/flood.yaml" > /dev/null 2>&1
sleep 1
ticks() { awk '{print $14 + $15}' "/proc/$pid_am/stat"; }
c0=$(ticks); t0=$(date +%s%N)
sleep 2
c1=$(ticks); t1=$(date +%s%N)
am_pct=$(( (c1 - c0) * 100 * 1000000000 / $(getconf CLK_TCK) / (t1 - t0) ))
check "a component flooding its output: the manager at under 30 % of a core (${am_pct} %)" [ "$am_pct" -lt 30 ]
check "and its lines over the limit are dropped and counted in its log" \
    grep -q -- "-- [0-9]* lines dropped (rate limit)" "$T/alpha/logs/chatty.log"
"$M" down > /dev/null 2>&1

# A bad policy name: refused whole, at its line and column, by marie up and by marie-am.
cat > "$T/bad.yaml" <<EOF
system: bad
components:
  a:
    exec: $COMP
    sched: {policy: realtime, priority: 40}
EOF
"$M" up "$T/bad.yaml" > "$T/up.out" 2>&1
rc=$?
check "marie up: exit 2 ($rc)" [ "$rc" = 2 ]
check "marie up: file:line:col of the bad policy" \
    grep -q "$T/bad.yaml:5:21: sched policy: expected other, fifo or rr, got 'realtime'" "$T/up.out"
"$BIN/marie-am" --host alpha --state-dir "$T/gamma" --system "$T/bad.yaml" > "$T/gamma.out" 2>&1
rc=$?
check "marie-am --system: exit 2 ($rc) with the same message" \
    sh -c "[ $rc = 2 ] && grep -q 'bad.yaml:5:21: sched policy' '$T/gamma.out'"
finish
