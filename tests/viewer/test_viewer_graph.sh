#!/bin/sh
# test-light
# test_viewer_graph: the system graph page in headless Chromium against a real marie-am: hosts,
# components, ports and the channel between them with its live rate; a click on a component
# and on Restart (the PIN given in the address, as marie view prints it) sends a signed order that
# the manager obeys.
. tests/lib.sh
T=$(mktemp -d /tmp/marie-test-graph.XXXXXX)
export MARIE_KEY=$T/key MARIE_SEQ_FILE=$T/seq
OUT=$T
cleanup() {
    "$BIN/marie" down > /dev/null 2>&1
    stop_started
    rm -rf "$T"
}
trap cleanup EXIT INT TERM
CHROME=$(command -v chromium || command -v chromium-browser || true)
[ -n "$CHROME" ] || { echo "chromium missing (scripts/install-deps.sh browser)"; exit 1; }

"$BIN/marie" keygen "$T/key"
start am "$BIN/marie-am" --host alpha --state-dir "$T/am"
sleep 0.3
setup "system up under marie-am" "$BIN/marie" up tests/data/viewer/graph.yaml
"$BIN/marie-viewer-server" --name viewer --param http_port=8121 --param key_file="$T/key" --param pin=27182818 \
    --param url_file="$T/url" > "$T/viewer.log" 2>&1 &
pids="$pids $!"
setup "viewer serves" wait_for 10 test -s "$T/url"
CDP=9224
"$CHROME" --headless --no-sandbox --disable-gpu --no-first-run --disable-background-networking \
    --disable-component-update --disable-sync --disable-dev-shm-usage --user-data-dir="$T/chrome" \
    --remote-debugging-port=$CDP about:blank > "$T/chrome.log" 2>&1 &
pids="$pids $!"
setup "chromium" wait_for 30 python3 -c "import urllib.request; urllib.request.urlopen('http://127.0.0.1:$CDP/json/version')"

drawn="document.body.dataset.components === '2' && document.body.dataset.channels >= 1 &&
  [...document.querySelectorAll('[data-channel=EXAMPLE] ~ text')].some((t) => /^marie\\.counter_t +[1-9][0-9.]* msg\\/s/.test(t.textContent))"
edges="[...document.querySelectorAll('#graph path.edge-out')].length >= 1 && [...document.querySelectorAll('#graph path.edge-in')].length >= 1"
click="document.querySelector('[data-comp=walker]').dispatchEvent(new MouseEvent('click', {bubbles: true}));
  setTimeout(() => document.querySelector('#sel-controls button[data-cmd=restart]').click(), 600); true"
restarted="[...document.querySelectorAll('#graph text')].some((t) => /restarts 1 /.test(t.textContent))"
python3 tests/viewer/cdp.py --port $CDP http://127.0.0.1:8121/graph.html --timeout 20 --dom "$T/graph1.html" \
    --until "$drawn && $edges" --screenshot "$T/graph.png" > "$T/cdp1.log" 2>&1
check "graph: host, two components and the EXAMPLE channel with its type and a live rate" [ $? -eq 0 ]
check "graph: a publisher's edge into the channel and a subscriber's edge out of it" \
    grep -q 'class="edge-in"' "$T/graph1.html"
python3 tests/viewer/cdp.py --port $CDP 'http://127.0.0.1:8121/graph.html#pin=27182818' --timeout 20 --dom "$T/graph2.html" \
    --until "$drawn" --do "$click" --until2 "$restarted" > "$T/cdp2.log" 2>&1
check "click walker, Restart: the page shows it restarted once" [ $? -eq 0 ]
ps_restart() { "$BIN/marie" ps | awk '$2 == "walker" { print $6 }' | grep -qx 1; }
check "marie ps agrees: walker restarted once (a signed order from the page)" ps_restart
check "the viewer sent it as a signed order" grep -q "order sent: restart walker" "$T/viewer.log"
mkdir -p "$B/test-logs/viewer-graph" && cp "$T/graph.png" "$B/test-logs/viewer-graph/" 2>/dev/null
finish
