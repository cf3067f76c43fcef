#!/bin/sh
# test-light
# test_up_apply: `marie up` on a changed system applies the difference: only the components
# whose configuration hash changed restart, new ones start, removed ones stop, and the others
# go on as they run (same process, output still captured, still supervised); another system is
# still refused. A relative `exec` starts from the system file's folder, for marie up and for a
# marie-am started elsewhere, also when the manager runs a copy of the file (launch arguments).
. tests/lib.sh
T=$(mktemp -d /tmp/marie-test-apply.XXXXXX)
export MARIE_KEY=$T/key MARIE_SEQ_FILE=$T/seq MARIE_TEST_TRACE=$T/trace XDG_CACHE_HOME=$T/cache
M="$BIN/marie"
TOP=$(pwd)
AM_PID=
cleanup() { [ -n "$AM_PID" ] && kill "$AM_PID" 2>/dev/null; wait 2>/dev/null; rm -rf "$T"; }
trap cleanup EXIT
"$M" keygen "$T/key"
mkdir -p "$T/sys/bin"
cp "$B/tests/bin/marie-test-comp" "$T/sys/bin/tc"
: > "$T/trace"
# the manager runs from another folder than the system file's and than marie's
(cd / && exec "$TOP/$BIN/marie-am" --host alpha --state-dir "$T/am") > "$T/am.log" 2>&1 & AM_PID=$!
wait_for 15 "$M" ps --window 0.5 > /dev/null

# system NAME B_HZ WITH_C WITH_E: a, b (print_hz B_HZ), d (depends on b), c and e optional
system() {
    printf 'system: %s\nhosts: [alpha]\ncomponents:\n' "$1"
    printf '  a: {exec: bin/tc, params: {print_hz: 5}}\n'
    printf '  b: {exec: bin/tc, params: {print_hz: %s}}\n' "$2"
    printf '  d: {exec: bin/tc, depends: [b]}\n'
    [ "$3" = 1 ] && printf '  c: {exec: bin/tc}\n'
    [ "$4" = 1 ] && printf '  e: {exec: bin/tc}\n'
    return 0
}
system apply 1 1 0 > "$T/sys/s.yaml"
pid() { ps_field "$1" pid; }
execs() { grep -c " $1 exec " "$T/trace"; }

relative_up() {
    (cd "$T/sys" && "$TOP/$M" up s.yaml) > "$T/up1.out" 2>&1; rc=$?; cat "$T/up1.out" "$T/am.log"
    [ $rc -eq 0 ] && for c in a b c d; do [ "$(ps_field $c state)" = running ] || return 1; done
}
check "a relative exec from the file's folder: marie up passes and a manager started in / runs it" relative_up
A=$(pid a) B0=$(pid b) D=$(pid d) C=$(pid c)
echo "pids: a $A b $B0 c $C d $D"

# b's parameter changes, c goes, e comes
system apply 2 0 1 > "$T/sys/s.yaml"
applied() {
    "$M" up "$T/sys/s.yaml" > "$T/up2.out" 2>&1; rc=$?; cat "$T/up2.out"
    [ $rc -eq 0 ] && grep -q "alpha: applied the changes: restart b (configuration changed); start e (new); stop c (removed); 2 unchanged" "$T/up2.out"
}
check "marie up on a changed system answers what it does (exit 0)" applied
only_diff() {
    ps_field b pid; "$M" ps
    [ "$(pid a)" = "$A" ] && [ "$(pid d)" = "$D" ] && [ "$(execs a)" = 1 ] && [ "$(execs d)" = 1 ] &&
        [ "$(execs b)" = 2 ] && [ "$(pid b)" != "$B0" ] && [ "$(ps_field b state)" = running ] &&
        [ "$(ps_field e state)" = running ] && [ -z "$(ps_field c state)" ] && ! kill -0 "$C" 2>/dev/null
}
check "b restarted, e started, c stopped; a and d (depends on b) kept their processes" only_diff
new_hash() {
    want=$("$M" hash "$T/sys/s.yaml" | awk '$1 == "b" {print $2}')
    [ -n "$want" ] && [ "$(ps_field b config_hash)" = "$want" ] && grep -q "^b $want " "$T/am/config-hashes"
}
check "the manager records b's new configuration hash" new_hash
# a's output goes on reaching its log through the pipe carried into the new system
log_lines() { grep -c "line .* from a" "$T/am/logs/a.log"; }
output_kept() {
    n=$(log_lines); sleep 1.5; m=$(log_lines); echo "a's log: $n then $m lines"
    [ "$m" -ge $((n + 4)) ] && "$M" logs a -n 3 | grep -q "line .* from a"
}
check "a kept component's output is still captured" output_kept
a_back() { p=$(pid a); [ -n "$p" ] && [ "$p" != 0 ] && [ "$p" != "$A" ] && [ "$(ps_field a state)" = running ]; }
still_supervised() { kill -9 "$A"; wait_for 15 a_back && [ "$(execs a)" = 2 ]; }
check "a kept component is still restarted after kill -9" still_supervised
same_again() {
    n=$(wc -l < "$T/trace")
    "$M" up "$T/sys/s.yaml" > "$T/up3.out" 2>&1; rc=$?; cat "$T/up3.out"
    [ $rc -eq 0 ] && [ "$(wc -l < "$T/trace")" = "$n" ] && grep -q "is up on 1 host" "$T/up3.out"
}
check "the same file again starts and stops nothing" same_again
system other 2 0 1 > "$T/sys/o.yaml"
other_refused() {
    out=$("$M" up "$T/sys/o.yaml" 2>&1); rc=$?; echo "$out"
    [ $rc -ne 0 ] && echo "$out" | grep -q "another system (apply) is running here: marie down first" &&
        [ "$(ps_field a state)" = running ]
}
check "another system is refused while one runs" other_refused

# launch arguments: the manager runs its own copy of the filled-in file, from its state folder;
# the relative exec still starts from the user's file's folder
check "down" "$M" down
# ... and so do the components' relative types: (read by each component from the copy)
"$BIN/marie-types-gen" -o "$T/sys/gen" tests/data/types/reading.lcm --lang c > /dev/null
sed -e 's/print_hz: 5/print_hz: ${hz}/' -e 's/^hosts: \[alpha\]$/hosts: [alpha]\ntypes: [gen]/' "$T/sys/s.yaml" > "$T/sys/args.yaml"
copy_relative() {
    "$M" up "$T/sys/args.yaml" -a hz=3 > "$T/up4.out" 2>&1; rc=$?; cat "$T/up4.out"
    [ $rc -eq 0 ] && [ "$(ps_field a state)" = running ] && grep -q '^types: \[gen\]' "$T/am/system.yaml"
}
check "a relative exec and types: in a file with launch arguments (the manager's copy) run" copy_relative
elsewhere() {
    "$M" down > /dev/null
    (cd / && "$TOP/$M" up "$T/sys/s.yaml") > "$T/up5.out" 2>&1; rc=$?; cat "$T/up5.out"
    [ $rc -eq 0 ] && [ "$(ps_field b state)" = running ]
}
check "marie up from another folder finds the relative exec beside the file" elsewhere
missing() {
    sed 's|bin/tc}|bin/nosuch}|' "$T/sys/s.yaml" > "$T/sys/m.yaml"
    out=$("$M" up "$T/sys/m.yaml" 2>&1); rc=$?; echo "$out"
    [ $rc -eq 2 ] && echo "$out" | grep -q "m.yaml:[0-9]*:[0-9]*: component 'e': program '$T/sys/bin/nosuch': No such file or directory (a relative exec starts from the system file's folder)"
}
check "a relative exec that is not there is refused with where it was looked for" missing
# a change that takes time to apply (a component that ignores SIGTERM: killed after its 2 s
# stop_timeout): an up meanwhile is "busy", and a down drops the change
slow() { printf 'system: apply\nhosts: [alpha]\ncomponents:\n  a: {exec: bin/tc}\n  slow: {exec: '"'"'trap "" TERM; while :; do sleep 0.2; done'"'"', shell: true, args: [%s], heartbeat_timeout: 0, stop_timeout: 2}\n' "$1"; }
slow 1 > "$T/sys/slow.yaml"
check "a system with a component that ignores SIGTERM" "$M" up "$T/sys/slow.yaml"
busy_then_down() {
    slow 2 > "$T/sys/slow.yaml"
    "$M" up --no-wait "$T/sys/slow.yaml" > "$T/up6.out" 2>&1 || return 1
    "$M" up --no-wait "$T/sys/slow.yaml" > "$T/up7.out" 2>&1; rc=$?; cat "$T/up6.out" "$T/up7.out"
    [ $rc -ne 0 ] && grep -q "busy: the last up is being applied" "$T/up7.out" || return 1
    "$M" down > /dev/null && "$M" --json ps | grep -q '"name":"slow"' && [ -z "$(pgrep -f 'while :; do sleep 0.2')" ]
}
check "an up while a change is applied is busy; a down drops the change and stops all" busy_then_down
check "down" "$M" down
am_clean() {
    kill "$AM_PID"; wait "$AM_PID"; rc=$?; AM_PID=
    echo "marie-am exit $rc"; grep -A5 "Sanitizer" "$T/am.log"
    [ $rc -eq 0 ] && ! grep -q "Sanitizer" "$T/am.log"
}
check "the manager exits cleanly (no sanitizer report under SAN=1)" am_clean
finish
