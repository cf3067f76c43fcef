#!/bin/sh
# test_marie_tools: marie-record, marie-play and marie-spy on a real bus (the test's own network
# namespace): filters, splitting, speed and loop, and every marie type decoded from a recorded
# log by the Java types jar.
. tests/lib.sh
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
SAMPLES=$B/tests/bin/xb-samples
JAR=$B/java/marie_types.jar
CP=$JAR:/usr/share/java/lcm.jar

# Publishes samples of every type on JAVA.* (and OTHER.*, which the filter must leave out)
# while marie-record records JAVA.* only.
record_samples() {
    $BIN/marie-record -q -o "$T/run.lcmlog" -c 'JAVA\..*' &
    rec=$!
    wait_for 5 test -f "$T/run.lcmlog" || return 1
    sleep 0.3
    $SAMPLES publish JAVA. 2 "$T/published.txt" > "$T/expected.txt" || return 1
    $SAMPLES publish OTHER. 1 > /dev/null || return 1
    sleep 0.5
    kill -INT $rec
    wait $rec
    test -s "$T/run.lcmlog"
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
    $SAMPLES listen "$regex" 15 "$n" > "$T/heard.txt" &
    l=$!
    wait_for 5 grep -q listening "$T/heard.txt" || return 1
    $BIN/marie-play "$@" || return 1
    wait $l
    grep -v listening "$T/heard.txt" | sort > "$T/h.txt"
    sort "$want" > "$T/w.txt"
    cmp -s "$T/h.txt" "$T/w.txt" || { echo "heard $(wc -l < "$T/h.txt") of $n"; diff "$T/w.txt" "$T/h.txt" | head; return 1; }
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
    wait_for 5 sh -c "ls '$T'/big* >/dev/null 2>&1" || return 1
    sleep 0.3
    $SAMPLES publish SPLIT. 2 "$T/split.txt" > /dev/null || return 1
    sleep 0.5
    kill -INT $rec
    wait $rec
    pieces=$(ls "$T"/big.* | wc -l)
    echo "split into $pieces files"
    [ "$pieces" -ge 2 ] && play_and_hear 'SPLIT\..*' "$T/split.txt" -s 20 $(ls "$T"/big.* | sort)
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

helps() {
    $BIN/marie-record --help >/dev/null && $BIN/marie-play --help >/dev/null && $BIN/marie-spy --help >/dev/null
}

check record_with_a_channel_filter record_samples
check java_jar_decodes_every_type_from_the_log java_decodes
check filter_left_other_channels_out no_other_channels
check play_replays_every_message play_all
check play_channel_filter play_filtered
check play_loop_twice play_loop
check record_split_by_size_and_play_the_pieces split_by_size
check record_split_by_time split_by_time
check spy_classpath_has_every_type spy_finds_every_type
check tools_have_help helps
finish
