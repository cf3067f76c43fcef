#!/bin/sh
# Runs every benchmark in its own network namespace, gathers their TSV rows into
# $B/bench/results.tsv (bench metric value unit baseline ratio) and prints them as a table.
set -u
B=${B:-build}
out=$B/bench/results.tsv
mkdir -p "$B/bench/logs"
printf 'bench\tmetric\tvalue\tunit\tbaseline\tratio\n' > "$out"
status=0
for b in "$@"; do
    name=$(basename "$b")
    echo "bench: running $name" >&2
    # A long bench may have its own limit: BENCH_TIMEOUT_<name>, the name's other characters
    # written _ (BENCH_TIMEOUT_bench_demo_sh; bench_eval drives 200 goals).
    var=BENCH_TIMEOUT_$(printf '%s' "$name" | tr -c 'A-Za-z0-9_' '_')
    limit=$(eval echo "\${$var:-}")
    [ -z "$limit" ] && [ "$name" = bench_eval ] && limit=10800
    # bench_pipeline compares real-time scheduling with the normal one, bench_am runs a manager
    # at a real-time priority: their namespace keeps the caller's user where it may (a user
    # namespace refuses real-time scheduling).
    keep=0
    [ "$name" = bench_pipeline ] && keep=1
    [ "$name" = bench_am ] && keep=1
    if ! B=$B MARIE_NETNS_KEEP_USER=$keep timeout -k 5 "${limit:-${BENCH_TIMEOUT:-600}}" scripts/netns-run "$b" > "$B/bench/logs/$name.tsv" 2> "$B/bench/logs/$name.log"; then
        echo "bench: $name failed (see $B/bench/logs/$name.log)" >&2
        status=1
    fi
    # Rows only: a tab-separated line whose first field is not a header or a comment.
    grep -P '^[^\t#]+\t[^\t]+\t' "$B/bench/logs/$name.tsv" | grep -v -P '^bench\tmetric\t' >> "$out"
done
column -t -s "$(printf '\t')" "$out"
echo "results: $out"
exit $status
