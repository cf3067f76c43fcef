#!/bin/sh
# test_python_shm: a Python component's ports on channels the system file puts on shared memory
# (kind: shm) and on the same-host fast path (kind: local). It publishes bursts of 100 KB images
# that C Splitters (marie-ca) read there and forward through their own rings, and reads what they
# forward back: every image of each burst must come back once and byte for byte as sent, and one
# past the channel's max_size is refused and counted; upstream LCM for Python, as lcm-spy and
# a recorder would, sees every image whole on the channels' names. Before
# Python ports took part (refused at start) and before the C readers took messages announced by
# a notice without a ring, none came back.
. tests/lib.sh
T=$(mktemp -d /tmp/marie-test-pyshm.XXXXXX)
PIDS=
cleanup() { for p in $PIDS $COUNTERS; do kill "$p" 2>/dev/null; done; sleep 0.3; rm -rf "$T"; }
trap cleanup EXIT
py=$(scripts/peer-venv.sh) || { echo "LCM for Python is not installed (scripts/peer-venv.sh); failing"; exit 1; }
# the peer as lcm-spy or a recorder would be set up for bursts of images: a large receive buffer
peer() { LCM_DEFAULT_URL="udpm://239.255.76.67:7667?ttl=0&recv_buf_size=4194304" PYTHONPATH=$B/python "$py" tests/python/lcm_peer.py "$@"; }
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
COUNTERS=
for ch in SHM_A SHM_B LOC_A LOC_B; do peer count $ch 6 > "$T/count.$ch" & COUNTERS="$COUNTERS $!"; done
sleep 0.5
PYTHONPATH=python:$B/python MARIE_RESOLVE=$BIN/marie-resolve timeout 30 python3 tests/python/shm_burst.py \
    --system "$T/system.yaml" --name pyb > "$T/out" 2> "$T/err"
echo "exit $?"; cat "$T/out"; tail -5 "$T/err"
whole() { grep -qx "$1 burst 24 received 24 exact 24" "$T/out"; }
check "every image of a burst through a shm channel, C to Python and back, byte-exact" whole shm
check "every image of a burst through a local channel, C to Python and back, byte-exact" whole local
check "an image past max_size is refused and counted" grep -qx "publish_too_big 1" "$T/out"
wait $COUNTERS
seen() { for ch in SHM_A SHM_B LOC_A LOC_B; do echo "$ch: $(cat "$T/count.$ch")"; done; cat "$T"/count.* | grep -cx 24 | grep -qx 4; }
check "upstream LCM sees the 24 images whole on each channel, both ways" seen
finish
