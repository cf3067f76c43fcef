#!/bin/sh
# test-timeout: 900
# Explore, then navigate (marie-demo --mission explore): the explore profile maps the office
# from an empty map until no reachable frontier is left; the map is saved and judged against the
# world; the sim profile's mission then runs with the localizer and the planner on that map
# (MARIE_MAP). About a minute.
. tests/lib.sh
out=$B/test-explore-app
rm -rf "$out"; mkdir -p "$out"

$BIN/marie-demo --quiet --mission explore --out "$out/explore" --timeout 240 --explore-timeout 400 \
    > "$out/explore.txt" 2>&1
x=$out/explore/summary.json
cat "$out/explore.txt"
ex() { python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['explore'][sys.argv[2]])" "$x" "$1"; }
check "explore: exploration ends with no reachable frontier left" test "$(ex done)" = True
check "explore: the saved map is a map_server pair" test -s "$out/explore/explored.yaml" -a -s "$out/explore/explored.pgm"
# The issue's figures. Measured on this machine with exact scan stamps: 33 of 35 live runs (the
# two others: a machine running two explores and more at once, and a gyro taken before its bias
# was known, since mended), 70 of 70 replays (docs/mapping.md, "Scan stamps, scan by scan").
check "explore: the map covers the office's free space (>= 0.95)" le 0.95 "$(ex coverage)"
check "explore: aligned, its walls are the world's (precision >= 0.95)" le 0.95 "$(ex aprecision)"
check "explore: aligned, the world's walls are in it (recall >= 0.95)" le 0.95 "$(ex arecall)"
check "explore: the mapper's pose against the truth, RMS < 0.10 m" le "$(ex rms)" 0.10
built_on() { grep -q "map $(realpath "$out/explore")/explored.yaml: " "$out/explore/state/onboard2/logs/$1.log"; }
check "explore: the localizer and the planner ran on the built map" eval "built_on localizer && built_on planner"
check "explore: then the mission completes on it, every goal reached" \
    test "$(json $x mission_done)/$(json $x reached)" = "True/$(json $x goals)"
check "explore: localization on the built map, RMS against the world < 0.20 m" le "$(json $x rms)" 0.20
check "explore: no collision" test "$(json $x collisions)" = 0
finish
