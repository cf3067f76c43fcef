#!/bin/sh
# test-timeout: 240
# marie and ROS 2 as one system: config/spartacus.yaml's ros2 profile (the simulated Spartacus with
# marie-ros2) under the four managers, and a ROS 2 peer that is not marie code (the PyPI cyclonedds
# binding, its own Cyclone build, with rosbags' ROS 2 message definitions: tests/ros2/ros2_peer.py)
# and was given no configuration. It decodes /scan, /odom, /map, /tf, /tf_static and /amcl_pose,
# turns the robot with /cmd_vel and sends it to room A with /goal_pose, which the bridge turns into
# a request signed with the system's key; the mission obeys only such requests.
. tests/lib.sh
OUT=$B/test-ros2-system
rm -rf "$OUT"; mkdir -p "$OUT"
export MARIE_KEY=$OUT/key MARIE_SEQ_FILE=$OUT/seq
PATH=$BIN:$PATH
PY=$(scripts/peer-venv.sh) || { echo "[  FAILED  ] setup: peer venv"; exit 1; }
cleanup() {
    marie --timeout 20 down > /dev/null 2>&1
    stop_started
}
trap cleanup EXIT INT TERM
num() { sed -n "s/^$1=//p" "$OUT/peer.txt"; }

setup "order key" marie keygen "$MARIE_KEY"
for h in onboard1 onboard2 onboard3 laptop; do
    mkdir -p "$OUT/state/$h"
    start "am-$h" marie-am --host $h --state-dir "$OUT/state/$h" --key "$MARIE_KEY"
done
hosts() { marie --json ps --window 0.7 2>/dev/null | python3 -c 'import json, sys; sys.exit(len(json.load(sys.stdin)["hosts"]) != 4)'; }
setup "four managers answer" wait_for 10 hosts
setup "marie up --profile ros2" marie --timeout 30 up config/spartacus.yaml --profile ros2
PYTHONPATH=tests/ros2 timeout 200 "$PY" tests/ros2/ros2_drive.py 5.0 10.0 90 > "$OUT/peer.txt" 2> "$OUT/peer.err"
cat "$OUT/peer.txt"; tail -5 "$OUT/peer.err"

check "/scan: LaserScan decoded, 181 beams over 180 deg in the laser frame" \
    test "$(num scan_beams) $(num scan_span_deg) $(num scan_frame)" = "181 180.0 laser"
check "/scan: finite ranges within limits, no return as +inf (REP 117)" \
    test "$(num scan_in_limits)$(num scan_no_return_as_inf)" = 11
check "/odom: Odometry from odom to base_link" test "$(num odom_frames)" = "odom>base_link"
check "/map: the office map (800x600 at 0.05 m, map_server values) in the map frame" \
    test "$(num map_size) $(num map_resolution) $(num map_values_ok) $(num map_frame)" = "800x600 0.050 1 map"
check "/map: walls are there (1-30% occupied)" python3 -c "import sys; sys.exit(not 0.01 < float(sys.argv[1]) < 0.3)" "$(num map_occupied_share)"
check "/tf_static: base_link -> laser" test "$(num tf_static_laser)" = 1
check "/tf: map -> odom -> base_link lands within 0.2 m of /amcl_pose (REP 105)" le "$(num tf_vs_pose_m)" 0.2
check "/diagnostics: components' heartbeats" grep -q "^diag_example=marie:_" "$OUT/peer.txt"
check "/cmd_vel: the robot turned (> 1 rad in 3 s at 0.8 rad/s asked)" le 1.0 "$(num cmd_vel_turned_rad)"
check "/cmd_vel: it stops turning once ROS 2 stops asking" le "$(num omega_after_release)" 0.05
check "/goal_pose: the robot reached room A (within 0.5 m of 5,10)" le "$(num goal_distance_m)" 0.5
check "streams kept flowing while driving" le 100 "$(num final_count_scan)"
echo "# ros2: all topics seen $(num seen_after_s) s after start, room A reached $(num goal_after_s) s after /goal_pose"
finish
