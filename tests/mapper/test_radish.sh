#!/bin/sh
# test_radish: two real robots' logs that no one here made (tests/data/radish: freiburg-101 and
# seattle, GMapping-corrected CARMEN logs) imported with `marie log import carmen`, read back by
# LCM's own lcm-logplayer, mapped with the robot's own odometry and the default parameters as fast
# as the mapper goes (mapper_replay, the library as marie-mapper feeds it), and scored by `marie
# map eval` against GMapping's poses (a reference, not ground truth): the goals of
# docs/mapping.md, "Real robots' logs". Then one log played by lcm-logplayer at 50x into a live
# marie-mapper, its poses recorded by lcm-logger and scored the same way: what a user does with
# their own robot's log (its scans carry +inf for no return, REP 117).
. tests/lib.sh
B=${B:-build}
BIN=$B/bin
OUT=$B/test-logs/radish
rm -rf "$OUT" && mkdir -p "$OUT"
export LCM_DEFAULT_URL="udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608"
trap stop_started EXIT INT TERM
fig() { json "$OUT/$1.eval.json" "$2"; }
# messages of each kind lcm-logplayer plays from a log: "CHANNEL COUNT" lines
played() {
    lcm-logplayer -v -s 1000000 -l "$LCM_DEFAULT_URL" "$1" 2>/dev/null |
        awk '$2 == "Channel" { n[$3]++ } END { for (c in n) print c, n[c] }' | sort
}

for log in freiburg-101 seattle; do
    $BIN/marie-log import carmen tests/data/radish/$log-corrected.log.gz "$OUT/$log.lcm" > "$OUT/$log.import.txt" 2>&1
    rc=$?
    cat "$OUT/$log.import.txt"
    scans=$(awk '/^imported/ { print $5 }' "$OUT/$log.import.txt")
    odom=$(awk '/^imported/ { print $7 }' "$OUT/$log.import.txt")
    check "$log: imported, GMapping's re-basings chained into the robot's own odometry" \
        eval 'test "$rc" -eq 0 && grep -q "re-based the odometry" "$OUT/$log.import.txt"'
    played "$OUT/$log.lcm" > "$OUT/$log.played.txt"
    cat "$OUT/$log.played.txt"
    check "$log: LCM's lcm-logplayer reads every message of the imported log" \
        eval 'grep -qx "LASER $scans" "$OUT/$log.played.txt" && grep -qx "ODOMETRY $odom" "$OUT/$log.played.txt" &&
              grep -qx "REFERENCE $scans" "$OUT/$log.played.txt"'

    $B/tests/helpers/mapper_replay "$OUT/$log.lcm" --out "$OUT/$log.run.lcm" --save "$OUT/$log.built.yaml" > "$OUT/$log.replay.txt" 2>&1
    cat "$OUT/$log.replay.txt"
    $BIN/marie map eval "$OUT/$log.run.lcm" --reference "$OUT/$log.lcm" --png "$OUT/$log.png" --format json \
        > "$OUT/$log.eval.json" 2> "$OUT/$log.eval.err"
    cat "$OUT/$log.eval.json" "$OUT/$log.eval.err"
    check "$log: every scan mapped and scored (pairs = scans)" test "$(fig $log pairs)" -eq "$scans"
    check "$log: relation error over 1 m of path <= 0.06 m" le "$(fig $log re1)" 0.06
    check "$log: ATE <= 0.15 m after the rigid alignment" le "$(fig $log ate_rms)" 0.15
    check "$log: the map picture is written" test -s "$OUT/$log.png"
    # Its walls where GMapping's are: the map built from the robot's odometry against the one
    # drawn from GMapping's poses (each scan placed where GMapping placed it, the matcher off),
    # within one cell after the best small alignment; a doubled wall or a bent corridor lowers it.
    $B/tests/helpers/mapper_replay "$OUT/$log.lcm" --truth-odometry min_score=2 loop_closure=false \
        --save "$OUT/$log.reference.yaml" > /dev/null 2>&1
    $BIN/marie map compare "$OUT/$log.built.yaml" "$OUT/$log.reference.yaml" > "$OUT/$log.compare.txt" 2>&1
    cat "$OUT/$log.compare.txt"
    ap=$(awk '/aprecision/ { for (i = 1; i < NF; i++) if ($i == "aprecision") print $(i + 1) }' "$OUT/$log.compare.txt")
    check "$log: its walls are where GMapping's are (aligned precision >= 0.85)" le 0.85 "${ap:-0}"
done

# The live mapper, fed by LCM's own player at 50 times the robot's pace.
log=freiburg-101
start logger lcm-logger -q --lcm-url="$LCM_DEFAULT_URL" "--channel=^(POSE|MAP|MAP_UPDATE)$" "$OUT/live.lcm"
start mapper $BIN/marie-mapper --name mapper
sleep 1
lcm-logplayer -s 50 -l "$LCM_DEFAULT_URL" "$OUT/$log.lcm" > "$OUT/player.log" 2>&1
sleep 6     # the mapper's last map (it sends the whole map again every 5 s)
stop_started
pids=""
$BIN/marie map eval "$OUT/live.lcm" --reference "$OUT/$log.lcm" --png "$OUT/live.png" --format json > "$OUT/live.eval.json" 2>&1
cat "$OUT/live.eval.json"
tail -5 "$OUT/mapper.log"
scans=$(awk '/^imported/ { print $5 }' "$OUT/$log.import.txt")
check "live: no scan refused (its +inf beams are no returns, not bad input)" \
    eval '! grep -qiE "bad_(scan|nonfinite|payload)" "$OUT/mapper.log"'
check "live: a pose for nearly every scan (the mapper keeps pace at 50x)" \
    le "$(python3 -c "print(0.95 * $scans)")" "$(json "$OUT/live.eval.json" pairs)"
check "live: the map picture is written" test -s "$OUT/live.png"
finish
