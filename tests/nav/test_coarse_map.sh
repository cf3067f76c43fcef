#!/bin/sh
# A map at 0.2 m cells of a finer world (the evaluation's warehouse: 0.8 m racks, 2 m aisles),
# as a mapper with coarse cells draws it: a cell is a wall when any part of it is. marie-eval
# drives 4 random goals with the robot given that map: every goal reached, the localizer never
# lost and its pose within 0.15 m RMS of the truth (the beams' ends are measured from the coarse
# walls' faces, not from their cells' centres 10 cm behind).
. tests/lib.sh
out=$B/test-nav-coarse
rm -rf "$out"; mkdir -p "$out"
$BIN/marie-eval --worlds "$B/worlds/eval" --world warehouse --coarse 0.2 --goals 4 --seed 1 --speed 4 \
    --out "$out/runs" > "$out/eval.txt" 2> "$out/eval.log"
rc=$?
cat "$out/eval.txt"
field() { awk -v k="$1" '$1 == "warehouse" { print $k }' "$out/eval.txt"; }
check "marie-eval ran" test $rc = 0
check "the robot was given the map at 0.2 m" grep -q 'map.yaml: .* at 0.200 m' "$out/runs/warehouse/localizer.log"
check "4/4 goals reached" test "$(field 2)" = "4/4"
check "no collision" test "$(field 4)" = 0
check "never lost" test "$(field 9)" = 0
check "localization RMS under 0.15 m" le "$(field 7)" 0.15
finish
