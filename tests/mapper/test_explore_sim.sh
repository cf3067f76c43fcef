#!/bin/sh
# test_explore_sim: the robot maps the office world by itself: marie-sim, marie-odometry,
# marie-mapper (pose and map), marie-planner on the live map, marie-behaviours following its
# paths, and marie-explore choosing frontiers until none is reachable; the saved map is judged
# against the world.
. tests/lib.sh
B=${B:-build}
BIN=$B/bin
OUT=$B/test-logs/explore_sim
rm -rf "$OUT" && mkdir -p "$OUT"
WORLD=sim/worlds/office.yaml
export LCM_DEFAULT_URL="udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608"
trap stop_started EXIT INT TERM

start sim $BIN/marie-sim --name sim --param world=$WORLD --param speed=${SIM_SPEED:-5} --param lockstep=0.5 --param start_y=15.7
start odometry $BIN/marie-odometry --name odometry --clock sim
start mapper $BIN/marie-mapper --name mapper --clock sim --param init_x=2 --param init_y=15.7 ${MAPPER_ARGS:-}
start planner $BIN/marie-planner --name planner --clock sim --param unknown_is_free=true ${PLANNER_ALGO:+--param algorithm=$PLANNER_ALGO}
start behaviours $BIN/marie-behaviours --name behaviours --clock sim --param input_mode=subscribe
start explore $BIN/marie-explore --name explore --clock sim
wait_for ${EXPLORE_WALL_S:-250} grep -q "explore_done" "$OUT/explore.log"
done_rc=$?
$BIN/marie map save "$OUT/explored" --wait 12 > "$OUT/save.txt" 2>&1
cat "$OUT/save.txt"
$BIN/marie map compare "$OUT/explored.yaml" $WORLD --start 2 15.7 > "$OUT/compare.txt" 2>&1
cat "$OUT/compare.txt"
grep -c "frontier_goal" "$OUT/explore.log" | sed 's/^/frontier goals: /'
grep -c "frontier_given_up" "$OUT/explore.log" | sed 's/^/given up: /'
check "exploration ends with no reachable frontier left" test "$done_rc" -eq 0
read_fig() { awk -v k="$1" '{ for (i = 1; i < NF; i++) if ($i == k) print $(i + 1) }' "$OUT/compare.txt"; }
check "the explored map covers the office (coverage >= 0.80)" awk -v a="$(read_fig coverage)" 'BEGIN { exit !(a >= 0.80) }'
# Aligned (the best rigid transform within 0.5 m, 0.03 rad): measured 0.96 / 0.80 / 0.83.
check "aligned, it covers the office (coverage >= 0.90)" awk -v a="$(read_fig acoverage)" 'BEGIN { exit !(a >= 0.90) }'
check "aligned, its walls are the world's (precision >= 0.70)" awk -v a="$(read_fig aprecision)" 'BEGIN { exit !(a >= 0.70) }'
check "aligned, the world's walls are in it (recall >= 0.70)" awk -v a="$(read_fig arecall)" 'BEGIN { exit !(a >= 0.70) }'
finish
