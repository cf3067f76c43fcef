#!/bin/sh
# test-light
# test_map_updates: marie-mapper sends a large map whole only now and then and the rectangles
# that changed in between (MAP_UPDATE); its readers assemble them. A short route in marie-sim
# with the threshold at one cell (every map is "large"), recorded with lcm-logger: the whole
# maps and the updates, assembled as a reader does, give cell for cell the map the mapper sends
# whole once the robot stands still; the updates are a fraction of the bytes; the planner and
# marie-explore apply them (marie-explore killed and restarted mid-route too), and the viewer
# serves the map they make (docs/mapping.md, "Map updates").
. tests/lib.sh
B=${B:-build}
BIN=$B/bin
OUT=$B/test-logs/map_updates
rm -rf "$OUT" && mkdir -p "$OUT"
export LCM_DEFAULT_URL="udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608"
trap stop_started EXIT INT TERM

start logger lcm-logger -q --lcm-url="$LCM_DEFAULT_URL" "--channel=^(MAP|MAP_UPDATE|MARIE_HEARTBEAT)$" "$OUT/run.lcm"
start sim $BIN/marie-sim --name sim --param world=sim/worlds/office.yaml --param speed=4 --param lockstep=0.5 --param start_y=15.7
start odometry $BIN/marie-odometry --name odometry --clock sim
start mapper $BIN/marie-mapper --name mapper --clock sim --param init_x=2 --param init_y=15.7 \
    --param update_cells=1 --param republish_s=4
start planner $BIN/marie-planner --name planner --clock sim --param unknown_is_free=true
start explore $BIN/marie-explore --name explore --clock sim
start viewer $BIN/marie-viewer-server --name viewer --param http_port=8131 --param url_file="$OUT/viewer.url"
$B/tests/helpers/route_driver --route "4.1,15.7;4.1,21.5;4.1,15.7;9.0,15.7" --timeout 90 --hold 3 > "$OUT/driver.txt" 2>&1 &
drv=$!
# Kill it and see: marie-explore dies mid-route and comes back; updates it hears before the next
# whole map are for a map it does not hold (counted, waited out), then it applies them again.
sleep 6
kill -9 "$pid_explore"
wait "$pid_explore" 2>/dev/null
start explore2 $BIN/marie-explore --name explore --clock sim
wait "$drv"
drc=$?
cat "$OUT/driver.txt"
# (--hold: standing still, the last changes go out as an update, then the whole map again after
# republish_s of simulated time, at speed 4, and heartbeats.)
sleep 1
# What the viewer gives a page that opens now: width, height, occupied and known cells.
python3 - > "$OUT/page.txt" 2>&1 <<'PY'
import base64, sys
sys.path.insert(0, "tests/viewer")
from wsclient import WsClient
m = WsClient("127.0.0.1", 8131).until(lambda f: f.get("k") == "map", 5)
c = [v - 256 if v > 127 else v for v in base64.b64decode(m["msg"]["cells"])] if m else []    # int8, base64
print("page", m and m["msg"]["width"], m and m["msg"]["height"], "occupied", sum(v >= 65 for v in c),
      "known", sum(v >= 0 for v in c))
PY
stop_started
pids=""

$B/tests/helpers/map_updates_check "$OUT/run.lcm" planner explore viewer > "$OUT/check.txt" 2>&1
crc=$?
cat "$OUT/check.txt" "$OUT/page.txt"
fig() { awk -v k="$2" '{ for (i = 1; i < NF; i++) if ($i == k) { print $(i + 1); exit } }' "$1"; }
val() { awk -v k="$2" '$1 == k { print $2; f = 1 } END { if (!f) print 0 }' "$1"; }

check "the route is driven to its end with the mapper live" test "$drc" -eq 0
check "the log is read" test "$crc" -eq 0
check "the map goes as updates between whole maps (>= 5 updates, >= 2 whole)" \
    eval 'test "$(fig $OUT/check.txt updates)" -ge 5 && test "$(fig $OUT/check.txt whole)" -ge 2'
check "every update is well formed and inside its map" test "$(fig $OUT/check.txt refused)" -eq 0
# (the last whole map in the frame of the one before: one that grew comes in a new frame)
check "the updates since the last whole map rebuild it cell for cell (>= 2 compared)" \
    eval 'test "$(fig $OUT/check.txt last_diff)" -eq 0 && test "$(fig $OUT/check.txt compared)" -ge 2'
check "an update is on average under a quarter of a whole map" \
    eval 'test $(( $(fig $OUT/check.txt update_bytes) * 4 * $(fig $OUT/check.txt whole) )) -lt $(( $(fig $OUT/check.txt whole_bytes) * $(fig $OUT/check.txt updates) ))'
check "the planner applies them" test "$(val $OUT/check.txt planner.map_updates)" -ge 3
# (explore.map_updates_unmatched: the updates it heard before its first whole map; often 1-3,
# 0 when it came back just before a whole map)
check "marie-explore, restarted mid-route, takes a whole map and applies the updates again" \
    eval 'test "$(val $OUT/check.txt explore.maps)" -ge 1 && test "$(val $OUT/check.txt explore.map_updates)" -ge 3'

check "the viewer applies them" test "$(val $OUT/check.txt viewer.map_updates)" -ge 3
check "no reader refuses one" eval 'test "$(val $OUT/check.txt planner.bad_map_update)" -eq 0 &&
    test "$(val $OUT/check.txt explore.bad_map_update)" -eq 0 && test "$(val $OUT/check.txt viewer.bad_map_update)" -eq 0'
check "a page opened at the end gets the map the updates made" \
    test "$(awk '$1 == "final" { print $2, $3, $4, $5, $6, $7 }' $OUT/check.txt)" = "$(awk '{ print $2, $3, $4, $5, $6, $7 }' $OUT/page.txt)"
finish
