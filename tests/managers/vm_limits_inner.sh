#!/bin/sh
# Runs inside the VM (see tests/managers/test_vm_limits.sh), whose kernel has cgroup v2 with the
# memory and cpu controllers: marie-am holds components to their limits with cgroups of their own.
B=${B:-build}
. tests/lib.sh
out=${VM_OUT:-/tmp}
ip link set lo up
ip link set lo multicast on
ip route add 224.0.0.0/4 dev lo
echo 8388608 > /proc/sys/net/core/rmem_max
mount -t cgroup2 none /sys/fs/cgroup
T=/tmp/limits
mkdir -p $T
export MARIE_KEY=$T/key MARIE_SEQ_FILE=$T/seq MARIE_LOG=${MARIE_LOG:-warn}
M="$BIN/marie"
"$M" keygen "$T/key" > /dev/null
TC=$(cd "$B" && pwd)/tests/bin/marie-test-comp
cat > "$T/limits.yaml" <<EOF
system: limits
hosts: [vm]
defaults:
  restart: {policy: always, backoff_min: 0.2, backoff_max: 1, stable_after: 60, max_failures: 0}
components:
  leaker:
    exec: $TC
    params: {leak_mb_s: 40}
    limits: {memory: 16M}
    heartbeat_timeout: 0
  hog:
    exec: $TC
    params: {busy: 0.9}
    limits: {cpu: 0.25}
    heartbeat_timeout: 0
EOF
# heartbeat_timeout 0 above: an emulated CPU on a loaded host may take more than 5 s to start a
# component, and a hog held to a quarter of a core beats late; here only the limits are judged.
MARIE_LOG=info "$BIN/marie-am" --host vm --state-dir "$T/am" > "$out/am.log" 2>&1 &
am=$!
wait_for 60 sh -c '"$0" ps > /dev/null' "$M"
check "up with limits" "$M" --timeout 30 up --no-wait "$T/limits.yaml"
check "marie-am made cgroups for them (cgroup v2 with memory and cpu)" \
    wait_for 10 grep -q "limits: memory and cpu limits are cgroup v2 limits, in /sys/fs/cgroup" "$out/am.log"
# A component's processes are in its cgroup: marie-am put them there (its own pid is elsewhere).
in_cgroup() { p=$(cat "/sys/fs/cgroup/c.$1/cgroup.procs"); [ -n "$p" ] && ! echo "$p" | grep -qx "$am"; }
check "the hog runs in its cgroup" wait_for 30 in_cgroup hog
check "and so does the leaker" wait_for 30 in_cgroup leaker
check "its cgroup holds its limit (memory.max 16M)" \
    sh -c "[ \$(cat /sys/fs/cgroup/c.leaker/memory.max) -eq $((16 << 20)) ]"
check "the kernel kills the leak at 16 MB: a limit_exceeded event, and it is restarted" \
    wait_for 120 sh -c "[ \$(grep -c 'limit_exceeded: leaker (pid [0-9]*): memory: the kernel killed it at its limit of 16 MB' '$out/am.log') -ge 1 ] && grep -q 'respawn: leaker (pid [0-9]*) killed by signal 9' '$out/am.log'"
check "it never held more than its limit (memory.peak)" \
    sh -c "[ \$(cat /sys/fs/cgroup/c.leaker/memory.peak 2>/dev/null || echo 0) -le $((16 << 20)) ]"
check "the hog's cgroup holds it to a quarter of a core (cpu.max)" grep -qx "25000 100000" /sys/fs/cgroup/c.hog/cpu.max
# its use over 6 s or so, from the cgroup's own count and the VM's clock
cpu_and_time() { echo "$(sed -n 's/^usage_usec //p' /sys/fs/cgroup/c.hog/cpu.stat) $(cut -d' ' -f1 /proc/uptime)"; }
a=$(cpu_and_time)
sleep 6
b=$(cpu_and_time)
share=$(echo "$a $b" | awk '{ printf "%.3f", ($3 - $1) / 1e6 / ($4 - $2) }')
echo "hog used $share core"
check "a hog that wants 0.9 core gets at most 0.25 (+ a period's slack: 0.27)" le "$share" 0.27
check "held back more than a quarter of a 5 s window: a limit_exceeded event, restarted" \
    wait_for 30 grep -q "limit_exceeded: hog (pid [0-9]*): cpu: held to its limit of 0.25 core" "$out/am.log"
shown() { ps_out=$("$M" ps); echo "$ps_out"; echo "$ps_out" | grep -q "leaker .*memory 16M (cgroup), breached"; }
check "marie ps shows the limits held by cgroups" shown
"$M" down > /dev/null 2>&1
kill $am
wait $am
check "marie-am removes the components' cgroups when it stops" sh -c "! [ -d /sys/fs/cgroup/c.leaker ]"
finish
