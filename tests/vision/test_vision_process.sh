#!/bin/sh
# test-light
# test_vision_process: the marie-vision and marie-vision-render programs as separate
# processes on the bus: synthetic camera frames in, tag messages read; a camera that cannot
# be opened is reported with its reason; SIGTERM quits cleanly.
. tests/lib.sh
tmp=$(mktemp -d /tmp/vision-proc-XXXXXX)
trap 'kill $vpid 2>/dev/null; rm -rf "$tmp"' EXIT

# Frames published by marie-vision-render are read by marie-vision.
$BIN/marie-vision --param min_hits=2 \
    --param 'messages=[{id: 3, message: dock ahead, kind: dock}, {id: 8, goal: {x: 1, y: 2}}]' \
    > "$tmp/v1.log" 2>&1 &
vpid=$!
sleep 0.5
read_dock() {
    $BIN/marie-vision-render --publish CAMERA_IMAGE --count 4 --rate 20 --format jpeg \
        --tag 3:0.16:-0.2:0:1.2:0.2:0.1:0.3 --tag 8:0.16:0.3:0:1.5 >/dev/null 2>&1
    grep -q 'tag 3 reads: dock ahead' "$tmp/v1.log"
}
check "synthetic camera frames are read as tag messages" wait_for 10 read_dock
kill -TERM $vpid
wait $vpid
rc=$?
check "sigterm quits with status 0" [ "$rc" -eq 0 ]

# The simulator's camera on a robot turning left in a tag world: tag 3 ahead, then tag 7.
$BIN/marie-vision --param min_hits=2 \
    --param 'messages=[{id: 3, message: three ahead}, {id: 7, message: seven on the left}]' \
    > "$tmp/v7.log" 2>&1 &
vpid=$!
# Its first heartbeat says it reads the bus (a fixed wait missed the frames on a loaded machine).
$BIN/marie topic echo MARIE_HEARTBEAT --once --timeout 20 > /dev/null
$BIN/marie-vision-render --world tests/data/vision/world.yaml --robot 0:0:0 --turn 1.5 --rate 10 --count 14 \
    --publish CAMERA_IMAGE
check "turning robot reads the tag ahead" wait_for 5 grep -q 'tag 3 reads: three ahead' "$tmp/v7.log"
check "then the tag on its left" wait_for 5 grep -q 'tag 7 reads: seven on the left' "$tmp/v7.log"
kill -TERM $vpid; wait $vpid 2>/dev/null

# A folder of rendered images.
mkdir "$tmp/imgs"
for i in 0 1 2; do
    $BIN/marie-vision-render --tag 5:0.16:0:0:1 --noise 3 --out "$tmp/imgs/f$i.png" || exit 1
done
$BIN/marie-vision --param "source=folder:$tmp/imgs" --param rate_hz=20 \
    --param 'messages=[{id: 5, message: five}]' > "$tmp/v2.log" 2>&1 &
vpid=$!
check "image folder frames are read" wait_for 10 grep -q 'tag 5 reads: five' "$tmp/v2.log"
check "end of the folder is announced" wait_for 10 grep -q 'source_ended' "$tmp/v2.log"
kill -TERM $vpid; wait $vpid 2>/dev/null

# A camera that does not exist: the reason is printed and the process stays up, failed,
# for its manager to see.
$BIN/marie-vision --param source=/dev/video77 > "$tmp/v3.log" 2>&1 &
vpid=$!
check "unreadable camera reports why" wait_for 10 grep -q "cannot be opened" "$tmp/v3.log"
check "still running (failed) after a bad camera" kill -0 $vpid
kill -TERM $vpid; wait $vpid 2>/dev/null

# Wrong intrinsics.
$BIN/marie-vision --param fx=-3 --param fy=500 --param cx=320 --param cy=240 --param width=640 \
    --param height=480 > "$tmp/v4.log" 2>&1 &
vpid=$!
check "wrong intrinsics report why" wait_for 10 grep -q "focal lengths" "$tmp/v4.log"
kill -TERM $vpid; wait $vpid 2>/dev/null

# From a system file: parameters and port bindings as a robot would have them.
$BIN/marie-vision --system tests/data/vision/vision.yaml --name vision > "$tmp/v5.log" 2>&1 &
vpid=$!
sleep 0.5
read_charger() {
    $BIN/marie-vision-render --publish CAMERA_IMAGE --count 3 --rate 20 --tag 7:0.16:0:0:1.4 >/dev/null 2>&1
    grep -q 'tag 7 reads: to the charger' "$tmp/v5.log"
}
check "system file configures messages" wait_for 10 read_charger
kill -TERM $vpid; wait $vpid 2>/dev/null
$BIN/marie-vision --system tests/data/vision/vision_bad_messages.yaml --name vision > "$tmp/v6.log" 2>&1 &
vpid=$!
check "a messages mistake is reported with file:line" \
    wait_for 10 grep -q "vision_bad_messages.yaml:10:.*mapped twice" "$tmp/v6.log"
kill -TERM $vpid; wait $vpid 2>/dev/null

# Unknown parameter: a configuration error, exit status 2.
check "unknown parameter is a config error" sh -c "$BIN/marie-vision --param colour=red >/dev/null 2>&1; [ \$? -eq 2 ]"
check "no sanitizer reports (make test SAN=1)" sh -c "! grep -l 'Sanitizer\\|runtime error' $tmp/*.log"
finish
