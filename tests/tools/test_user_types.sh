#!/bin/sh
# test_user_types: a message type defined outside marie (tests/data/types/reading.lcm, copied to a
# temporary directory), made first-class by marie-types-gen, flows through a user's C component,
# a user's Python component, the XML bridge, marie topic, marie-spy, a Mailbox (a pull), a
# Splitter and a recording played back; malformed and non-finite payloads of it are still refused
# (by the Mailbox and the Splitter too). The other side is upstream LCM for
# Python with lcm-gen's classes.
. tests/lib.sh
T=$(mktemp -d /tmp/marie-test-types.XXXXXX)
OUT=$T
cleanup() { stop_started; rm -rf "$T"; }
trap cleanup EXIT
py=$(scripts/peer-venv.sh) || { echo "LCM for Python is not installed (scripts/peer-venv.sh); failing"; exit 1; }
mkdir "$T/ux"
cp tests/data/types/reading.lcm tests/data/types/ux_probe.c tests/data/types/ux_echo.py "$T/ux/"

check "marie-types-gen makes C, C++, Python, Java and the library" sh -c "
    $BIN/marie-types-gen -o $T/gen $T/ux/reading.lcm &&
    test -f $T/gen/c/lcmtypes/ux_reading_t.c && test -f $T/gen/c/lcmtypes/ux_types.c &&
    test -f $T/gen/cpp/ux/reading_t.hpp && test -f $T/gen/python/lcmtypes/ux/reading_t.py &&
    test -f $T/gen/python/lcmtypes/ux/_typeinfo.py && test -f $T/gen/java/ux_types.jar &&
    test -f $T/gen/lib/libmarie-types-ux.so"
clash() { ! "$BIN/marie-types-gen" -o "$T/clash" lcmtypes/pose2d_t.lcm 2> "$T/clash.err" && grep -q 'already a marie type' "$T/clash.err"; }
check "a marie type's name is refused" clash
fp_agrees() {
    # the fingerprint of marie's descriptors is lcm-gen's (its Python class computes its own)
    PYTHONPATH=$B/python:$T/gen/python python3 -c '
import struct
from lcmtypes.ux import reading_t, _typeinfo
assert struct.unpack(">q", reading_t._get_packed_fingerprint())[0] == _typeinfo.TYPES["ux.reading_t"][0]'
}
check "descriptors carry lcm-gen's fingerprint" fp_agrees
# a user's C component, built outside marie's tree against the generated C (with the
# sanitizers when make built libmarie with them)
SANFLAGS=""
[ "${SAN:-0}" = 1 ] && SANFLAGS="-fsanitize=address,undefined"
build_probe() {
    ${CC:-cc} -O1 $SANFLAGS -I"$T/gen/c" -I. -I"$B/gen/c" $(pkg-config --cflags lcm glib-2.0) -o "$T/ux-probe" \
        "$T/ux/ux_probe.c" "$T"/gen/c/lcmtypes/*.c "$B/lib/libmarie.a" $(pkg-config --libs lcm glib-2.0 libsodium) -lm -lpthread
}
check "a C component compiles against the generated code" build_probe

export MARIE_TYPES_PATH=$T/gen
peer() { PYTHONPATH=$B/python:$T/gen/python "$py" tests/python/lcm_peer.py "$@"; }
hbv() { peer hb "$1" 3 | python3 -c "import json,sys; h=json.load(sys.stdin); c=h['counters']; print($2)"; }
start probe "$T/ux-probe" --name probe
start echo env PYTHONPATH=python:$B/python MARIE_RESOLVE=$BIN/marie-resolve python3 "$T/ux/ux_echo.py" --name echo
start bridge "$BIN/marie-xml-bridge" --name bridge --param port=7677
# the Communication Adapters carry it by name, as any type: a Mailbox answers pulls of the
# probe's readings, a Splitter copies them to two channels
start mailbox "$BIN/marie-ca" mailbox --name mb --param type=ux.reading_t --param channel=READING
start splitter "$BIN/marie-ca" splitter --name sp --param type=ux.reading_t --param input=READING \
    --param 'outputs=[READING_A, READING_B]'
sleep 2
round_trip() {
    e=$(hbv echo 'c.get("received", 0)'); p=$(hbv probe 'c.get("received", 0), c.get("intact", 0)')
    echo "python echo received $e; C probe received, intact: $p"
    [ "$e" -gt 10 ] && python3 -c "import sys; r, i = map(int, sys.argv[1:]); sys.exit(0 if r > 10 and i == r else 1)" $p
}
check "C -> Python -> C on a typed port of the user's type" round_trip
no_bad() { [ "$(hbv probe 'h["bad_input"]')" = 0 ] && [ "$(hbv echo 'h["bad_input"]')" = 0 ]; }
check "nothing refused meanwhile" no_bad

# malformed and non-finite payloads of the user's type: refused, counted, never handed over
PYTHONPATH=$B/python:$T/gen/python "$py" - <<'PY'
import lcm, math
from lcmtypes.ux import reading_t
r = reading_t(); r.sensor = "bad"; r.n = 1; r.samples = [float("nan")]
lc = lcm.LCM("udpm://239.255.76.67:7667?ttl=0")
lc.publish("READING_ECHO", r.encode())          # NaN in an array: bad_nonfinite
r.samples = [1.0]
lc.publish("READING_ECHO", r.encode()[:-5])     # cut short: bad_payload
lc.publish("READING", r.encode() + b"\0")       # a byte too many: bad_payload, for the Python echo
PY
refused() {
    v=$(hbv probe 'c.get("bad_nonfinite", 0), c.get("bad_payload", 0)'); w=$(hbv echo 'c.get("bad_payload", 0)')
    echo "probe $v echo $w"; [ "$v" = "1 1" ] && [ "$w" = 1 ]
}
check "malformed and non-finite readings are refused and counted" wait_for 5 refused
ca_refused() {
    m=$(hbv mb 'c.get("bad_payload", 0), h["bad_input"]'); s=$(hbv sp 'c.get("bad_payload", 0), h["bad_input"]')
    echo "mailbox $m splitter $s"; [ "$m" = "1 1" ] && [ "$s" = "1 1" ]
}
check "the Mailbox and the Splitter refuse the malformed reading, and count it" wait_for 5 ca_refused

# a pull answered by the Mailbox: the newest reading, well-formed, as upstream LCM decodes it
pull() {
    PYTHONPATH=$B/python:$T/gen/python "$py" - <<'PY'
import select, sys, time
import lcm
from lcmtypes.marie import pull_request_t, pull_reply_t
from lcmtypes.ux import reading_t
lc = lcm.LCM("udpm://239.255.76.67:7667?ttl=0")
got = []
lc.subscribe("PULL_ME", lambda ch, data: got.append(pull_reply_t.decode(data)))
rq = pull_request_t(); rq.utime = int(time.time() * 1e6); rq.request_id = 7; rq.requester = "test"
rq.channel, rq.reply_channel, rq.timeout_ms = "READING", "PULL_ME", 500
lc.publish("READING.PULL", rq.encode())
end = time.time() + 3
while not got and time.time() < end:
    if select.select([lc.fileno()], [], [], 0.1)[0]:
        lc.handle()
r = got[0]
m = reading_t.decode(bytes(r.data))
print("pull: status", r.status, "age", r.age_us, "us, sensor", m.sensor, "samples", list(m.samples), "where", m.where.x, m.where.y)
sys.exit(0 if r.status == 0 and r.request_id == 7 and m.sensor == "thermo" and r.size == len(r.data) else 1)
PY
}
check "a Mailbox pull answers the newest reading" pull
split() {
    a=$(peer count READING_A 1.5) b=$(peer count READING_B 1.5); echo "READING_A $a READING_B $b in 1.5 s"
    [ "$a" -ge 5 ] && [ "$b" -ge 5 ] && "$BIN/marie" topic echo READING_B --once --field sensor | grep -qx thermo
}
check "the Splitter copies readings to its two outputs" split

# the XML bridge: lists, describes, streams and publishes the user's type
PYTHONPATH= python3 - "$T/xml.out" <<'PY' > "$T/xml.log" 2>&1
import socket, sys, time
s = socket.create_connection(("127.0.0.1", 7677), timeout=5)
f = s.makefile("rb")
out = open(sys.argv[1], "w")
out.write(f.readline().decode())                                   # hello
s.sendall(b'<types id="t"/><describe type="ux.reading_t" id="d"/>'
          b'<subscribe channel="READING" type="ux.reading_t" id="s"/>')
for _ in range(3):
    out.write(f.readline().decode())
s.sendall(b'<publish channel="READING_ECHO" type="ux.reading_t" id="p"><sensor>xml</sensor><value>1.5</value>'
          b'<samples>1 2 3</samples><where><x>4</x></where></publish>')
deadline, seen = time.time() + 3, set()
while time.time() < deadline and len(seen) < 2:
    line = f.readline().decode()
    out.write(line)
    seen |= {k for k in ('to="publish"', '<message ') if k in line}
out.close()
PY
check "the bridge lists ux.reading_t" grep -q '<type name="ux.reading_t"' "$T/xml.out"
check "the bridge describes it" grep -q '<field name="samples" type="float" dims="\[n\]"' "$T/xml.out"
check "the bridge streams it" sh -c "grep '<message channel=\"READING\" type=\"ux.reading_t\"' $T/xml.out | grep -q '<sensor>thermo</sensor>'"
check "the bridge publishes it" grep -q '<ok to="publish" id="p"' "$T/xml.out"

# marie topic: echo decodes it from its descriptors
check "marie topic echo decodes it" sh -c "$BIN/marie topic echo READING --once --field sensor | grep -qx thermo"
echo_json() { "$BIN/marie" topic echo READING --once --json > "$T/echo.json" && python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
assert d["type"] == "ux.reading_t" and d["msg"]["samples"] == [1, 2, 3] and d["msg"]["where"]["y"] == 2, d' "$T/echo.json"; }
check "marie topic echo --json gives every field" echo_json
check "marie topic list names its type" sh -c "$BIN/marie topic list --duration 1 | grep -q '^READING .*ux.reading_t'"

# marie-spy (lcm-spy) decodes it from the generated jar
check "marie-spy decodes it" sh -c "$BIN/marie-spy --check | grep -q 'user type ux.reading_t'"

# record and play: the recording replays readings the Python component accepts
rec_play() {
    "$BIN/marie-record" -q -o "$T/run.lcmlog" -c READING --duration 1.5 || return 1
    kill "$pid_probe"; wait "$pid_probe" 2>/dev/null; sleep 0.5
    before=$(hbv echo 'c.get("received", 0)')
    "$BIN/marie-play" "$T/run.lcmlog" || return 1
    sleep 0.5
    after=$(hbv echo 'c.get("received", 0), h["bad_input"]')
    echo "before $before, after play $after"
    python3 -c "import sys; b = int(sys.argv[1]); a, bad = int(sys.argv[2]), int(sys.argv[3]); sys.exit(0 if a - b >= 20 and bad == 1 else 1)" $before $after
}
check "a recording of it plays back into the Python component" rec_play
finish
