#!/bin/sh
# marie bag: the demo's log exported to rosbag2 (MCAP) and read back by rosbags, not marie code:
# every message there, scans in limits or +inf; imported again: the same messages (every field a
# ROS 2 message carries, angles to 1e-9 rad through their quaternions). Then a bag rosbags wrote
# itself (sqlite3 storage, no return as NaN) is imported and replayed into a fresh localizer,
# which finds the poses the robot's own localizer published in the run. `marie bag info` on both.
. tests/lib.sh
OUT=$B/test-logs/marie_bag
rm -rf "$OUT"; mkdir -p "$OUT"
PY=$(scripts/peer-venv.sh) || { echo "[  FAILED  ] setup: peer venv"; exit 1; }
W="env PYTHONPATH=$B/gen/bag-python $PY tests/tools/bag_roundtrip.py"
trap stop_started EXIT

setup "the demo runs" "$BIN/marie-demo" --quiet --out "$OUT/demo" --timeout 120
LOG=$OUT/demo/demo.lcm
check "marie bag export writes rosbag2 in MCAP" "$BIN/marie" bag export "$LOG" "$OUT/bag"
check "the bag is MCAP with its metadata" test -s "$OUT/bag/bag.mcap" -a -s "$OUT/bag/metadata.yaml"
check "rosbags reads back every message, scans in limits or +inf" $W readback "$OUT/bag" "$LOG"
check "marie bag import brings them back" "$BIN/marie" bag import "$OUT/bag" "$OUT/back.lcm"
check "export -> import: the same messages" $W same "$LOG" "$OUT/back.lcm"
check "marie bag info: an MCAP bag" sh -c "'$BIN/marie' bag info '$OUT/bag' | grep -q '^  /scan  *sensor_msgs/msg/LaserScan  *[1-9][0-9]*$'"
check "marie bag info: an LCM log" sh -c "'$BIN/marie' bag info '$LOG' | grep -q '^  LASER  *laser_scan_t'"

# A bag marie did not write, replayed into the localizer.
setup "rosbags writes a sqlite3 bag" $W write "$LOG" "$OUT/rosbags_bag"
check "marie bag import reads sqlite3" "$BIN/marie" bag import "$OUT/rosbags_bag" "$OUT/from_rosbags.lcm"
check "marie bag info: a sqlite3 bag" sh -c "'$BIN/marie' bag info '$OUT/rosbags_bag' | grep -q 'nav_msgs/msg/Odometry'"
start localizer "$BIN/marie-localizer" --name replay --clock sim --port pose=POSE_REPLAY --port particles=PARTICLES_REPLAY \
    --param map=sim/worlds/office.yaml --param init_x=2.0 --param init_y=15.0
sleep 1
dur=$(json "$OUT/demo/summary.json" sim_s)
play=$(python3 -c "print(int(float('$dur') / 4 + 15))")
"$B/tests/replay_check" "$LOG" "$play" > "$OUT/replay.txt" 2>&1 &
chk=$!
sleep 0.5
lcm-logplayer -s 4 "$OUT/from_rosbags.lcm" > /dev/null 2>&1
wait $chk; rc=$?
cat "$OUT/replay.txt"
check "the localizer on the imported bag finds the run's poses" test $rc = 0
finish
