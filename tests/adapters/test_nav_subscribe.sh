#!/bin/sh
# test-light
# test_nav_subscribe: the same pipeline without Communication Adapters: marie-behaviours in
# input_mode=subscribe, the mission without a SharedMap; a two-goal mission in the office world,
# after malformed and absurd messages (random bytes, NaN poses, empty scans) on every input;
# then an operator's teleop commands take over.
. tests/lib.sh
B=${B:-build}
BIN=$B/bin
OUT=$B/test-logs/nav_subscribe
rm -rf "$OUT" && mkdir -p "$OUT"
MAP=sim/worlds/office.yaml
trap stop_started EXIT INT TERM

cat > "$OUT/system.yaml" <<'Y'
system: nav-subscribe-test
components:
  mission:
    exec: marie-mission
    params:
      sharedmap: false
      goals:
        - {name: corridor, x: 9.0, y: 14.8}
        - {name: room, x: 4.0, y: 9.0}
Y


start sim $BIN/marie-sim --name sim --param world=$MAP --param speed=4 --param lockstep=0.5
start odometry $BIN/marie-odometry --name odometry --clock sim
start localizer $BIN/marie-localizer --name localizer --clock sim --param map=$MAP --param init_x=2 --param init_y=15
start planner $BIN/marie-planner --name planner --clock sim --param map=$MAP --param algorithm=prm
start behaviours $BIN/marie-behaviours --name behaviours --clock sim --param input_mode=subscribe
start mission $BIN/marie-mission --name mission --clock sim --system $OUT/system.yaml

sleep 1
$B/tests/helpers/adapt_probe --timeout 60 --goals 2 --done --settle 1 --verbose --garbage --teleop-after-done > "$OUT/probe.txt" 2> "$OUT/probe.log"
rc=$?
alive=0
for p in $pids; do kill -0 "$p" 2>/dev/null && alive=$((alive + 1)); done
cat "$OUT/probe.txt"
check "mission completes with subscribed inputs, localized" test "$rc" -eq 0
check "no pull requests without Mailboxes" grep -q "^probe: 0 pull requests" "$OUT/probe.txt"
check "every component survived the bad input" test "$alive" -eq 6
check "teleop wins while its commands come" grep -Eq "^probe: [1-9][0-9]* commands from teleop" "$OUT/probe.txt"
finish
