#!/bin/sh
# test_viewer: marie-view seen through headless Chromium. A recorded demo log (map, poses,
# laser, particles, path, goals, decision timeline, components and a restart), scrubbing to a
# time, live following of publishers and of the simulator on the bus, corrupt and foreign
# logs, and a lost server: the page always says what is wrong instead of going blank.
. tests/lib.sh
SRV=$BIN/marie-viewer-server
GEN=$B/tests/bin/viewer-gen
tmp=$(mktemp -d)
pids=""
cleanup() {
    for p in $pids; do kill "$p" 2>/dev/null; done
    for p in $pids; do wait "$p" 2>/dev/null; done
    rm -rf "$tmp"
}
trap cleanup EXIT INT TERM

CHROME=$(command -v chromium || command -v chromium-browser || true)
# Chromium as a user would run it headless, with nothing reaching out to the network.
chrome() {
    timeout 60 "$CHROME" --headless --no-sandbox --disable-gpu --disable-quic --no-first-run \
        --disable-background-networking --disable-component-update --disable-sync \
        --disable-dev-shm-usage --user-data-dir="$(mktemp -d "$tmp/chrome.XXXXXX")" "$@" 2>>"$tmp/chrome.err"
}
dump() {    # dump URL OUT [budget ms]
    chrome --virtual-time-budget="${3:-4000}" --dump-dom "$1" > "$2"
}

# serve NAME PORT param...: start the server, wait until it serves.
serve() {
    name=$1; port=$2; shift 2
    rm -f "$tmp/$name.url"
    "$SRV" --name "viewer-$name" --param http_port="$port" --param url_file="$tmp/$name.url" "$@" \
        > "$tmp/$name.log" 2>&1 &
    last_pid=$!
    pids="$pids $last_pid"
    wait_for 15 test -s "$tmp/$name.url"
}
has() { grep -q -- "$1" "$2"; }
attr() { sed -n "s/.*<body[^>]*$1=\"\([^\"]*\)\".*/\1/p" "$2" | head -1; }
ge() { [ "${1:-0}" -ge "$2" ] 2>/dev/null; }

if [ -z "$CHROME" ]; then
    echo "chromium is not installed (scripts/install-deps.sh browser)"
    check "chromium installed" false
    finish
fi

"$GEN" log "$tmp/demo.lcmlog" --seconds 45
"$GEN" log "$tmp/bad.lcmlog" --seconds 20 --corrupt
head -c 50000 /dev/urandom > "$tmp/noise.lcmlog"

# ---- a recorded demo log, scrubbed to 30 s and paused
check "server plays the demo log" serve demo 8101 --param log="$tmp/demo.lcmlog"
dump "http://127.0.0.1:8101/?t=30&paused=1" "$tmp/demo.html" 5000
d=$tmp/demo.html
check "page connected in log mode" test "$(attr data-mode "$d")" = log -a "$(attr data-connected "$d")" = 1
check "map drawn" test "$(attr data-map-drawn "$d")" = 1
check "estimated and true pose drawn" test "$(attr data-pose "$d")" = 1 -a "$(attr data-truth "$d")" = 1
check "laser, particles, path and goals drawn" sh -c "[ $(attr data-laser "$d") -ge 1 ] && [ $(attr data-particles "$d") -ge 100 ] && [ $(attr data-path "$d") -ge 2 ] && [ $(attr data-goals "$d") -ge 4 ]"
check "timeline holds every decision of the log (226)" test "$(attr data-decisions "$d")" = 226
check "decision list shows 30 decisions up to 30 s" test "$(grep -o '<li data-winner=' "$d" | wc -l)" -eq 30
check "decision list names the winners" has '<li data-winner="follow_path"' "$d"
check "winner's reason is shown" has 'tracking path' "$d"
check "votes of every behaviour in the decision panel" sh -c "grep -q '<td>estop</td>' $d && grep -q '<td>teleop</td>' $d && grep -q '<td>avoid</td>' $d"
check "five components from heartbeats" test "$(attr data-components "$d")" = 5
check "planner restart counted" has 'data-component="planner" data-restarts="1"' "$d"
check "mission events up to 30 s: 4 goals reached" test "$(grep -o 'data-kind="goal_reached"' "$d" | wc -l)" -eq 4
check "no error banner" has 'id="banner" class="banner hidden"' "$d"
check "log time shown" has '30.0 s / 45.0 s' "$d"

# scrubbing to the e-stop: the current decision is the e-stop's
dump "http://127.0.0.1:8101/?t=12.5&paused=1" "$tmp/estop.html" 4000
check "seek to 12.5 s: e-stop won the current decision" \
    test "$(grep -o '<li data-winner="[a-z_]*"' "$tmp/estop.html" | head -1)" = '<li data-winner="estop"'
check "seek to 12.5 s: 2 goals reached so far" test "$(grep -o 'data-kind="goal_reached"' "$tmp/estop.html" | wc -l)" -eq 2

chrome --virtual-time-budget=5000 --window-size=1280,900 --screenshot="$B/viewer.png" \
    "http://127.0.0.1:8101/?t=30&paused=1" > /dev/null
check "screenshot saved ($B/viewer.png)" sh -c "[ \$(stat -c %s $B/viewer.png) -gt 20000 ]"

# ---- corrupt and foreign logs: a message on the page, the rest still shown
check "server plays a corrupt log" serve bad 8102 --param log="$tmp/bad.lcmlog"
dump "http://127.0.0.1:8102/?t=5&paused=1" "$tmp/bad.html" 4000
check "corrupt log: banner names the corrupt records" grep -Eq 'log has [0-9]+ corrupt record' "$tmp/bad.html"
check "corrupt log: map and decisions still shown" \
    sh -c "[ $(attr data-map-drawn "$tmp/bad.html") = 1 ] && [ $(attr data-decisions "$tmp/bad.html") -ge 90 ]"
check "server reads random bytes as a log" serve noise 8103 --param log="$tmp/noise.lcmlog"
dump "http://127.0.0.1:8103/" "$tmp/noise.html" 3000
check "random bytes: 'no readable records' banner" has 'log has no readable records' "$tmp/noise.html"
check "random bytes: the page is laid out, not blank" has 'id="components"' "$tmp/noise.html"

# ---- a lost server: the page says so and keeps retrying
python3 -m http.server 8104 --bind 127.0.0.1 --directory tools/viewer/www > /dev/null 2>&1 &
pids="$pids $!"
wait_for 10 sh -c "python3 -c \"import urllib.request; urllib.request.urlopen('http://127.0.0.1:8104/')\""
dump "http://127.0.0.1:8104/" "$tmp/lost.html" 3000
check "no WebSocket server: 'connection lost, retrying' banner" has 'connection lost, retrying' "$tmp/lost.html"
check "no WebSocket server: page marked disconnected" test "$(attr data-connected "$tmp/lost.html")" = 0

# ---- live: publishers on the bus
check "server follows the bus" serve live 8105
"$GEN" live --seconds 12 > /dev/null 2>&1 &
gen=$!
pids="$pids $gen"
sleep 2
dump "http://127.0.0.1:8105/" "$tmp/live.html" 3000
l=$tmp/live.html
check "live: page in live mode" test "$(attr data-mode "$l")" = live
check "live: map, poses and laser from the bus" \
    sh -c "[ $(attr data-map-drawn "$l") = 1 ] && [ $(attr data-pose "$l") = 1 ] && [ $(attr data-truth "$l") = 1 ] && [ $(attr data-laser "$l") -ge 1 ]"
check "live: decisions arrive" sh -c "[ $(attr data-decisions "$l") -ge 5 ] && grep -q '<li data-winner=' $l"
check "live: components from heartbeats (and the viewer itself)" sh -c "[ $(attr data-components "$l") -ge 6 ]"
kill "$gen" 2>/dev/null

# ---- live: the simulator's ground truth and laser on the office map
if [ -x "$BIN/marie-sim" ]; then
    "$BIN/marie-sim" --name sim --param speed=1 > "$tmp/sim.log" 2>&1 &
    pids="$pids $!"
    check "server follows the sim" serve sim 8106 --param map=sim/worlds/office.yaml
    sleep 2
    dump "http://127.0.0.1:8106/" "$tmp/sim.html" 3000
    s=$tmp/sim.html
    check "sim: office map from the map file" test "$(attr data-map-drawn "$s")" = 1
    check "sim: true pose and laser from marie-sim" \
        sh -c "[ $(attr data-truth "$s") = 1 ] && [ $(attr data-laser "$s") -ge 1 ]"
    check "sim: the simulator in the components table" has 'data-component="sim"' "$s"
fi
finish
