#!/bin/sh
# test-light
# test_viewer_layout: the viewer's page on a laptop's 1280x800 screen (and 1920x1080) with the
# Spartacus robot's 17 components and their managers' CPU: the play button, the timeline and the
# whole components table (its CPU column too) in view without scrolling, the map taking the room
# left. Live, a bus busy only with channels the page does not draw is reported as such ("the bus
# carries 20 msg/s ... EXAMPLE"), not as "waiting for data from the bus"; once drawn data flows
# the banner goes. Screenshots: $B/test-logs/viewer-1280x800.png, viewer-live-1280x800.png.
. tests/lib.sh
T=$(mktemp -d /tmp/marie-test-vlayout.XXXXXX)
pids=""
cleanup() {
    for p in $pids; do kill "$p" 2>/dev/null; done
    for p in $pids; do wait "$p" 2>/dev/null; done
    rm -rf "$T"
}
trap cleanup EXIT INT TERM
CHROME=$(command -v chromium || command -v chromium-browser || true)
CDP=9226
[ -n "$CHROME" ] || { check "chromium installed" false; finish; }
PY=$(scripts/peer-venv.sh) || { echo "[  FAILED  ] setup: peer venv"; exit 1; }
"$CHROME" --headless --no-sandbox --disable-gpu --disable-quic --no-first-run --disable-background-networking \
    --disable-component-update --disable-sync --disable-dev-shm-usage --user-data-dir="$T/chrome" \
    --remote-debugging-port=$CDP about:blank > "$T/chrome.log" 2>&1 &
pids="$pids $!"
setup "headless chromium" wait_for 30 python3 -c "import urllib.request; urllib.request.urlopen('http://127.0.0.1:$CDP/json/version')"
cdp() { python3 tests/viewer/cdp.py --port $CDP "$@"; }

# the synthetic run, with the heartbeats and the managers' status of Spartacus's components added
"$B/tests/bin/viewer-gen" log "$T/gen.lcmlog" --seconds 40
PYTHONPATH=$B/python "$PY" - "$T/gen.lcmlog" "$T/run.lcmlog" <<'PY'
import sys
import lcm
from lcmtypes.marie import am_component_status_t, am_status_t, heartbeat_t
NAMES = ["drives", "gyro", "laser", "odometry", "mailbox", "sharedmap", "vision", "odometer", "estop",
         "xml-bridge", "face", "ros2"]
HOSTS = ["onboard1", "onboard2", "onboard3", "laptop"]
events = [(e.timestamp, e.channel, e.data) for e in lcm.EventLog(sys.argv[1], "r")]
t0 = events[0][0]
for s in range(40):
    t = t0 + s * 1000000
    for i, n in enumerate(NAMES):
        h = heartbeat_t(); h.utime = t; h.component = n; h.host = HOSTS[i % 4]; h.pid = 30000 + i; h.state = 2
        h.reason = ""; h.uptime_us = s * 1000000; h.msgs_in = 123456 + s; h.msgs_out = 654321 + s; h.bad_input = 12
        events.append((t + 1000 + i, "MARIE_HEARTBEAT", h.encode()))
    for k, host in enumerate(HOSTS):
        st = am_status_t(); st.utime = t; st.host = host; st.system = "spartacus"
        for i, n in enumerate(NAMES):
            if i % 4 != k:
                continue
            c = am_component_status_t(); c.name = n; c.group = ""; c.state = "running"; c.pid = 30000 + i
            c.cpu = 12.5 + i; c.config_hash = ""
            st.components.append(c)
        st.ncomponents = len(st.components)
        events.append((t + 2000 + k, "MARIE_AM_STATUS", st.encode()))
log = lcm.EventLog(sys.argv[2], "w", overwrite=True)
for t, ch, data in sorted(events, key=lambda e: e[0]):
    log.write_event(t, ch, data)
log.close()
PY
"$BIN/marie-viewer-server" --name viewer --param http_port=8141 --param log="$T/run.lcmlog" \
    --param url_file="$T/url" > "$T/viewer.log" 2>&1 &
pids="$pids $!"
setup "viewer plays the run" wait_for 10 test -s "$T/url"

# the page's layout, measured where the user sees it
CPU_SHOWN="document.querySelector('#components tr[data-component=drives] td:nth-child(8)').textContent.endsWith('%')"
LAYOUT="(function(){
  var r = function(e){ var b = e.getBoundingClientRect(); return [b.left, b.top, b.right, b.bottom]; };
  var aside = document.querySelector('aside'), map = document.getElementById('map');
  var cells = [].map.call(document.querySelectorAll('#components tr'), function(tr){ return r(tr.children[7]); });
  return {vw: innerWidth, vh: innerHeight, play: r(document.getElementById('play')),
          playDisabled: document.getElementById('play').disabled, timeline: r(document.getElementById('timeline')),
          aside: r(aside), asideScrollW: aside.scrollWidth, asideClientW: aside.clientWidth,
          rows: document.querySelectorAll('#components tbody tr').length, cpu: cells,
          cpuText: document.querySelector('#components tr[data-component=drives] td:nth-child(8)').textContent,
          map: [map.width, map.height], mapBox: r(map), pageScroll: document.documentElement.scrollHeight};
})()"
layout() {
    size=$1
    cdp "http://127.0.0.1:8141/?t=30&paused=1" --size "$size" --timeout 20 \
        --until "document.body.dataset.settled === '1' && +document.body.dataset.components >= 17 && $CPU_SHOWN" --dom "$T/layout-$size.html" \
        --eval "$LAYOUT" --eval-out "$T/layout-$size.json" --screenshot "$B/test-logs/viewer-$size.png" > "$T/cdp-$size.log" 2>&1 || {
        cat "$T/cdp-$size.log"; grep -o 'data-components="[0-9]*"\|<tr data-component="drives".\{0,300\}' "$T/layout-$size.html"; return 1; }
    python3 - "$T/layout-$size.json" "$2" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
d = json.loads(d) if isinstance(d, str) else d
vw, vh = d["vw"], d["vh"]
inside = lambda b: b[0] >= 0 and b[1] >= 0 and b[2] <= vw and b[3] <= vh
print("viewport %dx%d: play %s, timeline %s, aside %s (scroll width %d / %d), %d rows, cpu column right %.0f, map %s" % (
    vw, vh, d["play"], d["timeline"], d["aside"], d["asideScrollW"], d["asideClientW"], d["rows"],
    max(c[2] for c in d["cpu"]), d["map"]))
assert d["rows"] >= 17, "rows"
assert inside(d["play"]) and not d["playDisabled"], "the play button is not in view"
assert inside(d["timeline"]), "the timeline is not in view"
assert d["pageScroll"] <= vh, "the page scrolls"
assert d["asideScrollW"] <= d["asideClientW"], "the side panel scrolls sideways"
assert all(c[2] <= d["aside"][2] for c in d["cpu"]), "the CPU column is clipped"
assert d["cpuText"].endswith("%"), d["cpuText"]
w, h = map(int, sys.argv[2].split("x"))
assert d["map"][0] >= w and d["map"][1] >= h, "the map is smaller than %s" % sys.argv[2]
PY
}
check "1280x800: play button, timeline and every column of 17 components in view; map 760x540 or more" layout 1280x800 760x540
check "1920x1080: the same, and the map grows (1400x800 or more)" layout 1920x1080 1400x800

# live: a producer on a channel the page does not draw, then the synthetic robot's stream
"$BIN/marie-viewer-server" --name viewer-live --param http_port=8142 > "$T/live.log" 2>&1 &
pids="$pids $!"
"$BIN/marie-example-producer" --name producer --param rate_hz=20 > "$T/producer.log" 2>&1 &
pids="$pids $!"
BANNER="document.getElementById('banner').textContent"
check "live, 20 msg/s on EXAMPLE only: the banner says what the bus carries, not 'waiting'" \
    cdp http://127.0.0.1:8142/ --size 1280x800 --timeout 20 \
        --until "document.body.dataset.bus === 'other' && $BANNER.includes('EXAMPLE 20/s (producer)') && !$BANNER.includes('waiting')" \
        --screenshot "$B/test-logs/viewer-live-1280x800.png" --dom "$T/live.html"
"$B/tests/bin/viewer-gen" live --seconds 15 > /dev/null 2>&1 &
pids="$pids $!"
check "once drawn data flows, the banner goes" \
    cdp http://127.0.0.1:8142/ --size 1280x800 --timeout 20 \
        --until "document.body.dataset.bus === 'drawn' && document.getElementById('banner').className === 'banner hidden' && +document.body.dataset.laser >= 1"
finish
