#!/bin/sh
# test-light
# Bad input from ROS 2 never reaches the bus nor stops marie-ros2: a NaN or infinite /cmd_vel, a
# goal in another frame, CDR that is not the type it is named (Cyclone refuses it, the bridge
# counts it), a LaserScan whose ranges count lies, and a writer of another type under /cmd_vel's
# name are each counted; TELEOP and GOAL_REQUEST carry nothing of them, and one good /cmd_vel
# after them all goes through. ROS_DOMAIN_ID picks the domain. Then the table's own mistakes: a goal topic without the key, a
# channel no port reads, an unknown key, each refused at its file:line:col.
. tests/lib.sh
OUT=$B/test-logs/ros2_bad_input
rm -rf "$OUT"; mkdir -p "$OUT/py"
PY=$(scripts/peer-venv.sh) || { echo "[  FAILED  ] setup: peer venv"; exit 1; }
export MARIE_KEY=$OUT/key MARIE_SEQ_FILE=$OUT/seq
trap stop_started EXIT
setup "lcm-gen --python" lcm-gen -p --ppath "$OUT/py" lcmtypes/*.lcm
setup "order key" "$BIN/marie" keygen "$MARIE_KEY"
start logger lcm-logger -q "$OUT/bus.lcm"
start ros2 "$BIN/marie-ros2" --system tests/ros2/bad_input.yaml --name ros2
sleep 1
PYTHONPATH=tests/ros2 timeout 60 "$PY" tests/ros2/bad_peer.py > "$OUT/peer.txt" 2>&1
sleep 1.5       # a heartbeat after the last sample
alive=0; kill -0 "$pid_ros2" 2>/dev/null && alive=1
stop_started
PYTHONPATH="$OUT/py" "$PY" tests/ros2/hb_counters.py "$OUT/bus.lcm" ros2 TELEOP GOAL_REQUEST SCAN_IN > "$OUT/counters.txt"
cat "$OUT/peer.txt" "$OUT/counters.txt"
n() { v=$(sed -n "s/^$1=//p" "$OUT/counters.txt"); echo "${v:-0}"; }

check "the bridge stayed up through it all" test "$alive" = 1
check "NaN, infinite and wrong-frame messages counted (3 rounds of 3)" test "$(n bad_ros2)" = 9
check "CDR that does not decode as its type counted (malformed Twist, lying LaserScan)" le 2 "$(n bad_cdr)"
check "a writer of another type under /cmd_vel counted" le 1 "$(n wrong_type)"
check "only the one good /cmd_vel reached TELEOP" test "$(n channel_TELEOP)" = 1
check "no goal reached GOAL_REQUEST, no scan SCAN_IN" test "$(n channel_GOAL_REQUEST)$(n channel_SCAN_IN)" = 00

# ROS_DOMAIN_ID: a bridge on domain 7 is heard on 7, not on 0.
start dom7 env ROS_DOMAIN_ID=7 "$BIN/marie-ros2" --system tests/ros2/bad_input.yaml --name ros2
sleep 1
on7=$(PYTHONPATH=tests/ros2 timeout 30 "$PY" tests/ros2/domain_peer.py 7 5)
on0=$(PYTHONPATH=tests/ros2 timeout 30 "$PY" tests/ros2/domain_peer.py 0 3)
stop_started
check "ROS_DOMAIN_ID=7: heard on domain 7, not on 0" test "$on7 $on0" = "heard=1 heard=0"

# The table's mistakes, each at its position in the file.
refused() {     # refused FILE TEXT: the bridge does not start, and says TEXT
    timeout 2 "$BIN/marie-ros2" --system "$1" --name ros2 > "$OUT/refused.log" 2>&1   # it stays up, failed
    grep -q "$2" "$OUT/refused.log" || { cat "$OUT/refused.log"; return 1; }
}
cat > "$OUT/nokey.yaml" <<Y
ros2:
  topics:
    - {channel: GOAL_REQUEST, topic: /goal_pose, direction: from_ros}
components:
  ros2: {exec: marie-ros2}
Y
sed 's/GOAL_REQUEST/NOWHERE/' "$OUT/nokey.yaml" > "$OUT/noport.yaml"
sed 's/direction: from_ros/direction: from_ros, rate: 5/' "$OUT/nokey.yaml" > "$OUT/badkey.yaml"
check "a goal topic without key_file is refused at its line" refused "$OUT/nokey.yaml" "nokey.yaml:3:7: .*key_file"
check "a channel no port writes is refused at its line" refused "$OUT/noport.yaml" "noport.yaml:3:7: .*NOWHERE"
check "an unknown key is refused at its line" refused "$OUT/badkey.yaml" "badkey.yaml:3:.*rate"
finish
