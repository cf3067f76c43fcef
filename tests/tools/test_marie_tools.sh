#!/bin/sh
# test-light
# test_marie_tools: marie-record, marie-play and marie-spy on a real bus (the test's own network
# namespace): filters, splitting, speed and loop, and every marie type decoded from a recorded
# log by the Java types jar. Everything runs on a non-default LCM URL with a raised receive
# buffer: marie-record must hand it to lcm-logger in a form it accepts, and playback at 20x
# sends the log in bursts that overflow a socket's default (~200 KB) buffer when the listener
# is slow to be scheduled.
. tests/lib.sh
export LCM_DEFAULT_URL="udpm://239.255.76.68:7668?ttl=0&recv_buf_size=4194304"
# lcm-logger queues at most 30 messages for its handler: samples come 20 ms apart, not in a burst
export XB_SAMPLES_PACE_MS=20
URL2="udpm://239.255.76.69:7669?ttl=0&recv_buf_size=4194304"
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
SAMPLES=$B/tests/bin/xb-samples
JAR=$B/java/marie_types.jar
CP=$JAR:/usr/share/java/lcm.jar

# Waits on events, so a loaded machine only makes the test slower: until a socket of this
# namespace has joined the multicast group of an LCM URL (the recorder binds first and joins
# after, and a datagram sent in between is not delivered), and until every socket on the URL's
# port has read all its datagrams (the recorder has them; lcm-logger writes its file only when
# the next message comes or when it exits, so the file cannot tell).
joined() {
    grp=$(echo "$1" | sed 's#udpm://\([0-9.]*\):.*#\1#' | awk -F. '{printf "%02X%02X%02X%02X", $4, $3, $2, $1}')
    grep -q "$grp" /proc/net/igmp
}
drained() {
    port=$(echo "$1" | sed 's#udpm://[0-9.]*:\([0-9]*\).*#\1#')
    awk -v p="$(printf ':%04X' "$port")" 'substr($2, length($2) - 4) == p { split($5, q, ":"); if (q[2] != "00000000") busy = 1 }
        END { exit busy }' /proc/net/udp
}
# stop_recorder PID URL N PATTERN: once the recorder has read everything, stop it; then the
# files PATTERN names (expanded once the recorder is done) must hold N records
stop_recorder() {
    pid=$1; url=$2; n=$3; shift 3
    wait_for 60 drained "$url"
    # From LCM's receive thread to lcm-logger's writer: until the files hold them, bounded (a
    # fixed 0.5 s before the SIGINT left 30 of 106 unwritten once on a loaded machine).
    # shellcheck disable=SC2048,SC2086
    wait_for 10 records "$n" $* || true
    kill -INT "$pid"
    wait "$pid" || return 1
    # shellcheck disable=SC2048,SC2086
    records "$n" $* && return 0
    # shellcheck disable=SC2048,SC2086
    echo "recorded fewer than $n records: $(channels $* | wc -l)"
    return 1
}
records() {
    want=$1; shift
    channels "$@" | wc -l | { read -r got; [ "$got" -ge "$want" ]; }
}
# the channels of a log, one per record
channels() {
    python3 - "$@" <<'PY'
import struct, sys
for f in sys.argv[1:]:
    d, i = open(f, "rb").read(), 0
    while i + 28 <= len(d) and struct.unpack(">I", d[i:i + 4])[0] == 0xEDA1DA01:
        cl, dl = struct.unpack(">II", d[i + 20:i + 28])
        if i + 28 + cl + dl > len(d):
            break
        print(d[i + 28:i + 28 + cl].decode())
        i += 28 + cl + dl
PY
}

# Publishes samples of every type on JAVA.* (and OTHER.*, which the filter must leave out)
# while marie-record records JAVA.* only.
record_samples() {
    $BIN/marie-record -q -o "$T/run.lcmlog" -c 'JAVA\..*' &
    rec=$!
    wait_for 60 joined "$LCM_DEFAULT_URL" || return 1
    $SAMPLES publish JAVA. 2 "$T/published.txt" > "$T/expected.txt" || return 1
    $SAMPLES publish OTHER. 1 > /dev/null || return 1
    stop_recorder $rec "$LCM_DEFAULT_URL" "$(wc -l < "$T/published.txt")" "$T/run.lcmlog"
}

java_decodes() {
    mkdir -p "$T/classes" &&
    javac -nowarn -cp "$CP" -d "$T/classes" tests/tools/MarieLogDump.java &&
    java -cp "$T/classes:$CP" MarieLogDump "$JAR" "$T/run.lcmlog" > "$T/java.txt" &&
    python3 tests/tools/compare_canon.py "$T/expected.txt" "$T/java.txt"
}

no_other_channels() {
    ! grep -q '^#OTHER' "$T/java.txt" && ! grep -q 'unknown-type' "$T/java.txt"
}

# Plays FILES with marie-play ARGS while listening to REGEX; what is heard must equal the
# lines of WANT (channel, size, hash), in any order.
play_and_hear() {
    regex=$1; want=$2; shift 2
    n=$(wc -l < "$want")
    # The listener stops once it has heard all N, or after 60 s: a bound, not a budget the
    # playback must fit in (under load, a 15 s budget from the listener's start ran out)
    $SAMPLES listen "$regex" 60 "$n" > "$T/heard.txt" &
    l=$!
    wait_for 60 grep -q listening "$T/heard.txt" || return 1
    $BIN/marie-play "$@" || return 1
    wait $l
    grep -v listening "$T/heard.txt" | sort > "$T/h.txt"
    sort "$want" > "$T/w.txt"
    cmp -s "$T/h.txt" "$T/w.txt" || {
        echo "heard $(wc -l < "$T/h.txt") of $n"; diff "$T/w.txt" "$T/h.txt" | head
        grep '^Udp:' /proc/net/snmp      # where a datagram was lost: RcvbufErrors, InErrors
        return 1
    }
}

play_all() {
    play_and_hear 'JAVA\..*' "$T/published.txt" -s 20 "$T/run.lcmlog"
}

play_filtered() {
    grep '^JAVA\.pose' "$T/published.txt" > "$T/pose.txt"
    [ -s "$T/pose.txt" ] && play_and_hear 'JAVA\..*' "$T/pose.txt" -s 20 -c 'JAVA\.pose.*' "$T/run.lcmlog"
}

play_loop() {
    grep '^JAVA\.gyro_t ' "$T/published.txt" > "$T/g1.txt"
    cat "$T/g1.txt" "$T/g1.txt" > "$T/g2.txt"
    play_and_hear 'JAVA\.gyro_t' "$T/g2.txt" -s 20 --loop 2 -c 'JAVA\.gyro_t' "$T/run.lcmlog"
}

split_by_size() {
    $BIN/marie-record -q -o "$T/big" --split-mb 0.002 -c 'SPLIT\..*' &
    rec=$!
    wait_for 60 joined "$LCM_DEFAULT_URL" || return 1
    # 6 ms apart: the logger's handler stops to start each new file, and liblcm queues only 30
    # messages meanwhile (at 2 ms apart it lost some on a heavily loaded machine)
    XB_SAMPLES_PACE_MS=6 $SAMPLES publish SPLIT. 2 "$T/split.txt" > /dev/null || return 1
    stop_recorder $rec "$LCM_DEFAULT_URL" "$(wc -l < "$T/split.txt")" "$T/big.*" || return 1
    pieces=$(ls "$T"/big.* | wc -l)
    echo "split into $pieces files"
    [ "$pieces" -ge 2 ] && play_and_hear 'SPLIT\..*' "$T/split.txt" -s 20 $(ls "$T"/big.* | sort)
}

# --url beats the environment: what is published there is recorded, the default URL's is not
record_explicit_url() {
    $BIN/marie-record -q -o "$T/url.lcmlog" --url "$URL2" &
    rec=$!
    wait_for 60 joined "$URL2" || return 1
    $SAMPLES publish DEFAULT. 1 > /dev/null || return 1
    LCM_DEFAULT_URL=$URL2 $SAMPLES publish URL2. 1 "$T/url2.txt" > /dev/null || return 1
    n=$(wc -l < "$T/url2.txt")
    stop_recorder $rec "$URL2" "$n" "$T/url.lcmlog" || return 1
    ! records $((n + 1)) "$T/url.lcmlog" || { echo "the default URL's messages were recorded too"; return 1; }
    (LCM_DEFAULT_URL=$URL2; export LCM_DEFAULT_URL
     play_and_hear '.*' "$T/url2.txt" -s 20 --url "$URL2" "$T/url.lcmlog")
}

split_by_time() {
    $BIN/marie-record -q -o "$T/tm" --split-time 0.4 --duration 1.3 &&
    pieces=$(ls "$T"/tm.* | wc -l) && echo "split into $pieces files" && [ "$pieces" -ge 2 ]
}

spy_finds_every_type() {
    out=$($BIN/marie-spy --check) || return 1
    echo "$out"
    n=$(grep -c '^#' "$T/expected.txt")
    [ "$(echo "$out" | sed 's/[^0-9]*\([0-9]*\).*/\1/')" -eq $((n / 2)) ] &&
    $BIN/marie-spy --print-classpath | grep -q marie_types.jar
}

# The real lcm-spy, launched by `marie spy` on a virtual X display: a message of no known type
# and one of every marie type; a screenshot shows the Spy naming the marie types, not the other.
real_spy() {
    command -v Xvfb > /dev/null || { echo "Xvfb missing (scripts/install-deps.sh base)"; return 1; }
    Xvfb -displayfd 3 -screen 0 1280x800x24 -nolisten tcp 3> "$T/display" > "$T/xvfb.log" 2>&1 &
    xvfb=$!
    wait_for 30 test -s "$T/display" || { kill $xvfb; return 1; }
    export DISPLAY=":$(cat "$T/display")"
    timeout 120 $BIN/marie spy > "$T/spy.log" 2>&1 &
    spy=$!
    ok=1
    if wait_for 60 grep -q 'Found [1-9][0-9]* LCM types' "$T/spy.log"; then
        # the Spy subscribes once its window is up: send until the first row shows
        python3 -c "
import struct
with open('$T/unknown.lcmlog', 'wb') as f:
    ch, data = b'AAA.unknown', bytes(range(7, 39))
    f.write(struct.pack('>IqqII', 0xEDA1DA01, 0, 1, len(ch), len(data)) + ch + data)"
        spied() {
            lcm-logplayer "$T/unknown.lcmlog" > /dev/null 2>&1
            $SAMPLES publish SPY. 1 > /dev/null
            xwd -root -silent > "$T/spy.xwd" && python3 tests/tools/spy_check.py "$T/spy.xwd"
        }
        wait_for 60 spied && ok=0
    fi
    cat "$T/spy.log"
    kill $spy $xvfb 2>/dev/null
    wait $spy $xvfb 2>/dev/null
    unset DISPLAY
    return $ok
}

check record_with_a_channel_filter record_samples
check java_jar_decodes_every_type_from_the_log java_decodes
check filter_left_other_channels_out no_other_channels
check play_replays_every_message play_all
check play_channel_filter play_filtered
check play_loop_twice play_loop
check record_split_by_size_and_play_the_pieces split_by_size
check record_split_by_time split_by_time
check record_and_play_on_an_explicit_url record_explicit_url
check spy_classpath_has_every_type spy_finds_every_type
check real_lcm_spy_decodes_marie_types real_spy
finish
