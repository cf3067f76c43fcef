#!/bin/sh
# test_balance_loads: two competing loads over five minutes on four hosts (network namespaces
# on one bridge): the two hogs that start on one host are split by one move, and then nothing
# moves again. In make test-slow (it lasts five minutes by design).
. tests/managers/fourhosts.sh
minutes=${BALANCE_MINUTES:-5}

"$BIN/marie" keygen "$T/key"
for h in $HOSTS; do start_am "$h"; done
sleep 0.5
where() {
    M --json ps --window 0.7 2>/dev/null | python3 -c '
import json, sys
for h in json.load(sys.stdin)["hosts"]:
    for c in h["components"]:
        if c["name"] == sys.argv[1] and c["state"] in ("running", "degraded", "starting"):
            print(h["host"])' "$1" | tr '\n' ' ' | sed 's/ $//'
}
moves() { cat "$T"/*.log | grep -c "balance: .* moves to "; }
split() { a=$(where hog_a); b=$(where hog_b); echo "hog_a on: $a, hog_b on: $b"; [ -n "$a" ] && [ -n "$b" ] && [ "$a" != "$b" ]; }

setup "up on four hosts" M up tests/data/managers/balance_loads.yaml
check "the two hogs leave each other within 15 s" wait_for 15 split
# Watch for the whole time, a sample every 10 s: the hogs stay apart and the moves are counted.
end=$(( $(date +%s) + minutes * 60 ))
apart=0 together=0
while [ "$(date +%s)" -lt "$end" ]; do
    sleep 10
    if split > /dev/null; then apart=$((apart + 1)); else together=$((together + 1)); fi
done
n=$(moves)
cat "$T"/*.log | grep "balance: .* moves to "
echo "in $minutes min: $n moves; samples apart $apart, together $together"
check "no flapping: one move in $minutes minutes of two competing loads (got $n)" [ "$n" -eq 1 ]
check "the hogs stayed apart at every sample" [ "$together" -eq 0 ]
setup "down" M down
finish
