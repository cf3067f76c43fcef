#!/bin/sh
# test-light
# test_run_tests: scripts/run-tests.sh counts what ran: a program that exits 0 with no case and
# no SKIPPED line fails, an explicit skip is counted as skipped, and the summary says so; with
# --jobs the programs before `--` run side by side, the longest of the last run first, and are
# reported in order, counted once; a program is killed at TEST_TIMEOUT unless its head declares
# a longer "# test-timeout: N"; one after `--` whose head says "# test-light" runs beside those
# before it and then beside the others after it (two light ones at a time unless LIGHT_LANES
# says otherwise), those after it of one "# test-group: NAME" run side by side, and those after
# a second `--` run last, once the light ones are done.
. tests/lib.sh
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT INT TERM
printf '#!/bin/sh\necho "nothing to do here"\nexit 0\n' > "$tmp/silent.sh"
printf '. tests/lib.sh\nskip "device" "no device here"\nexit 0\n' > "$tmp/skips.sh"
printf '. tests/lib.sh\ncheck "one" true\ncheck "two" true\nfinish\n' > "$tmp/passes.sh"
printf '. tests/lib.sh\ncheck "good" true\ncheck "bad" false\nfinish\n' > "$tmp/fails.sh"
printf '#!/bin/sh\nexit 3\n' > "$tmp/crashes.sh"
run() { B="$tmp" scripts/run-tests.sh "$@" > "$tmp/out" 2>&1; echo $? > "$tmp/rc"; cat "$tmp/out"; }
# reported NAMES SUMMARY [RC]: the programs' lines came in this order, the last line is SUMMARY
# (and the exit status RC).
reported() {
    [ "$(grep -E '^(PASS|FAIL) ' "$tmp/out" | awk '{print $2}' | tr '\n' ' ')" = "$1 " ] &&
        [ "$(tail -1 "$tmp/out")" = "$2" ] && { [ -z "${3:-}" ] || [ "$(cat "$tmp/rc")" -eq "$3" ]; }
}

run "$tmp/silent.sh"
check "a program that runs no case fails" grep -q '^FAIL silent.sh' "$tmp/out"
check "it is counted as one failure, exit status 1" \
    sh -c "tail -1 $tmp/out | grep -qx '0 passed, 1 failed, 0 skipped' && [ \$(cat $tmp/rc) -eq 1 ]"
check "the failure says no case ran" grep -q 'ran no case' "$tmp/out"

run "$tmp/skips.sh" "$tmp/passes.sh"
check "an explicit skip passes the program and names its reason" \
    sh -c "grep -q '^PASS skips.sh .* 1 skipped' $tmp/out && grep -q 'device: no device here' $tmp/out"
check "summary counts passes and skips, exit status 0" \
    sh -c "tail -1 $tmp/out | grep -qx '2 passed, 0 failed, 1 skipped' && [ \$(cat $tmp/rc) -eq 0 ]"

run "$tmp/fails.sh" "$tmp/crashes.sh"
check "failed cases and a failing exit are counted" \
    sh -c "tail -1 $tmp/out | grep -qx '1 passed, 2 failed, 0 skipped' && [ \$(cat $tmp/rc) -eq 1 ]"
check "the report names the failed case" grep -qx '    \[  FAILED  \] bad' "$tmp/out"

# sleeper FILE [HEAD]: a program (HEAD its first line) that sleeps 2 s between a "start" and an
# "end" line in $tmp/events; most: how many such programs ran at once (from the last `rm`).
sleeper() { printf '%s\n. tests/lib.sh\necho start >> "%s/events"\nsleep 2\necho end >> "%s/events"\ncheck "slept" true\nfinish\n' \
    "${2:-}" "$tmp" "$tmp" > "$1"; }
most() { awk '{ n += $1 == "start" ? 1 : -1; if (n > m) m = n } END { print m + 0 }' "$tmp/events"; }
sleeper "$tmp/slow.sh"
printf '# test-timeout: 10\n. tests/lib.sh\nsleep 2\ncheck "long by design" true\nfinish\n' > "$tmp/long.sh"
TEST_TIMEOUT=1 run "$tmp/slow.sh" "$tmp/long.sh"
check "a program over TEST_TIMEOUT is killed; one that declares a longer test-timeout is not" \
    sh -c "grep -q '^FAIL slow.sh' $tmp/out && grep -q 'timed out after 1s' $tmp/out && grep -q '^PASS long.sh' $tmp/out"
rm -f "$tmp/events"
run --jobs 2 "$tmp/slow.sh" "$tmp/slow.sh" "$tmp/fails.sh" -- "$tmp/skips.sh" "$tmp/passes.sh"
check "--jobs: every program reported once, in order, the summary counts them all" \
    reported 'slow.sh slow.sh fails.sh skips.sh passes.sh' '5 passed, 1 failed, 1 skipped' 1
check "--jobs 2: two programs run side by side ($(most) at once)" [ "$(most)" -eq 2 ]
sleeper "$tmp/light.sh" '# test-light'
rm -f "$tmp/events"
run --jobs 2 "$tmp/slow.sh" "$tmp/slow.sh" -- "$tmp/light.sh" "$tmp/passes.sh"
check "--jobs: a test-light program after -- runs beside those before it, reported after the others ($(most) at once)" \
    eval 'reported "slow.sh slow.sh passes.sh light.sh" "5 passed, 0 failed, 0 skipped" && [ "$(most)" -eq 3 ]'
# (two programs of one name side by side would share one log: two copies)
cp "$tmp/passes.sh" "$tmp/p1.sh"
cp "$tmp/passes.sh" "$tmp/p2.sh"
rm -f "$tmp/events"
run --jobs 2 "$tmp/p1.sh" "$tmp/p2.sh" -- "$tmp/light.sh" "$tmp/slow.sh"
check "--jobs: a test-light program still running when those before -- are done runs on beside the others after -- ($(most) at once)" \
    eval 'reported "p1.sh p2.sh slow.sh light.sh" "6 passed, 0 failed, 0 skipped" && [ "$(most)" -eq 2 ]'
sleeper "$tmp/g1.sh" '# test-group: pair'
cp "$tmp/g1.sh" "$tmp/g2.sh"
rm -f "$tmp/events"
run --jobs 2 "$tmp/p1.sh" "$tmp/p2.sh" -- "$tmp/g1.sh" "$tmp/passes.sh" "$tmp/g2.sh"
check "--jobs: the tests of one test-group after -- run side by side, printed where the first of them is ($(most) at once)" \
    eval 'reported "p1.sh p2.sh g1.sh g2.sh passes.sh" "8 passed, 0 failed, 0 skipped" && [ "$(most)" -eq 2 ]'
printf '#!/bin/sh\n# test-light\n. tests/lib.sh\nsleep 1\ncheck "light" true\n: > "%s/light.done"\nfinish\n' "$tmp" > "$tmp/light1.sh"
printf '. tests/lib.sh\ncheck "the light test was done before" test -f "%s/light.done"\nfinish\n' "$tmp" > "$tmp/alone.sh"
run --jobs 2 "$tmp/p1.sh" "$tmp/p2.sh" -- "$tmp/light1.sh" -- "$tmp/alone.sh"
check "--jobs: a test after a second -- runs last, once the light lane is done" \
    reported 'p1.sh p2.sh light1.sh alone.sh' '6 passed, 0 failed, 0 skipped'
for q in q1 q2 q3; do
    printf '. tests/lib.sh\necho %s >> "%s/started"\nsleep 1\ncheck "%s" true\nfinish\n' $q "$tmp" $q > "$tmp/$q.sh"
done
rm -f "$tmp/test-logs/durations"
run --jobs 2 "$tmp/q1.sh" "$tmp/q2.sh" "$tmp/q3.sh"
check "--jobs: the times of a run are recorded for the next one" \
    sh -c "grep -q '^q3.sh [0-9]' $tmp/test-logs/durations && grep -c . $tmp/test-logs/durations | grep -qx 3"
printf 'q1.sh 1\nq2.sh 2\nq3.sh 9\n' > "$tmp/test-logs/durations"
rm -f "$tmp/started"
run --jobs 2 "$tmp/q1.sh" "$tmp/q2.sh" "$tmp/q3.sh"
check "--jobs: the longest of the last run are taken first, reported in list order" \
    eval 'reported "q1.sh q2.sh q3.sh" "3 passed, 0 failed, 0 skipped" && [ "$(head -2 "$tmp/started" | sort | tr "\n" " ")" = "q2 q3 " ]'
cp "$tmp/light.sh" "$tmp/light2.sh"
rm -f "$tmp/events"
run --jobs 2 "$tmp/p1.sh" "$tmp/p2.sh" -- "$tmp/light2.sh" "$tmp/light.sh"
check "--jobs: two test-light programs run side by side in two lanes, reported in list order ($(most) at once)" \
    eval 'reported "p1.sh p2.sh light2.sh light.sh" "6 passed, 0 failed, 0 skipped" && [ "$(most)" -eq 2 ]'
rm -f "$tmp/events"
LIGHT_LANES=1 run --jobs 2 "$tmp/p1.sh" "$tmp/p2.sh" -- "$tmp/light2.sh" "$tmp/light.sh"
check "--jobs with LIGHT_LANES=1: the test-light programs run one after the other ($(most) at once)" \
    eval 'reported "p1.sh p2.sh light2.sh light.sh" "6 passed, 0 failed, 0 skipped" && [ "$(most)" -eq 1 ]'
run "$tmp/light.sh" -- "$tmp/light.sh"
check "without --jobs a test-light program runs like the others" \
    sh -c "grep -c '^PASS light.sh' $tmp/out | grep -qx 2 && tail -1 $tmp/out | grep -qx '2 passed, 0 failed, 0 skipped'"
# A run stopped midway (SIGTERM while two programs sleep) leaves no results folder behind.
mkdir "$tmp/t"; rm -f "$tmp/events"
B="$tmp" TMPDIR="$tmp/t" scripts/run-tests.sh --jobs 2 "$tmp/slow.sh" "$tmp/slow.sh" > "$tmp/out" 2>&1 &
stopped=$!
for _ in $(seq 50); do [ -s "$tmp/events" ] && break; sleep 0.1; done
kill -TERM "$stopped"; wait "$stopped"; echo $? > "$tmp/rc"
check "a run stopped midway exits 130 and removes its results folder ($(ls "$tmp/t" | wc -l) left)" \
    eval '[ "$(cat "$tmp/rc")" -eq 130 ] && [ -z "$(ls "$tmp/t")" ]'
finish
