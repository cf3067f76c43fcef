#!/bin/sh
# test-light
# test_viewer_landmarks: tags marie-vision placed in the map (LANDMARKS) are drawn on the
# viewer's map, with what they say. Screenshot: $B/test-logs/viewer-landmarks.png.
. tests/lib.sh
T=$(mktemp -d /tmp/marie-test-vlm.XXXXXX)
pids=""
cleanup() {
    for p in $pids; do kill "$p" 2>/dev/null; done
    for p in $pids; do wait "$p" 2>/dev/null; done
    rm -rf "$T"
}
trap cleanup EXIT INT TERM
CHROME=$(command -v chromium || command -v chromium-browser || true)
CDP=9224
[ -n "$CHROME" ] || { check "chromium installed" false; finish; }
"$CHROME" --headless --no-sandbox --disable-gpu --disable-quic --no-first-run --disable-background-networking \
    --disable-component-update --disable-sync --disable-dev-shm-usage --user-data-dir="$T/chrome" \
    --remote-debugging-port=$CDP about:blank > "$T/chrome.log" 2>&1 &
pids="$pids $!"
setup "headless chromium" wait_for 30 python3 -c "import urllib.request; urllib.request.urlopen('http://127.0.0.1:$CDP/json/version')"
"$BIN/marie-viewer-server" --name viewer --param http_port=8131 --param map=sim/worlds/office.yaml \
    --param url_file="$T/url" > "$T/viewer.log" 2>&1 &
pids="$pids $!"
setup "viewer serves" wait_for 10 test -s "$T/url"
"$B/tests/helpers/face_probe" --watch 30 --landmark "2:12.25:13.51:1.5708:room B" > /dev/null 2>&1 &
pids="$pids $!"
check "the landmark is drawn on the map with its text" \
    python3 tests/viewer/cdp.py --port $CDP http://127.0.0.1:8131/ --timeout 15 \
        --until "document.body.dataset.landmarks === '1' && document.body.dataset.mapDrawn === '1'" \
        --eval "S.landmarks[2].message + '@' + S.landmarks[2].x + ',' + S.landmarks[2].y" --eval-out "$T/lm.json" \
        --screenshot "$B/test-logs/viewer-landmarks.png"
check "at the published place" grep -q '"room B@12.25,13.51"' "$T/lm.json"
finish
