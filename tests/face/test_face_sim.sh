#!/bin/sh
# test-light
# test_face_sim: a tap on the touch page moves the simulated robot: the navigation stack runs
# with marie-sim, the mission (holding the key) has finished its list, a person taps "door B"
# on the page (touch screen emulated), and the robot drives there: the mission reaches the
# requested goal, the truth pose ends near it.
. tests/lib.sh
B=${B:-build}
BIN=$B/bin
OUT=$B/test-logs/face_sim
rm -rf "$OUT" && mkdir -p "$OUT"
MAP=sim/worlds/office.yaml
CHROME=$(command -v chromium || command -v chromium-browser || true)
CDP=9225
trap stop_started EXIT INT TERM
[ -n "$CHROME" ] || { check "chromium installed" false; finish; }
start chrome "$CHROME" --headless --no-sandbox --disable-gpu --disable-quic --no-first-run \
    --disable-background-networking --disable-component-update --disable-sync --disable-dev-shm-usage \
    --user-data-dir="$OUT/chrome" --remote-debugging-port=$CDP about:blank
"$BIN/marie" keygen "$OUT/key"

start sim $BIN/marie-sim --name sim --param world=$MAP --param speed=4 --param lockstep=0.5
start odometry $BIN/marie-odometry --name odometry --clock sim
start localizer $BIN/marie-localizer --name localizer --clock sim --param map=$MAP --param init_x=2 --param init_y=15
start planner $BIN/marie-planner --name planner --clock sim --param map=$MAP
start mailboxes $BIN/marie-ca mailbox --name mailboxes --param channel=POSE --param 'channels=[PATH, LASER, ESTOP]' --param depth=2
start behaviours $BIN/marie-behaviours --name behaviours --clock sim --param input_mode=pull
start mission $BIN/marie-mission --name mission --clock sim --param sharedmap=false --param key_file="$OUT/key" \
    --param tolerance=0.35 --param 'goals=[{name: start, x: 2.0, y: 15.0}]'
start face $BIN/marie-face --name face --param http_port=8151 --param key_file="$OUT/key" --param pin=1357 \
    --param 'places=[{name: door B, x: 12.25, y: 14.5, theta: -1.5708}, {name: lab, x: 20, y: 6}]' \
    --param url_file="$OUT/url"
setup "chromium and the page's server" wait_for 30 sh -c \
    "test -s '$OUT/url' && python3 -c \"import urllib.request; urllib.request.urlopen('http://127.0.0.1:$CDP/json/version')\""
check "the mission finished its own list first" wait_for 30 grep -q "mission done" "$OUT/mission.log"

$B/tests/helpers/adapt_probe --timeout 60 --goals 1 --done --verbose > "$OUT/probe.txt" 2> "$OUT/probe.log" &
probe=$!
ready="document.body.dataset.conn === '1' && document.querySelectorAll('[data-place]').length === 2"
check "a person taps 'door B' with the PIN" \
    python3 tests/viewer/cdp.py --port $CDP http://127.0.0.1:8151/ --size 800x480 --touch --timeout 15 \
        --until "($ready) && (document.getElementById('pin').value = '1357', true)" --tap '[data-place="0"]' \
        --then true --until2 "document.getElementById('notice').textContent === 'going to door B' && document.getElementById('what').textContent === 'On my way'" \
        --screenshot "$OUT/face-driving.png"
wait $probe
rc=$?
cat "$OUT/probe.txt"
grep "request_accepted\|goal_reached\|mission_done" "$OUT/probe.log"
check "the robot drove there: the requested goal is reached, mission done again" test "$rc" -eq 0
check "the goal reached was the person's" grep -q "goal_reached: goal 8[0-9]* 'door B' reached" "$OUT/probe.log"
check "no collision on the way" grep -q "^probe: 0 collisions" "$OUT/probe.txt"
finish
