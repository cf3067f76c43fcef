#!/bin/sh
# test_topic_param: marie topic list|echo|hz|pub and marie param list|get|set against running C
# and Python components (the example producers), with the order key: what a user types first.
# test-light
. tests/lib.sh
T=$(mktemp -d /tmp/marie-test-topic.XXXXXX)
OUT=$T
cleanup() { stop_started; rm -rf "$T"; }
trap cleanup EXIT
M=$BIN/marie
"$M" keygen "$T/key"
"$M" keygen "$T/otherkey"
export MARIE_KEY=$T/key MARIE_SEQ_FILE=$T/seq
start cp "$BIN/marie-example-producer" --name cp --param rate_hz=20 --param label=from-c
start pp "$BIN/marie-example-producer-py" --name pp --param rate_hz=10 --port out=PY_EXAMPLE
setup "both producers publish" sh -c "$M topic echo PY_EXAMPLE --once --timeout 20 > /dev/null && $M topic echo EXAMPLE --once --timeout 20 > /dev/null"
sleep 1.2   # a heartbeat of each, naming its output

listed() {
    "$M" topic list --duration 1.2 > "$T/list"; cat "$T/list"
    grep -q '^EXAMPLE  *marie.counter_t  *[12][0-9]\.[0-9]* .* cp$' "$T/list" &&
        grep -q '^PY_EXAMPLE  *marie.counter_t .* pp$' "$T/list" && grep -q '^MARIE_HEARTBEAT  *marie.heartbeat_t' "$T/list"
}
check "topic list: channels, types, rates and publishers" listed
list_json() { "$M" topic list --duration 1 --json | python3 -c '
import json, sys
d = {c["channel"]: c for c in json.load(sys.stdin)}
assert d["PY_EXAMPLE"]["type"] == "marie.counter_t" and d["PY_EXAMPLE"]["publishers"] == ["pp"], d
assert 4 <= d["PY_EXAMPLE"]["hz"] <= 15, d["PY_EXAMPLE"]'; }
check "topic list --json" list_json
check "topic echo --once" sh -c "$M topic echo EXAMPLE --once | grep -q '^EXAMPLE marie.counter_t {\"name\":\"from-c\",\"value\":[0-9]*}$'"
check "topic echo --field" sh -c "[ \$($M topic echo PY_EXAMPLE --once --field name) = py-example ]"
check "topic echo --field into an array of structs" sh -c "$M topic echo MARIE_HEARTBEAT --count 4 --field ports[0].channel | grep -qx PY_EXAMPLE"
check "topic echo of a silent channel gives up (exit 3)" sh -c "$M topic echo NOTHING --once --timeout 0.3; [ \$? = 3 ]"
# Rates are checked in wide bands: a busy machine stalls the producers (speed is the benchmarks'
# business); what matters is that hz measures, and that a set rate changes it.
rate() {
    "$M" topic hz EXAMPLE --duration 2.1 > "$T/hz"; cat "$T/hz"
    r=$(grep 'average rate' "$T/hz" | tail -1 | sed 's/.*rate \([0-9.]*\) Hz/\1/'); le 8 "$r" && le "$r" 30
}
check "topic hz: about 20 Hz measured" rate
pubbed() {
    "$M" topic echo POSE_TEST --once --timeout 3 --json > "$T/pose.json" & e=$!
    sleep 0.4
    "$M" topic pub POSE_TEST marie.pose_cov_t '{frame: map, pose: {x: 1.5, y: -2}, cov: [1, 0, 0, 0, 1, 0, 0, 0, 1]}'
    wait $e
    python3 -c 'import json,sys; m = json.load(open(sys.argv[1]))["msg"]; assert m["pose"]["x"] == 1.5 and m["cov"][4] == 1 and m["frame"] == "map", m' "$T/pose.json"
}
check "topic pub: a message from YAML, echoed back" pubbed
bad_pub() { out=$("$M" topic pub X marie.pose2d_t '{x: 1, z: 2}' 2>&1); [ $? -ne 0 ] && echo "$out" | grep -q 'z: no such field'; }
check "topic pub: an unknown field is refused with its name" bad_pub
signed_pub() {
    "$M" topic pub MARIE_LIFECYCLE marie.lifecycle_command_t '{target: pp, command: 4}' &&
        sleep 0.5 && "$M" topic echo MARIE_HEARTBEAT --count 6 --json | grep '"component":"pp"' | grep -q '"state":3'
}
check "topic pub: an order is signed with the key, and obeyed (pause)" signed_pub
forged_pub() {
    MARIE_KEY=$T/otherkey "$M" topic pub MARIE_LIFECYCLE marie.lifecycle_command_t '{target: cp, command: 4}'
    sleep 0.5; "$M" topic echo MARIE_HEARTBEAT --count 6 --json | grep '"component":"cp"' | grep -q '"state":2'
}
check "topic pub: signed with another key, refused" forged_pub
"$M" topic pub MARIE_LIFECYCLE marie.lifecycle_command_t '{target: pp, command: 5}'

for c in cp pp; do
    check "param list ($c)" sh -c "$M param list $c | grep -q '^rate_hz  *double  *dynamic '"
    check "param set of a dynamic parameter ($c)" "$M" param set $c rate_hz 40
    check "param get reads it back ($c)" sh -c "$M param get $c rate_hz | grep -qx '40\(\.0\)\?'"
    refused() { out=$("$M" param set $1 label other 2>&1); [ $? = 1 ] && echo "$out" | grep -q "not dynamic"; }
    check "param set of a fixed parameter refused with the reason ($c)" refused $c
    said_no() { out=$("$M" param set $1 rate_hz -- -1 2>&1); echo "$out"; [ $? = 1 ] || true; echo "$out" | grep -q "rate_hz must be in" &&
        "$M" param get $1 rate_hz | grep -qx '40\(\.0\)\?'; }
    check "the component's callback refuses a value, the old one stays ($c)" said_no $c
    unsigned() { out=$(MARIE_KEY=$T/otherkey "$M" param set $1 rate_hz 30 2>&1); echo "$out"; echo "$out" | grep -q "order refused: forged"; }
    check "param set signed with another key refused ($c)" unsigned $c
done
fast() {
    "$M" topic hz PY_EXAMPLE --duration 2.1 > "$T/hz2"; cat "$T/hz2"
    r=$(grep 'average rate' "$T/hz2" | tail -1 | sed 's/.*rate \([0-9.]*\) Hz/\1/'); le 22 "$r" && le "$r" 60
}
check "the Python producer runs at its new rate" fast
check "--version" sh -c "$BIN/marie-topic --version && $BIN/marie-param --version && $BIN/marie-example-producer --version && $BIN/marie-example-producer-py --version"
finish
