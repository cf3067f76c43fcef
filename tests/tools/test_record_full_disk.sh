#!/bin/sh
# test-light
# test_record_full_disk: marie-record on a disk with no room (a small tmpfs in a mount namespace
# of the test's own) fails loudly: it refuses to start below --min-free, stops when free space
# falls below it while recording, and when a write fails (ENOSPC) it exits 1 naming the error,
# with a file that holds only whole messages. Before, a full disk gave exit status 0 and a
# 0-byte file: lcm-logger's buffered writes failed unchecked.
if [ "${MARIE_IN_MOUNTNS:-}" != 1 ]; then
    MARIE_IN_MOUNTNS=1 exec unshare -m sh "$0" "$@"
fi
. tests/lib.sh
export LCM_DEFAULT_URL="udpm://239.255.76.70:7670?ttl=0&recv_buf_size=4194304"
export XB_SAMPLES_PACE_MS=2
T=$(mktemp -d)
D=$T/disk
mkdir -p "$D"
trap 'umount "$D" 2>/dev/null; rm -rf "$T"' EXIT

# disk KB [FILL_KB]: $D is a fresh tmpfs of KB kilobytes, FILL_KB of them taken
disk() {
    umount "$D" 2>/dev/null
    mount -t tmpfs -o "size=${1}k" tmpfs "$D" || return 1
    [ -z "${2:-}" ] || dd if=/dev/zero of="$D/fill" bs=1k count="$2" 2> /dev/null
    return 0
}

# publishes samples of every type until marie-record (pid $1) is gone
publish_while() {
    while kill -0 "$1" 2>/dev/null; do
        $B/tests/bin/xb-samples publish DISK. 1 > /dev/null 2>&1
    done
}

# record NAME ARGS...: marie-record -o $D/NAME ARGS with messages flowing; its exit status in
# $rc, its stderr in $T/err
record() {
    f=$1; shift
    $BIN/marie-record -q -o "$D/$f" "$@" 2> "$T/err" &
    r=$!
    publish_while $r
    wait $r
    rc=$?
    cat "$T/err"
}

# whole_messages FILE: the file is a sequence of whole LCM log events; their count printed
whole_messages() {
    python3 - "$1" <<'PY'
import struct, sys
d, i, n = open(sys.argv[1], "rb").read(), 0, 0
while i < len(d):
    sync, _, _, cl, dl = struct.unpack(">IqqII", d[i:i + 28])
    assert sync == 0xEDA1DA01 and i + 28 + cl + dl <= len(d), "torn message at byte %d" % i
    i, n = i + 28 + cl + dl, n + 1
print(n)
PY
}

full_disk_is_refused() {
    disk 256 256 || return 1
    record full.lcmlog --duration 1
    [ "$rc" = 1 ] && grep -q "below --min-free" "$T/err" && [ ! -e "$D/full.lcmlog" ]
}

write_error_is_an_error() {
    disk 256 256 || return 1
    record nospace.lcmlog --duration 5 --min-free 0
    [ "$rc" = 1 ] && grep -q "No space left on device" "$T/err" && [ "$(whole_messages "$D/nospace.lcmlog")" = 0 ]
}

disk_filling_up_keeps_whole_messages() {
    disk 48 || return 1
    record fills.lcmlog --duration 20 --min-free 0
    n=$(whole_messages "$D/fills.lcmlog") || return 1
    echo "$n whole messages kept, $(stat -c %s "$D/fills.lcmlog") bytes"
    [ "$rc" = 1 ] && grep -q "write failed after $n messages" "$T/err" && [ "$n" -gt 0 ]
}

falling_below_min_free_stops() {
    disk 512 || return 1
    # the disk fills once the recorder runs (its file made), not before: a loaded machine
    # may take longer than a fixed second to start it
    (wait_for 20 test -e "$D/below.lcmlog"; sleep 0.5; dd if=/dev/zero of="$D/fill" bs=1k count=400 2> /dev/null) &
    record below.lcmlog --duration 20 --min-free 200k
    [ "$rc" = 1 ] && grep -q "below --min-free.*recording stopped" "$T/err" &&
        whole_messages "$D/below.lcmlog" > /dev/null
}

room_enough_exits_0() {
    disk 4096 || return 1
    record fine.lcmlog --duration 1.5 --min-free 64k
    [ "$rc" = 0 ] && [ "$(whole_messages "$D/fine.lcmlog")" -gt 0 ]
}

check "a full disk: refused (exit 1), no file" full_disk_is_refused
check "no room for a message: exit 1 naming ENOSPC, nothing torn" write_error_is_an_error
check "the disk fills while recording: exit 1, the file holds whole messages" disk_filling_up_keeps_whole_messages
check "free space below --min-free while recording: stopped, exit 1" falling_below_min_free_stops
check "room enough: exit 0, messages recorded" room_enough_exits_0
finish
