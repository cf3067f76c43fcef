#!/bin/sh
# test-light
# test_sign_mission: the mission uses what the robot reads. Its only goal is "the room whose
# sign says B": the robot drives along the office corridor (search points), the simulator's
# camera shows the door signs, marie-vision places them in the map from the localizer's pose,
# and the mission goes to the door whose sign reads "room B". Reports the distance the sign
# was read from and its position error against the world file.
. tests/lib.sh
B=${B:-build}
BIN=$B/bin
OUT=$B/test-logs/sign_mission
rm -rf "$OUT" && mkdir -p "$OUT"
MAP=sim/worlds/office.yaml
trap stop_started EXIT INT TERM

cat > "$OUT/system.yaml" <<'Y'
system: sign-test
components:
  mission:
    exec: marie-mission
    params:
      tolerance: 0.35
      goals: []
      signs:
        - {name: room-b, message: room B, search: [[8.0, 15.0], [16.0, 15.0], [24.0, 15.0], [34.0, 15.0]]}
  vision:
    exec: marie-vision
    params:
      {width: 320, height: 240, fx: 250, fy: 250, cx: 159.5, cy: 119.5, tag_size: 0.2, decimate: 1,
       messages: [{id: 1, message: room A, kind: sign}, {id: 2, message: room B, kind: sign},
                  {id: 7, message: room G, kind: sign}, {id: 8, message: room H, kind: sign}]}
Y

start sim $BIN/marie-sim --name sim --param world=$MAP --param speed=4 --param lockstep=0.5 \
    --param camera=true --param camera_size=320x240
start odometry $BIN/marie-odometry --name odometry --clock sim
start localizer $BIN/marie-localizer --name localizer --clock sim --param map=$MAP --param init_x=2 --param init_y=15
start planner $BIN/marie-planner --name planner --clock sim --param map=$MAP
start mailboxes $BIN/marie-ca mailbox --name mailboxes --param channel=POSE --param 'channels=[PATH, LASER, ESTOP]' --param depth=2
start sharedmap env MARIE_STATE_DIR=$OUT $BIN/marie-ca sharedmap --name sharedmap --param state_file=$OUT/state.sharedmap
start behaviours $BIN/marie-behaviours --name behaviours --clock sim --param input_mode=pull
start vision $BIN/marie-vision --name vision --system $OUT/system.yaml
start mission $BIN/marie-mission --name mission --clock sim --system $OUT/system.yaml

$B/tests/helpers/adapt_probe --timeout 90 --goals 1 --done --verbose > "$OUT/probe.txt" 2> "$OUT/probe.log"
rc=$?
cat "$OUT/probe.txt"
grep "sign_read\|goal_" "$OUT/probe.log"

check "the mission completes: the room whose sign says B is reached" test "$rc" -eq 0
check "the goal was found by reading the sign" grep -q "sign 'room B' read at" "$OUT/probe.log"
# The sign's place as read, against sim/worlds/office.yaml: (12.00, 13.51).
line=$(grep -o "sign 'room B' read at ([-0-9.]*, [-0-9.]*) from [0-9.]* m; going to ([-0-9.]*, [-0-9.]*)" "$OUT/probe.log" | head -1)
report=$(echo "$line" | python3 -c "
import re, sys, math
m = re.search(r'at \(([-0-9.]+), ([-0-9.]+)\) from ([0-9.]+) m; going to \(([-0-9.]+), ([-0-9.]+)\)', sys.stdin.read())
x, y, r, gx, gy = map(float, m.groups())
e = math.hypot(x - 12.00, y - 13.51)
# The goal: 1 m out from the sign along its face (+y), where the robot then stands.
ge = math.hypot(gx - 12.00, gy - 14.51)
print('sign B read from %.2f m, placed %.3f m from the truth; goal (%.2f, %.2f), %.3f m from door B' % (r, e, gx, gy, ge))
sys.exit(0 if e < 0.3 and ge < 0.35 else 1)
")
rc=$?
echo "$report"
check "the sign is placed within 0.3 m of the world file's position (localizer pose), the goal before door B" test "$rc" -eq 0
finish
