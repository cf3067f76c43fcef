#!/bin/sh
# test-light
# test_viewer_stall: clients that stall do not hold up the others or the server's loop: 40
# connections that send half a request and wait, and 3 pages that open their WebSocket and
# never read (a 2 KB receive window), beside a live page. The page's files are still served
# and a new page still opens at once, the live page's frames keep coming, and the server quits
# cleanly afterwards. tests/viewer/stall_client.py plays the clients.
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
check "with 40 half requests open, a file is served within 3 s" lt "$(g 'd["fetch_s"] or 99')" 3
check "a new page gets its hello within 3 s" lt "$(g 'd["page_s"] or 99')" 3
check "the live page hears the bus: frames, no silence of 2 s" \
    sh -c "[ $(g 'd["live_frames"]') -ge 10 ] && $(command -v python3) -c 'import sys; sys.exit(not float(sys.argv[1]) < 2)' $(g 'd["live_max_gap_s"]')"
quits() { kill "$viewer"; wait "$viewer"; rc=$?; [ $rc -eq 0 ] && ! grep -Eq 'Sanitizer|runtime error' "$T/viewer.log" || { tail -20 "$T/viewer.log"; false; }; }
check "the server quits cleanly" quits
finish
