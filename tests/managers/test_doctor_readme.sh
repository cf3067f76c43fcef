#!/bin/sh
# test-keep-user
# test-light
# test_doctor_readme: the README's two-host example, run as the README says, passes marie doctor's
# bus checks (ttl, receive buffer): the example set ttl=0 for two hosts, and the doctor failed an
# 8 MB buffer above net.core.rmem_max that marie's bus, run as root, forces anyway.

. tests/lib.sh
T=$(mktemp -d /tmp/marie-test-doctor.XXXXXX)
OUT=$T
cleanup() { stop_started; rm -rf "$T"; }
trap cleanup EXIT
# the README's lines, as written there
url=$(sed -n "s/^ *export LCM_DEFAULT_URL='\([^']*\)'.*/\1/p" README.md)
sed -n '/^```yaml$/,/^```$/p' README.md | sed '1d;$d' | sed -n '/^system: example/,$p' > "$T/example.yaml"
check "the README has the example and its bus URL" sh -c "[ -n '$url' ] && grep -q '^hosts: \[onboard1, laptop\]' $T/example.yaml"
export LCM_DEFAULT_URL="$url" MARIE_KEY=$T/key MARIE_SEQ_FILE=$T/seq
"$BIN/marie" keygen "$T/key"
start am "$BIN/marie-am" --host onboard1 --state-dir "$T/am"
sleep 0.5
"$BIN/marie" --timeout 3 up "$T/example.yaml" --no-wait > "$T/up.log" 2>&1   # laptop has no manager here
"$BIN/marie" doctor > "$T/doctor.log" 2>&1
cat "$T/doctor.log"
check "doctor: ttl fits two hosts" grep -q '^ok  *ttl  *ttl=1 with 2 host(s)' "$T/doctor.log"
root_force() {
    # as root marie's bus forces the buffer past rmem_max (SO_RCVBUFFORCE); otherwise it is capped
    if [ "$(id -u)" = 0 ] && python3 -c 'import socket; s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM); s.setsockopt(socket.SOL_SOCKET, 33, 8388608)' 2>/dev/null; then
        grep -q '^ok  *recv-buffer' "$T/doctor.log"
    else
        grep -q '^FAIL  *recv-buffer.*the kernel caps it' "$T/doctor.log" || grep -q '^ok  *recv-buffer' "$T/doctor.log"
    fi
}
check "doctor: the receive buffer is judged as the bus will get it" root_force
finish
