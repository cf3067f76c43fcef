#!/bin/sh
# A small robot (robot.radius 0.18 m in the system file, shared by the simulator's chassis, the
# planner's inflation and the avoid corridor) crosses a 0.6 m door, drives a 0.7 m corridor and
# enters a room through another 0.6 m door of the small-robot world, without touching a wall
# (tests/adapters/test_planner.c shows the default footprint has no path through the door).
. tests/lib.sh
out=$B/test-nav-small
rm -rf "$out"; mkdir -p "$out"

$BIN/marie-demo --quiet --system config/small-robot.yaml --out "$out/run" --timeout 300 > "$out/run.txt" 2>&1
s=$out/run/summary.json
cat "$out/run.txt"
check "small robot: the mission completes" test "$(json $s mission_done)" = True
check "small robot: every goal reached, the first one only through the 0.6 m door" \
    test "$(json $s reached)" = "$(json $s goals)"
check "small robot: 4 goals" test "$(json $s goals)" = 4
check "small robot: no wall contact" test "$(json $s collisions)" = 0
check "small robot: localization RMS < 0.15 m" le "$(json $s rms)" 0.15
check "the simulator's chassis follows robot.radius (0.30 x 0.20 m)" \
    grep -q "chassis 0.30 x 0.20 m" "$out/run/state/onboard1/logs/sim.log"
finish
