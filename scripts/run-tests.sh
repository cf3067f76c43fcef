#!/bin/sh
# Runs marie's tests, each in its own network namespace with a time limit, and prints one
# summary line "N passed, N failed, N skipped". Cases are counted from cmocka's "[       OK ]",
# "[  FAILED  ]" and "[  SKIPPED ]" lines (tests/lib.sh prints the same for shell tests: its
# `skip NAME REASON` prints "[  SKIPPED ] NAME: REASON"). A program that fails without naming
# a case counts as one failure, and so does one that exits 0 having run no case and skipped
# none: a test that silently does nothing is a failure, never a pass. Logs go to $B/test-logs/.
#   scripts/run-tests.sh [--jobs N] TEST... [-- TEST... [-- TEST...]]   (env: B, TEST_TIMEOUT seconds per
#   program, default 300; a test whose first lines say "# test-timeout: N" gets N when that is
#   more, for a run that is long by design): with --jobs, the tests before `--` run N at a time (each in its own
#   namespace; a worker takes the next test as it finishes one, the longest of the last run
#   first by $B/test-logs/durations, which every run updates; their lines print when all are
#   done, in order), those after it one at a time. A test after `--` whose first lines say
#   "# test-light" (it mostly waits, and checks no timing that busy cores would break) runs in
#   lanes of their own from the start, LIGHT_LANES (default 2) light tests at a time, beside
#   the N and then beside the others after `--`; those run one at a time once the N are done, each printed as it
#   ends, and the light tests' lines print last, in order. Tests after `--` whose first lines
#   say "# test-group: NAME" (each was checked to keep its margins beside the others) run
#   side by side, all of that NAME at once where the first of them is in the list. Tests after
#   a second `--` (that need the cores to themselves) run last, one at a time, once all the
#   others are done, the light ones too. A test whose first lines say
#   "# test-keep-user" runs in a network namespace that keeps the caller's user where it may
#   (scripts/netns-run).
set -u
B=${B:-build}
logs=$B/test-logs
# Sanitizer builds: fail on the first report; known third-party leaks are suppressed.
export ASAN_OPTIONS=${ASAN_OPTIONS:-abort_on_error=1:detect_leaks=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$(pwd)/tests/lsan.supp}
mkdir -p "$logs"
# run_one TEST RESULT: runs it; its counts go to RESULT.counts, its report to stdout.
run_one() {
    t=$1
    name=$(basename "$t")
    log=$logs/$name.log
    start=$(date +%s)
    case "$t" in
    *.sh) cmd="sh $t" ;;
    *.py) cmd="python3 $t" ;;
    *) cmd="$t" ;;
    esac
    limit=${TEST_TIMEOUT:-300}
    own=$(head -20 "$t" 2>/dev/null | sed -n 's/^# test-timeout: \([0-9][0-9]*\)$/\1/p' | head -1)
    [ -n "$own" ] && [ "$own" -gt "$limit" ] && limit=$own
    keep=0
    head -20 "$t" 2>/dev/null | grep -q '^# test-keep-user$' && keep=1
    # Own process group and network namespace; a hung test is killed whole.
    B=$B MARIE_NETNS_KEEP_USER=$keep timeout -k 5 "$limit" scripts/netns-run $cmd > "$log" 2>&1 < /dev/null
    rc=$?
    ok=$(grep -c '^\[       OK \]' "$log")
    bad=$(grep '^\[  FAILED  \] [^0-9]' "$log" | sort -u | wc -l)
    # cmocka lists skipped names twice (as run, and in its summary): count names once
    skip=$(grep '^\[  SKIPPED \] [^0-9]' "$log" | sort -u | wc -l)
    nocase=0
    if [ "$rc" -ne 0 ] && [ "$bad" -eq 0 ]; then bad=1; fi
    if [ "$rc" -eq 0 ] && [ "$ok" -eq 0 ] && [ "$bad" -eq 0 ] && [ "$skip" -eq 0 ]; then
        bad=1; nocase=1
    fi
    secs=$(( $(date +%s) - start ))
    echo "$name $secs" >> "$logs/durations.new"
    echo "$ok $bad $skip $name" > "$2.counts"
    if [ "$bad" -eq 0 ]; then
        if [ "$skip" -eq 0 ]; then
            printf 'PASS %-40s %4d cases %4ds\n' "$name" "$ok" "$secs"
        else
            printf 'PASS %-40s %4d cases %3d skipped %4ds\n' "$name" "$ok" "$skip" "$secs"
            grep '^\[  SKIPPED \] [^0-9]' "$log" | sort -u | head -5 | sed 's/^/    /'
        fi
    else
        printf 'FAIL %-40s %4d ok %3d failed %4ds (exit %d; log %s)\n' "$name" "$ok" "$bad" "$secs" "$rc" "$log"
        grep -E '^\[  FAILED  \] [^0-9]|^\[  ERROR   \]|^\[   LINE   \]|Assert|ERROR: ' "$log" | head -20 | sed 's/^/    /'
        [ "$rc" -eq 124 ] && echo "    (timed out after ${limit}s)"
        [ "$nocase" -eq 1 ] && echo "    (exited 0 but ran no case and printed no [  SKIPPED ] line)"
    fi
}

passed=0; failed=0; skipped=0; failed_names=""
# tally RESULT: adds a finished test's counts and prints its report.
tally() {
    read -r ok bad skip name < "$1.counts"
    passed=$((passed + ok)); failed=$((failed + bad)); skipped=$((skipped + skip))
    [ "$bad" -eq 0 ] || failed_names="$failed_names $name"
    cat "$1"
    rm -f "$1" "$1.counts"
}
jobs=1
if [ "${1:-}" = --jobs ]; then jobs=$2; shift 2; fi
res=$(mktemp -d "${TMPDIR:-/tmp}/marie-tests.XXXXXX")
# Interrupted (Ctrl-C, a time limit), the workers go and so does the results folder.
pids=""; lane_pids=""
# shellcheck disable=SC2086
trap 'trap - INT TERM HUP; kill $pids $lane_pids 2>/dev/null; rm -rf "$res"; exit 130' INT TERM HUP
# The tests before `--` may run side by side (all of them when there is no `--`).
n=0
for t in "$@"; do
    [ "$t" = -- ] && break
    n=$((n + 1))
done
# light TEST: its head says "# test-light".
light() { head -20 "$1" 2>/dev/null | grep -q '^# test-light\($\|:\)'; }
# group TEST: the NAME its head gives as "# test-group: NAME", if any.
group() { head -20 "$1" 2>/dev/null | sed -n 's/^# test-group: \([A-Za-z0-9_-]*\)$/\1/p' | head -1; }
# take COUNTER: the next number of a counter file shared by workers (under flock).
take() { flock "$1" sh -c 'i=$(cat "$1"); echo $((i + 1)) > "$1"; echo "$i"' _ "$1"; }
# workers N NAME: N workers run the tests listed in $res/NAME (one a line), taking them in the
# order of the line numbers (from 0) in $res/NAME.order; the result of line i goes to
# $res/NAMEi. Their pids in $pids.
workers() {
    echo 0 > "$res/$2.next"
    pids=""
    q=0
    while [ "$q" -lt "$1" ]; do
        (while :; do
             i=$(sed -n "$(( $(take "$res/$2.next") + 1 ))p" "$res/$2.order")
             [ -n "$i" ] || break
             run_one "$(sed -n "$((i + 1))p" "$res/$2")" "$res/$2$i" > "$res/$2$i"
         done) &
        pids="$pids $!"
        q=$((q + 1))
    done
}
lane=0
if [ "$jobs" -gt 1 ] && [ "$n" -gt 1 ]; then
    lane=1
    # The light tests after `--`, LIGHT_LANES (default 2) at a time, in list order, beside the
    # workers and then beside the others after `--`.
    : > "$res/l"
    seen=0
    for t in "$@"; do
        if [ "$t" = -- ]; then seen=$((seen + 1))
        elif [ "$seen" = 1 ] && light "$t"; then echo "$t" >> "$res/l"
        fi
    done
    awk '{ print NR - 1 }' "$res/l" > "$res/l.order"
    workers "${LIGHT_LANES:-2}" l
    lane_pids=$pids
    # The tests before `--`, `jobs` at a time: a long test holds one worker while the others go
    # on through the list; the longest are taken first, by the times of the last run
    # ($logs/durations; a test it does not know counts as longest), so that no long one is left
    # to run alone at the end.
    dur=$logs/durations
    [ -f "$dur" ] || dur=/dev/null
    : > "$res/p"
    i=0
    for t in "$@"; do
        [ "$t" = -- ] && break
        echo "$t" >> "$res/p"
        echo "$i $(basename "$t")"
        i=$((i + 1))
    done | awk 'FILENAME != "-" { d[$1] = $2; next } { print ($2 in d ? d[$2] : 1e9), $1 }' "$dur" - |
        sort -s -k1,1gr | awk '{ print $2 }' > "$res/p.order"
    workers "$jobs" p
    # shellcheck disable=SC2086
    wait $pids
    i=0
    while [ "$i" -lt "$n" ]; do tally "$res/p$i"; i=$((i + 1)); done
    shift "$n"
fi
# After `--`: one at a time; with the lane, those of a group side by side, and those after a
# second `--` once all else is done, the light lane too.
i=0; groups=""; sec=0
for t in "$@"; do
    if [ "$t" = -- ]; then sec=$((sec + 1)); continue; fi
    g=""
    if [ "$lane" = 1 ]; then
        [ "$sec" -ge 2 ] && continue
        light "$t" && continue
        g=$(group "$t")
    fi
    if [ -z "$g" ]; then
        run_one "$t" "$res/s$i" > "$res/s$i"
        tally "$res/s$i"
        i=$((i + 1))
        continue
    fi
    # The first of a group: every test of that group runs now, side by side.
    case " $groups " in *" $g "*) continue ;; esac
    groups="$groups $g"
    members=""; started=""; usec=0
    for u in "$@"; do
        if [ "$u" = -- ]; then usec=$((usec + 1)); continue; fi
        [ "$usec" = 1 ] && ! light "$u" && [ "$(group "$u")" = "$g" ] || continue
        run_one "$u" "$res/s$i" > "$res/s$i" &
        started="$started $!"; members="$members s$i"
        i=$((i + 1))
    done
    # shellcheck disable=SC2086
    wait $started
    for m in $members; do tally "$res/$m"; done
done
if [ "$lane" = 1 ]; then
    # shellcheck disable=SC2086
    wait $lane_pids
    k=0
    while [ -f "$res/l$k.counts" ]; do tally "$res/l$k"; k=$((k + 1)); done
    sec=0
    for t in "$@"; do
        if [ "$t" = -- ]; then sec=$((sec + 1)); continue; fi
        [ "$sec" -ge 2 ] || continue
        run_one "$t" "$res/s$i" > "$res/s$i"
        tally "$res/s$i"
        i=$((i + 1))
    done
fi
rm -f "$res/p" "$res/p.order" "$res/p.next" "$res/l" "$res/l.order" "$res/l.next"
# The times of this run replace those of the last one for the next ordering.
cat "$logs/durations" "$logs/durations.new" 2>/dev/null | awk '{ d[$1] = $2 } END { for (k in d) print k, d[k] }' \
    > "$logs/durations.tmp" && mv "$logs/durations.tmp" "$logs/durations"
rm -f "$logs/durations.new"
rmdir "$res" 2>/dev/null
[ -n "$failed_names" ] && echo "failed:$failed_names"
echo "$passed passed, $failed failed, $skipped skipped"
[ "$failed" -eq 0 ]
