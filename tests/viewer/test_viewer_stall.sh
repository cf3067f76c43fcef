#!/bin/sh
# test-light
# test_viewer_stall: clients that stall do not hold up the others or the server's loop: 40
# connections that send half a request and wait, and 3 pages that open their WebSocket and
# never read (a 2 KB receive window), beside a live page. The page's files are still served
# and a new page still opens at once, the live page's frames keep coming, and the server quits
# cleanly afterwards; a malformed request is counted as bad input. tests/viewer/stall_client.py
# plays the clients.
. tests/lib.sh
T=$(mktemp -d /tmp/marie-test-viewer-stall.XXXXXX)
OUT=$T
trap 'stop_started; rm -rf "$T"' EXIT INT TERM
start gen "$B/tests/bin/viewer-gen" live --seconds 60
start viewer "$BIN/marie-viewer-server" --name viewer --param http_port=8116 --param url_file="$T/url"
viewer=$pid_viewer
setup "viewer serves" wait_for 10 test -s "$T/url"
python3 tests/viewer/stall_client.py 8116 40 3 > "$T/stall.json"
cat "$T/stall.json"
g() { python3 -c "import json, sys; d = json.load(open(sys.argv[1])); print(eval(sys.argv[2]))" "$T/stall.json" "$1"; }
check "the stalled pages were let in" [ "$(g 'd.get("stalled_status")')" = "['HTTP/1.1 101', 'HTTP/1.1 101', 'HTTP/1.1 101']" ]
check "with 40 half requests open, a file is served within 3 s" lt "$(g '99 if d["fetch_s"] is None else d["fetch_s"]')" 3
check "a new page gets its hello within 3 s" lt "$(g '99 if d["page_s"] is None else d["page_s"]')" 3
check "the live page hears the bus: frames, no silence of 2 s" \
    sh -c "[ $(g 'd["live_frames"]') -ge 10 ] && $(command -v python3) -c 'import sys; sys.exit(not float(sys.argv[1]) < 2)' $(g 'd["live_max_gap_s"]')"
# A malformed request: answered 400, and the viewer's heartbeat counts it as bad input.
malformed() {
    python3 -c '
import socket, sys
s = socket.create_connection(("127.0.0.1", 8116), timeout=5)
s.sendall(b"GET / HTTP/1.1\r\nHost: x\r\n folded\r\n\r\n")
sys.exit(0 if s.recv(100).startswith(b"HTTP/1.1 400") else 1)'
}
check "a malformed request is answered 400" malformed
# The viewer's own heartbeat, as a page sees it.
counted() {
    python3 -c '
import sys
sys.path.insert(0, "tests/viewer")
from wsclient import WsClient
c = WsClient("127.0.0.1", 8116, origin="http://127.0.0.1:8116")
hb = lambda m: m.get("ch") == "MARIE_HEARTBEAT" and m["msg"]["component"] == "viewer"
m = c.until(lambda m: hb(m) and m["msg"]["bad_input"] >= 1, 5)
sys.exit(0 if m and {"name": "web_requests", "value": 1} in m["msg"]["counters"] else 1)'
}
check "and counted as the viewer's bad input (web_requests in its heartbeat)" counted
check "with the reason and the address in its log" grep -q "folded header line from 127.0.0.1" "$T/viewer.log"
quits() { kill "$viewer"; wait "$viewer"; rc=$?; [ $rc -eq 0 ] && ! grep -Eq 'Sanitizer|runtime error' "$T/viewer.log" || { tail -20 "$T/viewer.log"; false; }; }
check "the server quits cleanly" quits
finish
