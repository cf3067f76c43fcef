#!/bin/sh
# test-light
# test_viewer_controls: the viewer's controls go through the managers: pause and resume a
# component with orders signed by the shared key (a real marie-am obeys them), set a goal;
# without a key the controls are refused; foreign web origins cannot open the WebSocket; a
# local script that is not a browser (no Origin) but has no PIN is refused, and so is a wrong
# PIN. Eight pages at most are open at once (WEBSERVE_MAX_PAGES): the
# ninth is refused while the page's files are still served, and a page that closes makes room.
. tests/lib.sh
T=$(mktemp -d /tmp/marie-test-viewer.XXXXXX)
export MARIE_KEY=$T/key MARIE_SEQ_FILE=$T/seq
OUT=$T
cleanup() {
    "$BIN/marie" down > /dev/null 2>&1
    stop_started
    rm -rf "$T"
}
trap cleanup EXIT INT TERM

"$BIN/marie" keygen "$T/key"
start am "$BIN/marie-am" --host alpha --state-dir "$T/am"
sleep 0.3
check "system up under marie-am" "$BIN/marie" up tests/data/viewer/controls.yaml

# The mission obeys the page's goal requests (signed with the key); its goal comes back to the page.
"$BIN/marie-mission" --name mission --param sharedmap=false --param key_file="$T/key" \
    --param 'goals=[{name: waiting, x: 50, y: 50}]' > "$T/mission.log" 2>&1 &
pids="$pids $!"
"$BIN/marie-viewer-server" --name viewer --param http_port=8111 --param key_file="$T/key" \
    --param url_file="$T/url" > "$T/viewer.log" 2>&1 &
viewer1=$!
pids="$pids $!"
check "viewer serves with a key" wait_for 10 test -s "$T/url"
PIN=$(sed -n 's|^marie-view: following the bus at http://127.0.0.1:8111/#pin=\([0-9]\{10\}\)$|\1|p' "$T/viewer.log")
check "it prints the page's address with a random 10-digit PIN" test -n "$PIN"
# A script on this host, no browser (so no Origin), as the peers that found the hole: an order
# and a goal without a PIN, then with a wrong one; nothing may reach the bus.
intruder() {
    python3 - "$1" <<'PY'
import sys
sys.path.insert(0, "tests/viewer")
from wsclient import WsClient
c = WsClient("127.0.0.1", 8111)
c.until(lambda m: m["type"] == "hello")
extra = {"pin": sys.argv[1]} if sys.argv[1] else {}
c.send(dict({"op": "order", "cmd": "pause", "target": "walker"}, **extra))
a = c.until(lambda m: m["type"] == "notice")
c.send(dict({"op": "goal", "x": 9, "y": 9}, **extra))
b = c.until(lambda m: m["type"] == "notice")
print(a, b)
sys.exit(0 if a and b and a["text"].startswith(("wrong PIN", "too soon")) and
         b["text"].startswith(("wrong PIN", "too soon")) else 1)
PY
}
check "a local script without a PIN: its order and goal are refused" intruder ""
check "with a wrong PIN too" intruder 0000000000
check "nothing reached the bus: walker still running" sh -c "\"$BIN/marie\" ps | grep walker | grep -q running"
check "and the viewer sent no order" sh -c "! grep -q 'order sent' '$T/viewer.log'"
sleep 4     # past the wait wrong PINs impose on this address (1 s, then 2 s)
check "pause, resume and goal from the page" python3 tests/viewer/controls_client.py 8111 "$PIN"
check "the mission accepted the viewer's signed goal request" grep -q "request_accepted.*viewer" "$T/mission.log"
check "marie ps agrees: walker running" sh -c "\"$BIN/marie\" ps | grep walker | grep -q running"

"$BIN/marie-viewer-server" --name viewer2 --param http_port=8112 --param url_file="$T/url2" > "$T/viewer2.log" 2>&1 &
viewer2=$!
pids="$pids $!"
wait_for 10 test -s "$T/url2"
refused() {
    python3 - <<'PY'
import sys
sys.path.insert(0, "tests/viewer")
from wsclient import WsClient
c = WsClient("127.0.0.1", 8112)
c.until(lambda m: m["type"] == "hello")
c.send({"op": "order", "cmd": "pause", "target": "walker"})
m = c.until(lambda m: m["type"] == "notice")
print(m)
sys.exit(0 if m and "controls are disabled" in m["text"] else 1)
PY
}
check "without a key the controls are refused" refused
pages() {
    python3 - <<'PY'
import sys, time, urllib.request
sys.path.insert(0, "tests/viewer")
from wsclient import WsClient
def page():
    c = WsClient("127.0.0.1", 8112, origin="http://127.0.0.1:8112")
    return c if c.until(lambda m: m["type"] == "hello") else None
def refused():
    try:
        c = WsClient("127.0.0.1", 8112, origin="http://127.0.0.1:8112")
        return c.until(lambda m: m["type"] == "hello", 2) is None
    except (ConnectionError, OSError):
        return True
open_ = [page() for _ in range(8)]
ok = all(open_)
print("8 pages open:", ok)
r = refused()
print("the ninth refused:", r)
html = urllib.request.urlopen("http://127.0.0.1:8112/", timeout=5).status == 200
print("the page's files still served:", html)
open_.pop().close()
again = None
for _ in range(20):
    time.sleep(0.1)
    try:
        again = page()
    except (ConnectionError, OSError):
        again = None
    if again:
        break
print("a page closed, another opens:", bool(again))
sys.exit(0 if ok and r and html and again else 1)
PY
}
check "eight pages at once: the ninth refused, files still served, a closed page makes room" pages
check "walker still running" sh -c "\"$BIN/marie\" ps | grep walker | grep -q running"
quits() { kill "$1"; wait "$1"; rc=$?; [ $rc -eq 0 ] && ! grep -Eq 'Sanitizer|runtime error' "$2" || { tail -20 "$2"; false; }; }
quits "$viewer1" "$T/viewer.log" && quits "$viewer2" "$T/viewer2.log"
check "viewers quit cleanly (exit 0, no sanitizer report)" test $? -eq 0
finish
