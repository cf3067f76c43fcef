#!/bin/sh
# test-group: robot
# test_viewer: marie-view seen through headless Chromium. A recorded demo log (map, poses,
# laser, particles, path, goals, decision timeline, components and a restart), scrubbing to a
# time, live following of publishers and of the simulator on the bus, corrupt and foreign
# logs, and a lost server: the page always says what is wrong instead of going blank.
. tests/lib.sh
SRV=$BIN/marie-viewer-server
GEN=$B/tests/bin/viewer-gen
tmp=$(mktemp -d)
pids=""
servers=""
cleanup() {
    for p in $pids; do kill "$p" 2>/dev/null; done
    for p in $pids; do wait "$p" 2>/dev/null; done
    rm -rf "$tmp"
}
trap cleanup EXIT INT TERM

CHROME=$(command -v chromium || command -v chromium-browser || true)
CDP=9222
# One headless Chromium for the whole test, started as a user would run it, with nothing
# reaching out to the network; pages are driven over its DevTools port (tests/viewer/cdp.py)
# so every check waits, in real time, for the state the page reports.
start_chrome() {
    "$CHROME" --headless --no-sandbox --disable-gpu --disable-quic --no-first-run \
        --disable-background-networking --disable-component-update --disable-sync \
        --disable-dev-shm-usage --user-data-dir="$tmp/chrome" --remote-debugging-port=$CDP \
        about:blank > "$tmp/chrome.log" 2>&1 &
    pids="$pids $!"
    wait_for 30 python3 -c "import urllib.request; urllib.request.urlopen('http://127.0.0.1:$CDP/json/version')"
}
# page URL OUT [JS condition] [more cdp.py options]: the DOM once the condition holds
page() {
    url=$1; out=$2; shift 2
    cond=${1:-"document.body.dataset.settled === '1'"}
    [ $# -gt 0 ] && shift
    python3 tests/viewer/cdp.py --port $CDP "$url" --dom "$out" --until "$cond" --timeout 20 "$@"
}

# serve NAME PORT param...: start the server, wait until it serves.
serve() {
    name=$1; port=$2; shift 2
    rm -f "$tmp/$name.url"
    "$SRV" --name "viewer-$name" --param http_port="$port" --param url_file="$tmp/$name.url" "$@" \
        > "$tmp/$name.log" 2>&1 &
    last_pid=$!
    pids="$pids $last_pid"
    servers="$servers $name:$last_pid"
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
# the demo's own log: a short run of marie-demo (the robot application under the managers, as
# make demo runs it) recorded meanwhile, in a network namespace of its own (the live checks
# below follow this one's bus), or VIEWER_DEMO_LOG; no log is a failure, never a skip
demo_log=${VIEWER_DEMO_LOG:-}
demo_pid=
if [ -z "$demo_log" ]; then
    demo_log=$tmp/realdemo/demo.lcm
    env -u MARIE_IN_NETNS scripts/netns-run "$BIN/marie-demo" --quiet --out "$tmp/realdemo" --timeout 15 \
        > "$tmp/realdemo.txt" 2>&1 &
    demo_pid=$!
    pids="$pids $demo_pid"
fi

setup "headless chromium with a DevTools port" start_chrome

"$GEN" log "$tmp/demo.lcmlog" --seconds 45 --truth "$tmp/demo.truth"
"$GEN" log "$tmp/bad.lcmlog" --seconds 20 --corrupt
head -c 50000 /dev/urandom > "$tmp/noise.lcmlog"

# ---- a recorded demo log, scrubbed to 30 s and paused
check "server plays the demo log" serve demo 8101 --param log="$tmp/demo.lcmlog"
check "page settles at 30 s of the log" page "http://127.0.0.1:8101/?t=30&paused=1" "$tmp/demo.html"
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
check "tag detections listed" has '<div id="tags">front: ' "$d"

# scrubbing to the e-stop: the current decision is the e-stop's
page "http://127.0.0.1:8101/?t=12.5&paused=1" "$tmp/estop.html"
check "seek to 12.5 s: e-stop won the current decision" \
    test "$(grep -o '<li data-winner="[a-z_]*"' "$tmp/estop.html" | head -1)" = '<li data-winner="estop"'
check "seek to 12.5 s: 2 goals reached so far" test "$(grep -o 'data-kind="goal_reached"' "$tmp/estop.html" | wc -l)" -eq 2

# the picture itself: the robot and its laser points at the pixels the log's true pose maps to
page "http://127.0.0.1:8101/?t=30&paused=1" "$tmp/shot.html" "" --screenshot "$B/viewer.png" --size 1280x900 \
    --eval "(function(){const c=document.getElementById('map'),r=c.getBoundingClientRect();return [r.left+c.clientLeft,r.top+c.clientTop,c.clientWidth,c.clientHeight]})()" \
    --eval-out "$tmp/canvas.json"
check "screenshot shows the true pose and laser points where they are ($B/viewer.png)" \
    python3 tests/viewer/png_check.py "$B/viewer.png" "$tmp/canvas.json" "$tmp/demo.truth" 30

# play, speed and pause as the page's buttons send them
playback() {
    python3 - <<'PY'
import sys
sys.path.insert(0, "tests/viewer")
from wsclient import WsClient
c = WsClient("127.0.0.1", 8101)
p = c.until(lambda m: m["type"] == "player")
c.send({"op": "seek", "t": p["t0"]})
c.send({"op": "speed", "v": 20})
c.send({"op": "play"})
a = c.until(lambda m: m["type"] == "player" and m["playing"] and m["speed"] == 20)
b = c.until(lambda m: m["type"] == "player" and m["playing"] and m["t"] > a["t"] + 2e6, 10)
arb = c.until(lambda m: m.get("k") == "arb", 5)
c.send({"op": "pause"})
z = c.until(lambda m: m["type"] == "player" and not m["playing"])
print(a and a["t"], b and b["t"], z and z["t"], arb and arb["msg"]["winner"])
sys.exit(0 if a and b and z and arb and z["t"] >= b["t"] else 1)
PY
}
check "play at 20x streams decisions, pause stops" playback

# ---- the launcher: marie view LOG --port N prints the URL and serves the page
"$BIN/marie" view "$tmp/demo.lcmlog" --port 8107 --paused > "$tmp/launcher.out" 2>&1 &
pids="$pids $!"
check "marie view prints the URL" wait_for 10 grep -q 'playing .*demo.lcmlog at http://127.0.0.1:8107/' "$tmp/launcher.out"
check "marie view serves the page" python3 -c "import urllib.request; assert b'marie viewer' in urllib.request.urlopen('http://127.0.0.1:8107/').read()"

# ---- corrupt and foreign logs: a message on the page, the rest still shown
check "server plays a corrupt log" serve bad 8102 --param log="$tmp/bad.lcmlog"
page "http://127.0.0.1:8102/?t=5&paused=1" "$tmp/bad.html"
check "corrupt log: banner names the corrupt records" grep -Eq 'log has [0-9]+ corrupt record' "$tmp/bad.html"
check "corrupt log: map and decisions still shown" \
    sh -c "[ $(attr data-map-drawn "$tmp/bad.html") = 1 ] && [ $(attr data-decisions "$tmp/bad.html") -ge 90 ]"
check "server reads random bytes as a log" serve noise 8103 --param log="$tmp/noise.lcmlog"
page "http://127.0.0.1:8103/" "$tmp/noise.html"
check "random bytes: 'no readable records' banner" has 'log has no readable records' "$tmp/noise.html"
check "random bytes: the page is laid out, not blank" has 'id="components"' "$tmp/noise.html"

missing() {
    "$SRV" --name viewer-missing --param log=/nonexistent.lcmlog --param http_port=8109 > "$tmp/missing.log" 2>&1
    rc=$?; cat "$tmp/missing.log"
    [ $rc -eq 1 ] && grep -q 'log /nonexistent.lcmlog: No such file' "$tmp/missing.log" && ! grep -Eq 'Sanitizer|runtime error' "$tmp/missing.log"
}
check "missing log: the server exits 1 with the reason" missing

# ---- a lost server: the page says so and keeps retrying
python3 -m http.server 8104 --bind 127.0.0.1 --directory tools/viewer/www > /dev/null 2>&1 &
pids="$pids $!"
wait_for 10 sh -c "python3 -c \"import urllib.request; urllib.request.urlopen('http://127.0.0.1:8104/')\""
page "http://127.0.0.1:8104/" "$tmp/lost.html" "document.getElementById('banner').textContent.includes('connection lost')"
check "no WebSocket server: 'connection lost, retrying' banner" has 'connection lost, retrying' "$tmp/lost.html"
check "no WebSocket server: page marked disconnected" test "$(attr data-connected "$tmp/lost.html")" = 0

# a server that dies under a connected page
setup "server to be killed" serve doomed 8108 --param log="$tmp/demo.lcmlog"
doomed=$last_pid
servers=$(echo "$servers" | sed "s/ doomed:$doomed//")
check "server killed under the page: 'connection lost' banner" \
    page "http://127.0.0.1:8108/" "$tmp/killed.html" "" --then "kill -9 $doomed" \
    --until2 "document.body.dataset.connected === '0' && document.getElementById('banner').textContent.includes('connection lost, retrying')"
check "killed server: the last picture stays on the page" test "$(attr data-map-drawn "$tmp/killed.html")" = 1

# ---- live: publishers on the bus
check "server follows the bus" serve live 8105
"$GEN" live --seconds 12 > /dev/null 2>&1 &
gen=$!
pids="$pids $gen"
l=$tmp/live.html
page "http://127.0.0.1:8105/" "$l" "document.body.dataset.settled === '1' && +document.body.dataset.laser >= 1 && +document.body.dataset.truth === 1 && +document.body.dataset.decisions >= 5 && +document.body.dataset.components >= 6 && document.body.dataset.mapDrawn === '1'"
check "live: page in live mode" test "$(attr data-mode "$l")" = live
check "live: map, poses and laser from the bus" \
    sh -c "[ $(attr data-map-drawn "$l") = 1 ] && [ $(attr data-pose "$l") = 1 ] && [ $(attr data-truth "$l") = 1 ] && [ $(attr data-laser "$l") -ge 1 ]"
check "live: decisions arrive" sh -c "[ $(attr data-decisions "$l") -ge 5 ] && grep -q '<li data-winner=' $l"
check "live: components from heartbeats (and the viewer itself)" sh -c "[ $(attr data-components "$l") -ge 6 ]"
kill "$gen" 2>/dev/null
check "live: publishers gone, 'no data from the bus' banner" \
    page "http://127.0.0.1:8105/" "$tmp/quiet.html" "document.getElementById('banner').textContent.includes('no data from the bus')"

# ---- live: the simulator's ground truth and laser on the office map
if [ -x "$BIN/marie-sim" ]; then
    "$BIN/marie-sim" --name sim --param speed=1 > "$tmp/sim.log" 2>&1 &
    pids="$pids $!"
    check "server follows the sim" serve sim 8106 --param map=sim/worlds/office.yaml
    s=$tmp/sim.html
    page "http://127.0.0.1:8106/" "$s" "document.body.dataset.settled === '1' && +document.body.dataset.laser >= 1 && document.body.dataset.truth === '1' && document.querySelector('tr[data-component=sim]') !== null"
    check "sim: office map from the map file" test "$(attr data-map-drawn "$s")" = 1
    check "sim: true pose and laser from marie-sim" \
        sh -c "[ $(attr data-truth "$s") = 1 ] && [ $(attr data-laser "$s") -ge 1 ]"
    check "sim: the simulator in the components table" has 'data-component="sim"' "$s"
fi

# ---- the demo's own log, recorded meanwhile
[ -n "$demo_pid" ] && wait "$demo_pid"
check "the demo's log recorded ($demo_log)" test -s "$demo_log"
check "server plays the demo's log" serve real 8110 --param log="$demo_log" --param map=sim/worlds/office.yaml
page "http://127.0.0.1:8110/?t=20&paused=1" "$tmp/real.html"
r=$tmp/real.html
check "demo log: map, poses and laser drawn" \
    sh -c "[ \"$(attr data-map-drawn "$r")\" = 1 ] && [ \"$(attr data-pose "$r")\" = 1 ] && [ \"$(attr data-laser "$r")\" -ge 1 ]"
check "demo log: decisions on the timeline and in the list" \
    sh -c "[ \"$(attr data-decisions "$r")\" -ge 10 ] && grep -q '<li data-winner=' $r"
check "demo log: components from heartbeats" sh -c "[ \"$(attr data-components "$r")\" -ge 3 ]"

# every server quits cleanly on SIGTERM (under SAN=1: no sanitizer report, no leak)
clean_exit() {
    for s in $servers; do
        n=${s%%:*}; p=${s#*:}
        kill "$p" 2>/dev/null
        wait "$p"; rc=$?
        if [ "$rc" -ne 0 ] || grep -Eq 'Sanitizer|runtime error' "$tmp/$n.log"; then
            echo "server $n: exit $rc"; tail -30 "$tmp/$n.log"; return 1
        fi
    done
}
check "servers quit cleanly" clean_exit
finish
