#!/bin/sh
# test-light
# test_mapper_replay: a run recorded with lcm-logger (marie-sim in channel mode driven along a
# short route, marie-odometry, and marie-mapper live) goes through the mapper's library again
# with mapper_replay: it places the robot as the truth has it, gives the same answer twice, and
# takes the library's parameters by name; --truth-odometry puts the truth in the odometry's place
# (docs/mapping.md, "Comparing mapper versions").
. tests/lib.sh
B=${B:-build}
BIN=$B/bin
OUT=$B/test-logs/mapper_replay
rm -rf "$OUT" && mkdir -p "$OUT"
export LCM_DEFAULT_URL="udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608"
trap stop_started EXIT INT TERM

start logger lcm-logger -q --lcm-url="$LCM_DEFAULT_URL" "--channel=^(LASER|ODOMETRY|SIM_TRUTH|POSE)$" "$OUT/run.lcm"
start sim $BIN/marie-sim --name sim --param world=sim/worlds/office.yaml --param speed=6 --param lockstep=0.5 --param start_y=15.7
start odometry $BIN/marie-odometry --name odometry --clock sim
start mapper $BIN/marie-mapper --name mapper --clock sim --param init_x=2 --param init_y=15.7
# The route only once lcm-logger records (on a loaded machine it started late and the log held
# 139 of the run's 516 scans).
wait_for 20 test -s "$OUT/run.lcm"
$B/tests/helpers/route_driver --route "4.1,15.7;4.1,22.5;4.1,15.7;11.0,15.7" --timeout 90 > "$OUT/driver.txt" 2>&1
drc=$?
cat "$OUT/driver.txt"
stop_started
pids=""

replay() { $B/tests/helpers/mapper_replay "$OUT/run.lcm" --world sim/worlds/office.yaml --start 2 15.7 0 "$@"; }
replay --save "$OUT/replayed.yaml" > "$OUT/a.txt" 2>&1
arc=$?
replay > "$OUT/b.txt" 2>&1
replay loop_closure=false kf_dist=0.4 > "$OUT/c.txt" 2>&1
replay no_such_parameter=1 > "$OUT/d.txt" 2>&1
drc2=$?
replay --truth-odometry min_score=2 loop_closure=false > "$OUT/e.txt" 2>&1
cat "$OUT/a.txt" "$OUT/c.txt" "$OUT/d.txt" "$OUT/e.txt"
fig() { awk -v k="$2" '{ for (i = 1; i < NF; i++) if ($i == k) { print $(i + 1); exit } }' "$1"; }

check "the route is driven to its end with the mapper live" test "$drc" -eq 0
check "the replay places some hundreds of scans" test "$arc" -eq 0 -a "$(fig $OUT/a.txt scans)" -ge 200
check "the replayed trajectory follows the truth (ATE RMS < 0.10 m)" lt "$(fig $OUT/a.txt ate_rms)" 0.10
check "its map's walls are the world's (precision >= 0.90)" le 0.90 "$(fig $OUT/a.txt precision)"
check "it writes the map it built" test -s "$OUT/replayed.yaml" -a -s "$OUT/replayed.pgm"
check "the same log gives the same answer twice" cmp -s "$OUT/a.txt" "$OUT/b.txt"
check "parameters are taken by name (no closures, half the keyframes)" \
    eval 'test "$(fig $OUT/c.txt closures)" -eq 0 && test "$(fig $OUT/c.txt keyframes)" -lt "$(fig $OUT/a.txt keyframes)"'
check "with the truth as odometry and the matcher off, the poses are the truth's (ATE < 1 mm)" \
    lt "$(fig $OUT/e.txt ate_rms)" 0.001
check "an unknown parameter is refused" eval 'test "$drc2" -eq 2 && grep -q "no_such_parameter=1" "$OUT/d.txt"'
finish
