#!/bin/sh
# test-light
# test_face_pin: the touch page's PIN against a guesser that is not a browser (no Origin): wrong
# PINs sent as fast as the server answers are compared a few times, not thousands; a patient
# guesser is locked out after five in a row, with a pin_lockout event on the bus; the right PIN
# is then refused too, from that address only. tests/face/pin_guess.py is the guesser.
. tests/lib.sh
T=$(mktemp -d /tmp/marie-test-face-pin.XXXXXX)
OUT=$T
trap 'stop_started; rm -rf "$T"' EXIT INT TERM
"$BIN/marie" keygen "$T/key" > /dev/null
start probe "$B/tests/helpers/face_probe" --watch 60
start face "$BIN/marie-face" --name face --param http_port=8131 --param key_file="$T/key" --param pin=735194 \
    --param url_file="$T/url"
setup "face server serves" wait_for 10 test -s "$T/url"
check "the PIN's strength is said at start" \
    grep -q "PIN guard: 5 wrong in a row lock an address out.*probability" "$T/face.log"
python3 tests/face/pin_guess.py 8131 735194 3 > "$T/guess.json"
cat "$T/guess.json"
g() { python3 -c "import json, sys; d = json.load(open(sys.argv[1])); print(eval(sys.argv[2]))" "$T/guess.json" "$1"; }
said() { g "$1" | grep -q "$2"; }     # said EXPR PATTERN
check "a flood of wrong PINs: hundreds sent, at most 3 compared in 3 s" \
    sh -c "[ $(g 'd["flood"]["tries"]') -ge 100 ] && [ $(g 'd["flood"].get("wrong", 0)') -le 3 ]"
check "the others refused unseen (too soon)" [ "$(g 'd["flood"].get("too soon", 0)')" -ge 97 ]
check "a patient guesser is locked out after 5 wrong PINs in a row" \
    [ "$(g 'd["flood"].get("wrong", 0) + d["patient"].count("wrong")')" -eq 5 ]
check "the lockout says for how long (a minute)" said 'd.get("lock_text")' 'locked: try again in 60 s'
check "the right PIN is refused while locked out" said 'd["right_pin_when_locked"]' '^locked'
check "another address is not locked out: its right PIN goes through" \
    said 'd["right_pin_other_address"]' '^stop asked$'
check "the lockout is an event on the bus" \
    wait_for 5 grep -q "event pin_lockout from face: 5 wrong PINs in a row from 127.0.0.1: locked out for 60 s" "$T/probe.log"
finish
