#!/bin/sh
# marie-eval, the short version of make bench's navigation table: 3 random reachable goals in
# the open hall with pillars and in the warehouse aisles (fixed seed), headless on the simulator's
# clock at 4x. Every goal is reached, nothing is touched, the driven path stays within 1.3x the
# shortest on median and the localization RMS under 0.15 m; the table has a row per world.
. tests/lib.sh
out=$B/test-nav-eval
rm -rf "$out"; mkdir -p "$out"
$BIN/marie-eval --worlds "$B/worlds/eval" --world hall,warehouse --goals 3 --seed 1 --speed 4 --out "$out/runs" \
    > "$out/eval.txt" 2> "$out/eval.log"
rc=$?
cat "$out/eval.txt"
row() { awk -v w="$1" '$1 == w' "$out/eval.txt"; }
field() { row "$1" | awk -v k="$2" '{ print $k }'; }
check "marie-eval ran every world" test $rc = 0
for w in hall warehouse; do
    check "$w: a row in the table" test -n "$(row $w)"
    check "$w: 3/3 goals reached" test "$(field $w 2)" = "3/3"
    check "$w: no collision" test "$(field $w 4)" = 0
    check "$w: median path within 1.3x the shortest" le "$(field $w 6)" 1.3
    check "$w: localization RMS under 0.15 m" le "$(field $w 7)" 0.15
done
finish
