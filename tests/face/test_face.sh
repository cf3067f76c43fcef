#!/bin/sh
# test-light
# test_face: the touch page in a headless Chromium at 800x480 and 1024x600, touch screen
# emulated and tapped with touch events: what the robot heard and said shows once the dialogue
# speaks, and fits; a tap on a place
# becomes a goal request signed by the server, which the mission obeys (it publishes the
# place as its goal); a wrong PIN is refused by the server, unsigned and forged requests on
# the bus by the mission; STOP pauses the configured component through marie-am; the page
# says when the server is gone and reconnects when it is back. Screenshots: $B/test-logs/face.
. tests/lib.sh
T=$(mktemp -d /tmp/marie-test-face.XXXXXX)
SHOTS=$B/test-logs/face
rm -rf "$SHOTS" && mkdir -p "$SHOTS"
export MARIE_KEY=$T/key MARIE_SEQ_FILE=$T/seq
OUT=$T
cleanup() {
    "$BIN/marie" down > /dev/null 2>&1
    [ -s "$T/face2.pid" ] && pids="$pids $(cat "$T/face2.pid")"
    stop_started
    rm -rf "$T"
}
trap cleanup EXIT INT TERM
CHROME=$(command -v chromium || command -v chromium-browser || true)
CDP=9223
if [ -z "$CHROME" ]; then
    check "chromium installed" false
    finish
fi
"$CHROME" --headless --no-sandbox --disable-gpu --disable-quic --no-first-run --disable-background-networking \
    --disable-component-update --disable-sync --disable-dev-shm-usage --user-data-dir="$T/chrome" \
    --remote-debugging-port=$CDP about:blank > "$T/chrome.log" 2>&1 &
pids="$pids $!"
setup "headless chromium" wait_for 30 python3 -c "import urllib.request; urllib.request.urlopen('http://127.0.0.1:$CDP/json/version')"

"$BIN/marie" keygen "$T/key"
start am "$BIN/marie-am" --host alpha --state-dir "$T/am"
# Answering, not just started: a sanitizer build beside the other tests took over 3 s.
setup "marie-am answers" wait_for 20 sh -c '"$0" ps > /dev/null' "$BIN/marie"
check "system up under marie-am" "$BIN/marie" up tests/data/viewer/controls.yaml
"$BIN/marie-mission" --name mission --param sharedmap=false --param key_file="$T/key" \
    --param 'goals=[{name: waiting, x: 50, y: 50}]' > "$T/mission.log" 2>&1 &
pids="$pids $!"
PLACES='places=[{name: kitchen, x: 3.0, y: 4.0}, {name: lab, x: 10.0, y: 2.0, theta: 1.57}]'
face() {
    rm -f "$T/url"
    "$BIN/marie-face" --name face --param http_port=8121 --param key_file="$T/key" --param pin=2468 \
        --param "$PLACES" --param stop_target=walker --param url_file="$T/url" >> "$T/face.log" 2>&1 &
    face_pid=$!
    pids="$pids $face_pid"
    wait_for 10 test -s "$T/url"
}
check "face server serves with a key" face
check "the PIN is printed at start" grep -q "PIN 2468" "$T/face.log"
"$B/tests/helpers/face_probe" --watch 60 --key "$T/key" > "$T/probe.txt" 2>&1 &
probe=$!
pids="$pids $probe"
URL=http://127.0.0.1:8121/
cdp() { python3 tests/viewer/cdp.py --port $CDP "$URL" --timeout 15 "$@"; }
ready="document.body.dataset.conn === '1' && document.querySelectorAll('[data-place]').length === 2 && document.querySelector('.host .light') !== null"
green="document.querySelector('.host[data-host=alpha] .light.green') !== null"
pin() {  # the PIN typed in, once the page is ready
    echo "(($ready) && (document.getElementById('pin').value = '$1', true))"
}
# tap PIN SELECTOR NOTICE [cdp options]: a finger's tap (touch events, touch screen emulated) on
# the element with the PIN typed, then the page must show NOTICE.
tap() {
    p=$1; sel=$2; want=$3; shift 3
    cdp --touch --until "$(pin "$p")" --tap "$sel" --then true \
        --until2 "document.getElementById('notice').textContent === '$want'" "$@"
}
check "nothing heard or said yet: the conversation panel stays hidden" \
    cdp --size 800x480 --until "$ready && document.getElementById('talk').hidden && document.getElementById('talk').offsetHeight === 0"
HEARD="go to the lab please" SAID="I am going to the lab"
"$B/tests/helpers/face_probe" --heard "$HEARD" --said "$SAID" --watch 0.2 > /dev/null 2>&1
talked="document.querySelector('#talk .line.heard') !== null && document.querySelector('#talk .line.heard').textContent === '$HEARD' && document.querySelector('#talk .line.said').textContent === '$SAID'"
check "the page shows what the robot heard and what it said" cdp --size 800x480 --until "$ready && $talked"
# layout: [nothing scrolls, STOP >= 80 px, a place >= 60 px, the conversation inside the
# screen, 200 px wide or more, its words 18 px or more, both lines whole]
layout="(function(){var s=document.getElementById('stop').getBoundingClientRect(), t=document.getElementById('talk').getBoundingClientRect(), l=document.querySelectorAll('#talk .line'); \
return [document.documentElement.scrollHeight <= innerHeight && document.documentElement.scrollWidth <= innerWidth, s.height >= 80, \
document.querySelector('.place').getBoundingClientRect().height >= 60, t.top >= 0 && t.bottom <= innerHeight && t.right <= innerWidth, t.width >= 200, \
parseFloat(getComputedStyle(l[0]).fontSize) >= 18, [].every.call(l, function(e){var w=e.querySelector('.words'); return e.getBoundingClientRect().bottom <= t.bottom && w.scrollHeight <= w.clientHeight + 1})]})()"
for size in 800x480 1024x600; do
    check "page at $size: places, host light, the conversation; screenshot" \
        cdp --size $size --until "$ready && $green && $talked" --screenshot "$SHOTS/face-$size.png" \
            --eval "$layout" --eval-out "$T/layout-$size.json"
    check "at $size everything fits without scrolling, STOP and places are finger-sized, the conversation readable" \
        grep -q '\[true, true, true, true, true, true, true\]' "$T/layout-$size.json"
done

check "a tap on 'lab' with the PIN: the page says it is going" \
    tap 2468 '[data-place="1"]' 'going to lab' --size 800x480 --screenshot "$SHOTS/face-tapped.png"
check "the goal request on the bus is signed with the key" wait_for 10 grep -q "request lab (10.00, 2.00) from .*/face: signed" "$T/probe.txt"
check "the mission obeys it: the place is its goal" wait_for 10 grep -q "^goal lab (10.00, 2.00)" "$T/probe.txt"
check "the mission says who asked" wait_for 5 grep -q "request_accepted.*lab" "$T/mission.log"

check "a wrong PIN is refused by the server" tap 1111 '[data-place="0"]' 'wrong PIN: try again in 1 s' --size 1024x600
sleep 1.5   # the wait a wrong PIN imposes on this address
check "no request for kitchen reached the bus" sh -c "! grep -q 'request kitchen' '$T/probe.txt'"

"$B/tests/helpers/face_probe" --unsigned intruder --watch 0.5 > /dev/null 2>&1
check "an unsigned request is refused by the mission" wait_for 5 grep -q "goal request 'intruder' from stranger refused: unsigned" "$T/mission.log"
check "a forged one too" wait_for 5 grep -q "goal request 'intruder' from stranger refused: forged" "$T/mission.log"
check "and the mission still goes to lab" sh -c "! grep -q '^goal intruder' '$T/probe.txt'"

check "STOP with the PIN: the page confirms" tap 2468 '#stop' 'stop asked' --size 800x480
check "marie-am obeyed the signed order: walker paused" wait_for 10 sh -c "\"$BIN/marie\" ps | grep walker | grep -q paused"
check "the host light turns amber" cdp --size 800x480 --until "document.querySelector('.host[data-host=alpha] .light.amber') !== null" --screenshot "$SHOTS/face-stopped.png"
check "GO ON resumes it" tap 2468 '#resume' 'moving on' --size 800x480
check "walker running again" wait_for 10 sh -c "\"$BIN/marie\" ps | grep walker | grep -q running"

# Same tab throughout: the server is killed, the page must say so, then it comes back.
restart="kill $face_pid; sleep 2; $BIN/marie-face --name face --param http_port=8121 --param key_file=$T/key \
 --param pin=2468 --param '$PLACES' --param stop_target=walker >> $T/face.log 2>&1 & echo \$! > $T/face2.pid"
check "server gone: the page says so, then reconnects by itself when it is back" \
    cdp --size 800x480 --until "$ready" --then "$restart" \
        --until2 "document.body.dataset.drops >= 1 && document.body.dataset.saidGone === '1' && $ready" \
        --screenshot "$SHOTS/face-back.png"
[ -s "$T/face2.pid" ] && pids="$pids $(cat "$T/face2.pid")"
finish
