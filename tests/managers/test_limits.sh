#!/bin/sh
# test-light
# test_limits: components held to their `limits:` by a real marie-am: a leak is caught at its
# memory limit and restarted, a CPU hog over its share for a 5 s window is stopped (on_breach:
# stop), a component's open files are limited by the kernel (its rlimit) and one that reaches
# the limit is stopped; each breach is a limit_exceeded event, and marie ps shows the limits and
# the breaches. Where marie-am has no cgroup v2 (this machine: cgroup v1 controllers) memory and
# CPU are watched by marie-am; tests/managers/test_vm_limits.sh runs the cgroup v2 side in a VM.
. tests/lib.sh
T=$(mktemp -d /tmp/marie-test-limits.XXXXXX)
export MARIE_KEY=$T/key MARIE_SEQ_FILE=$T/seq
OUT=$T
M="$BIN/marie"
cleanup() { "$M" down > /dev/null 2>&1; stop_started; rm -rf "$T"; }
trap cleanup EXIT INT TERM
"$M" keygen "$T/key" > /dev/null
TC=$(cd "$B" && pwd)/tests/bin/marie-test-comp
cat > "$T/limits.yaml" <<EOF
system: limits
hosts: [alpha]
defaults:
  restart: {policy: always, backoff_min: 0.2, backoff_max: 1, stable_after: 30, max_failures: 0}
components:
  leaker:
    exec: $TC
    params: {leak_mb_s: 40}
    limits: {memory: 64M}
  hog:
    exec: $TC
    params: {busy: 0.8}
    limits: {cpu: 0.1, on_breach: stop}
  files:
    exec: $TC
    params: {open_files: 10}
    limits: {nofile: 64}
  fd_leak:
    exec: $TC
    params: {open_files: 100}
    limits: {nofile: 64, on_breach: stop}
  free:
    exec: $TC
EOF
start am "$BIN/marie-am" --host alpha --state-dir "$T/am"
setup "marie-am answers" wait_for 20 sh -c '"$0" ps > /dev/null' "$M"
# --no-wait: the hog and fd_leak are stopped by their breaches, the leaker restarted again and
# again: "every component running" may never hold at one moment
check "up with limits" "$M" up --no-wait "$T/limits.yaml"
events() { grep -c "limit_exceeded: $1 (pid [0-9]*): $2" "$T/am.log"; }
# watch the leaker's resident memory as ps reports it, until it has been restarted twice
peak=0
leaker_restarted() {
    r=$("$M" --json ps --window 0.5 2>/dev/null | python3 -c '
import json, sys
for h in json.load(sys.stdin)["hosts"]:
    for c in h["components"]:
        if c["name"] == "leaker":
            print(c["rss"], c["restarts"])')
    set -- $r
    [ "${1:-0}" -gt "$peak" ] && peak=$1
    [ "${2:-0}" -ge 2 ]
}
check "a leak at 40 MB/s is restarted at its 64 MB limit, again and again" wait_for 20 leaker_restarted
check "each time a limit_exceeded event says why" sh -c "[ $(events leaker 'memory: ') -ge 2 ]"
check "resident memory seen by ps never far over the limit (peak $((peak >> 20)) MB, limit 64 MB + one sample)" \
    [ "$peak" -gt $((32 << 20)) -a "$peak" -le $(((64 + 12) << 20)) ]
hog_stopped() { [ "$(ps_field hog state)" = stopped ] && [ "$(events hog 'cpu: ')" -ge 1 ]; }
# 0.1 core: a hog gets more even on a machine loaded ten times over its two cores
check "a CPU hog (0.8 core) over its 0.1 core for a 5 s window is stopped (on_breach: stop)" wait_for 30 hog_stopped
pid=$(ps_field files pid)
check "the kernel holds files to 64 open files (its rlimit)" \
    grep -Eq '^Max open files +64 +64 ' "/proc/$pid/limits"
fd_stopped() { [ "$(ps_field fd_leak state)" = stopped ] && [ "$(events fd_leak 'nofile: ')" -eq 1 ]; }
check "one that reaches its open-file limit is stopped" wait_for 10 fd_stopped
check "its own open failed at the limit (Too many open files)" \
    grep -q "open_files: only .* opened: Too many open files" "$T/am/logs/fd_leak.log"
check "files, within its limits, was never touched" sh -c "[ $(events files .) -eq 0 ] && [ $(ps_field files restarts) -eq 0 ]"
shown() {
    out=$("$M" ps); echo "$out"
    echo "$out" | grep -q "^alpha  *leaker .*memory 64M (\(watched\|cgroup\)), breached [1-9][0-9]*$" &&
        echo "$out" | grep -q "^alpha  *hog  *stopped .*cpu 0.1 on_breach stop (\(watched\|cgroup\)), breached [1-9]" &&
        echo "$out" | grep -q "^alpha  *files .*nofile 64 (rlimit)$" &&
        echo "$out" | grep -Eq "^alpha  *free .*[0-9.]+[KMG]?$"
}
check "marie ps shows each one's limits, how they are held and its breaches" shown
finish
