#!/bin/sh
# test-light
# test_bag_types: a user's LCM type (tests/data/types/reading.lcm, made by marie-types-gen) through
# marie bag: exported as the custom ROS 2 message ux_msgs/msg/Reading, which rosbags decodes from
# the bag's own definition (no marie code, no type registered by hand), every field as written; one
# of marie's types without a ROS 2 counterpart carried the same way; a malformed reading refused and
# counted; a type ROS 2 cannot carry (an array of arrays) and a payload of no known type each skipped
# with a line saying why; `marie bag info` on the log and the bag; and the import giving back the
# very payloads.
. tests/lib.sh
T=$(mktemp -d /tmp/marie-test-bagtypes.XXXXXX)
trap 'rm -rf "$T"' EXIT
PY=$B/venv-bag/bin/python
[ -x "$PY" ] || { echo "[  FAILED  ] setup: the venv of marie bag (scripts/bag-venv.sh)"; exit 1; }
mkdir "$T/ux"
cp tests/data/types/reading.lcm "$T/ux/"
cat > "$T/ux/matrix.lcm" <<'LCM'
package ux;
struct matrix_t { int32_t m[2][3]; }
LCM
setup "marie-types-gen makes the types" "$BIN/marie-types-gen" -o "$T/gen" "$T/ux/reading.lcm" "$T/ux/matrix.lcm" --lang python
export PYTHONPATH=$B/python:$T/gen/python

# the log: 20 readings, one cut short, counters (marie's, no ROS 2 counterpart), matrices, and a
# payload no descriptor knows
"$PY" - "$T/run.lcm" <<'PY'
import struct, sys
import lcm
from lcmtypes.marie import counter_t, pose2d_t
from lcmtypes.ux import matrix_t, reading_t
log = lcm.EventLog(sys.argv[1], "w", overwrite=True)
t = 1_700_000_000_000_000
for i in range(20):
    r = reading_t(); r.utime = t + i; r.sensor = "thermo%d" % i; r.value = 0.5 * i
    r.samples = [float(k) / 4 for k in range(i % 4)]; r.n = len(r.samples)
    r.where = pose2d_t(); r.where.x, r.where.y, r.where.theta = i, -i, 0.1 * i
    log.write_event(t + 1000 * i, "READING", r.encode())
log.write_event(t + 30000, "READING", r.encode()[:-6])
for i in range(3):
    c = counter_t(); c.name = "ticks"; c.value = i
    log.write_event(t + 40000 + i, "COUNTER", c.encode())
    m = matrix_t(); m.m = [[i, 2, 3], [4, 5, 6]]
    log.write_event(t + 50000 + i, "MATRIX", m.encode())
log.write_event(t + 60000, "MYSTERY", struct.pack(">q", 0x1234567) + b"abc")
log.write_event(t + 60001, "MYSTERY", struct.pack(">q", 0x1234567) + b"def")
log.close()
PY

export_it() {
    "$BIN/marie" bag export "$T/run.lcm" "$T/bag" --types "$T/gen" --map READING=/reading --map COUNTER=/counter \
        --map MATRIX=/matrix --map MYSTERY=/mystery > "$T/export.out" 2> "$T/export.err"; rc=$?
    cat "$T/export.out" "$T/export.err"; [ $rc -eq 0 ]
}
check "marie bag export with the user's types (exit 0)" export_it
check "the readings go as ux_msgs/msg/Reading" grep -q '^/reading  *ux_msgs/msg/Reading  *20$' "$T/export.out"
check "marie's counter_t goes as marie_msgs/msg/Counter" grep -q '^/counter  *marie_msgs/msg/Counter  *3$' "$T/export.out"
check "the malformed reading is refused and counted" grep -qx 'refused READING: 1 malformed ux.reading_t messages' "$T/export.err"
check "an array of arrays is not carried, saying why" grep -q '^skipped MATRIX: 3 ux.matrix_t messages: ux.matrix_t.m is an array of arrays, which ROS 2 messages do not have$' "$T/export.err"
check "a payload of no known type is skipped with its count" grep -q '^skipped MYSTERY: 2 messages of no type' "$T/export.err"

readback() {
    "$PY" - "$T/bag" <<'PY'
# rosbags alone: the message definitions come from the bag
import pathlib, sys
from rosbags.highlevel import AnyReader
with AnyReader([pathlib.Path(sys.argv[1])]) as r:
    conns = {c.topic: c for c in r.connections}
    assert set(conns) == {"/reading", "/counter"}, conns
    print(conns["/reading"].msgdef.data)
    got = [r.deserialize(raw, c.msgtype) for c, _, raw in r.messages(connections=[conns["/reading"]])]
    assert len(got) == 20
    for i, m in enumerate(got):
        assert (m.utime, m.sensor, m.value, m.n) == (1_700_000_000_000_000 + i, "thermo%d" % i, 0.5 * i, i % 4), m
        assert list(m.samples) == [k / 4 for k in range(i % 4)] and m.samples.dtype.name == "float32", m
        assert (m.where.x, m.where.y) == (i, -i) and abs(m.where.theta - 0.1 * i) < 1e-12, m
        assert m.where.__msgtype__ == "marie_msgs/msg/Pose2d"
    c = [r.deserialize(raw, x.msgtype) for x, _, raw in r.messages(connections=[conns["/counter"]])]
    assert [(m.name, m.value) for m in c] == [("ticks", 0), ("ticks", 1), ("ticks", 2)], c
print("rosbags decoded 20 readings and 3 counters from the bag's own definitions")
PY
}
check "rosbags decodes them from the bag's definitions, every field as written" readback
info_log() {
    "$BIN/marie" bag info "$T/run.lcm" --types "$T/gen" > "$T/info.out"; cat "$T/info.out"
    grep -q '^  READING  *ux.reading_t  *21  (exported as custom ux_msgs/msg/Reading with --map or --all)$' "$T/info.out" &&
        grep -q '^  MYSTERY  *?  *2  (not exported: no descriptors for its type)$' "$T/info.out" &&
        grep -q '^  MATRIX  *ux.matrix_t  *3  (not exported: ux.matrix_t.m is an array of arrays' "$T/info.out"
}
check "marie bag info on the log names the user's type and what export does with it" info_log
info_bag() {
    "$BIN/marie" bag info "$T/bag" --types "$T/gen" > "$T/infob.out"; cat "$T/infob.out"
    grep -q '^  /reading  *ux_msgs/msg/Reading  *20$' "$T/infob.out"
}
check "marie bag info on the bag: the custom topic is importable" info_bag
round_trip() {
    "$BIN/marie" bag import "$T/bag" "$T/back.lcm" --types "$T/gen" --map /reading=READING --map /counter=COUNTER || return 1
    "$PY" - "$T/run.lcm" "$T/back.lcm" <<'PY'
import sys
import lcm
def events(p, ch):
    return [(e.timestamp, e.data) for e in lcm.EventLog(p, "r") if e.channel == ch]
for ch, n in (("READING", 20), ("COUNTER", 3)):
    a, b = events(sys.argv[1], ch)[:n], events(sys.argv[2], ch)
    assert a == b, (ch, len(a), len(b))
print("the same 20 readings and 3 counters, byte for byte")
PY
}
check "export then import gives back the very payloads" round_trip
no_types() {
    MARIE_TYPES_PATH= PYTHONPATH= "$BIN/marie" bag export "$T/run.lcm" "$T/bag2" --map READING=/reading --map COUNTER=/counter \
        > "$T/e2.out" 2> "$T/e2.err"; cat "$T/e2.out" "$T/e2.err"
    grep -q '^skipped READING: 21 messages of no type marie can carry' "$T/e2.err" && grep -q '^/counter ' "$T/e2.out"
}
check "without the user's descriptors the readings are skipped, saying where they come from" no_types
finish
