#!/bin/sh
# test_python_shm: a Python component's ports on channels the system file puts on shared memory
# (kind: shm) and on the same-host fast path (kind: local). It publishes bursts of 100 KB images
# that C Splitters (marie-ca) read there and forward through their own rings, and reads what they
# forward back: every image of each burst must come back once and byte for byte as sent, and one
# past the channel's max_size is refused and counted. Before
# Python ports took part (refused at start) and before the C readers took messages announced by
# a notice without a ring, none came back.
. tests/lib.sh
T=$(mktemp -d /tmp/marie-test-pyshm.XXXXXX)
PIDS=
cleanup() { for p in $PIDS; do kill "$p" 2>/dev/null; done; sleep 0.3; rm -rf "$T"; }
trap cleanup EXIT
cat > "$T/system.yaml" <<EOF2
system: pyshm
transports:
  SHM_A: {kind: shm, max_size: 200000, slots: 32}
  SHM_B: {kind: shm, max_size: 200000, slots: 32}
  LOC_A: {kind: local, max_size: 200000, slots: 32}
  LOC_B: {kind: local, max_size: 200000, slots: 32}
components:
  split-shm:
    exec: marie-ca
    args: [splitter]
    params: {input: SHM_A, type: marie.image_t, outputs: [SHM_B]}
  split-local:
    exec: marie-ca
    args: [splitter]
    params: {input: LOC_A, type: marie.image_t, outputs: [LOC_B]}
  pyb: {exec: /bin/true}
EOF2
for s in split-shm split-local; do
    "$BIN/marie-ca" splitter --system "$T/system.yaml" --name "$s" > "$T/$s.log" 2>&1 & PIDS="$PIDS $!"
done
sleep 1
PYTHONPATH=python:$B/python MARIE_RESOLVE=$BIN/marie-resolve timeout 30 python3 tests/python/shm_burst.py \
    --system "$T/system.yaml" --name pyb > "$T/out" 2> "$T/err"
echo "exit $?"; cat "$T/out"; tail -5 "$T/err"
whole() { grep -qx "$1 burst 24 received 24 exact 24" "$T/out"; }
check "every image of a burst through a shm channel, C to Python and back, byte-exact" whole shm
check "every image of a burst through a local channel, C to Python and back, byte-exact" whole local
check "an image past max_size is refused and counted" grep -qx "publish_too_big 1" "$T/out"
finish
