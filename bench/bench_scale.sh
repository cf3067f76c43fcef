#!/bin/sh
# bench_scale: the managers at scale. For 10, 20 and 40 hosts (a manager each, 12.5 components a
# host: 125, 250 and 500 components): `marie up` until all run, `marie ps` latency, each
# manager's CPU, RSS and PSS at rest, and the bus load of heartbeats and manager status (bytes/s,
# counted by the real lcm-logger). The hosts share this namespace: every manager and component
# receives every multicast message, as on one Ethernet segment.
set -u
B=${B:-build}
dir=$(mktemp -d /tmp/marie-bench-scale-XXXXXX)
trap 'pkill -f "marie-am --host bs" 2>/dev/null; [ -n "${SCALE_KEEP:-}" ] || rm -rf "$dir"' EXIT
export MARIE_KEY=$dir/key MARIE_SEQ_FILE=$dir/seq
"$B/bin/marie" keygen "$MARIE_KEY" > /dev/null || exit 1

ms_now() { date +%s%N | cut -c1-13; }
row() { printf 'scale\t%s\t%s\t%s\t-\t-\n' "$1" "$2" "$3"; }
# utime + stime of a process, in clock ticks
ticks() { awk '{print $14 + $15}' "/proc/$1/stat" 2>/dev/null || echo 0; }
kib() { awk -v k="$2" '$1 == k":" {print $2}' "/proc/$1/smaps_rollup" 2>/dev/null || echo 0; }

for hosts in ${SCALE_HOSTS:-10 20 40}; do
    n=$((hosts * 25 / 2))
    sys=$dir/scale$hosts.yaml
    {
        echo "system: scale$hosts"
        printf 'hosts: ['
        for h in $(seq 1 "$hosts"); do printf '%sbs%d' "$([ "$h" -gt 1 ] && echo ', ')" "$h"; done
        echo ']'
        echo 'components:'
        for i in $(seq 0 $((n - 1))); do
            printf '  c%03d:\n    exec: %s/tests/bin/marie-test-comp\n    host: bs%d\n    stop_timeout: 1\n' \
                "$i" "$(cd "$B" && pwd)" $((i % hosts + 1))
        done
    } > "$sys"
    pids=""
    for h in $(seq 1 "$hosts"); do
        "$B/bin/marie-am" --host "bs$h" --state-dir "$dir/s$hosts-$h" 2> "$dir/am$hosts-$h.log" &
        pids="$pids $!"
    done
    sleep 1
    t0=$(ms_now)
    if ! "$B/bin/marie" --timeout 30 up "$sys" --wait-timeout 120 > "$dir/up$hosts.log" 2>&1; then
        echo "bench_scale: marie up failed for $hosts hosts:" >&2
        grep -v 'no answer' "$dir/up$hosts.log" >&2
        row "hosts_${hosts}_components_${n}_up_failed" "$(grep -c 'no answer' "$dir/up$hosts.log")" "hosts silent"
        kill $pids
        wait
        continue
    fi
    row "hosts_${hosts}_components_${n}_bringup" $(($(ms_now) - t0)) ms
    sleep 2
    # At rest for 5 s: the managers' CPU, and what heartbeats and status put on the bus.
    before=""
    for p in $pids; do before="$before $(ticks "$p")"; done
    lcm-logger -c 'MARIE_HEARTBEAT|MARIE_AM_STATUS' --quiet "$dir/bus$hosts.lcm" > /dev/null 2>&1 &
    logger=$!
    s0=$(ms_now)
    sleep 5
    kill -INT "$logger"
    wait "$logger" 2> /dev/null
    s1=$(ms_now)
    hz=$(getconf CLK_TCK)
    set -- $before
    cpu=$(for p in $pids; do echo "$1 $(ticks "$p")"; shift; done |
        awk -v hz="$hz" -v ms=$((s1 - s0)) '{c = ($2 - $1) / hz / (ms / 1000) * 100; s += c; if (c > m) m = c}
            END {printf "%.2f %.2f", s / NR, m}')
    row "hosts_${hosts}_am_cpu_mean" "${cpu% *}" %core
    row "hosts_${hosts}_am_cpu_max" "${cpu#* }" %core
    set -- $pids
    row "hosts_${hosts}_am_rss" "$(kib "$1" Rss)" KiB
    row "hosts_${hosts}_am_anon" "$(kib "$1" Anonymous)" KiB
    row "hosts_${hosts}_am_pss" "$(kib "$1" Pss)" KiB
    bytes=$(stat -c %s "$dir/bus$hosts.lcm" 2> /dev/null || echo 0)
    row "hosts_${hosts}_bus_heartbeat_status" $((bytes * 1000 / (s1 - s0))) B/s
    # marie ps: the whole system's table, five times.
    for k in 1 2 3 4 5; do
        p0=$(ms_now)
        "$B/bin/marie" --timeout 30 ps > /dev/null 2>&1
        echo $(($(ms_now) - p0))
    done | sort -n | sed -n 3p | { read -r med; row "hosts_${hosts}_ps_median" "$med" ms; }
    "$B/bin/marie" down --wait-timeout 60 > /dev/null 2>&1
    kill $pids
    wait
done
