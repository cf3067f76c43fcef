#!/bin/sh
# test_mapper_sim: marie-sim (channel mode, office world) driven along a route through the
# corridor and six rooms; marie-odometry and marie-mapper build the map live; `marie map save`
# writes it; the saved map is judged against the world (precision, recall, coverage), the
# mapper's trajectory against the ground truth (ATE), and the localizer, planner and simulator
# must load it.
. tests/lib.sh
B=${B:-build}
BIN=$B/bin
OUT=$B/test-logs/mapper_sim
rm -rf "$OUT" && mkdir -p "$OUT"
WORLD=sim/worlds/office.yaml
# Maps are large messages: every socket gets a receive buffer that holds one.
export LCM_DEFAULT_URL="udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608"
trap stop_started EXIT INT TERM

ROUTE="4.1,15.7;4.1,22.5;4.1,7.5;4.1,15.7;11.0,15.7;11.0,19.0;11.0,7.5;11.0,15.7;16.25,15.7;16.25,22.5;16.25,7.5;16.25,15.7;20,15.7;20,22.5;20,7.5;20,15.7;10,15.7"
start sim $BIN/marie-sim --name sim --param world=$WORLD --param speed=4 --param lockstep=0.5 --param start_y=15.7
start odometry $BIN/marie-odometry --name odometry --clock sim
start mapper $BIN/marie-mapper --name mapper --clock sim --param init_x=2 --param init_y=15.7
$B/tests/helpers/route_driver --route "$ROUTE" --timeout 240 --traj "$OUT/traj.txt" > "$OUT/driver.txt" 2> "$OUT/driver.log"
drc=$?
cat "$OUT/driver.txt"
$BIN/marie map save "$OUT/built" --wait 12 > "$OUT/save.txt" 2>&1
src=$?
cat "$OUT/save.txt"
$BIN/marie map compare "$OUT/built.yaml" $WORLD --start 2 15.7 > "$OUT/compare.txt" 2>&1
cat "$OUT/compare.txt"
stop_started
pids=""

check "the route is driven to its end" test "$drc" -eq 0
check "marie map save writes the map from the bus" test "$src" -eq 0 -a -s "$OUT/built.yaml" -a -s "$OUT/built.pgm"
ate=$(awk '/^ate_rms/ {print $2}' "$OUT/driver.txt")
check "the mapper's pose follows the truth (ATE RMS < 0.10 m)" awk -v a="${ate:-9}" 'BEGIN { exit !(a >= 0 && a < 0.10) }'
read_fig() { awk -v k="$1" '{ for (i = 1; i < NF; i++) if ($i == k) print $(i + 1) }' "$OUT/compare.txt"; }
check "occupied cells are walls of the world (precision >= 0.85)" awk -v a="$(read_fig precision)" 'BEGIN { exit !(a >= 0.85) }'
check "the walls seen are in the map (recall >= 0.70)" awk -v a="$(read_fig recall)" 'BEGIN { exit !(a >= 0.70) }'
check "free space along the route is mapped (coverage >= 0.45)" awk -v a="$(read_fig coverage)" 'BEGIN { exit !(a >= 0.45) }'

# A component that cannot load its map fails its init and exits; one still running after 3 s
# has loaded it (timeout's status 124).
runs() { timeout 3 "$@" > "$OUT/load.log" 2>&1; [ $? -eq 124 ]; }
check "the localizer loads the saved map" runs $BIN/marie-localizer --name loc --param map=$OUT/built.yaml --param init_x=2 --param init_y=15.7
check "the planner loads the saved map" runs $BIN/marie-planner --name pln --param map=$OUT/built.yaml
check "the simulator runs in the saved map" runs $BIN/marie-sim --name sim2 --param world=$OUT/built.yaml --param start_y=15.7
check "a missing map is refused (the check above can fail)" sh -c "! timeout 3 $BIN/marie-localizer --name loc --param map=$OUT/none.yaml > /dev/null 2>&1"
finish
