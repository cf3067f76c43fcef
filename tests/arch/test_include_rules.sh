#!/bin/sh
# test_include_rules: the dependency rule of docs/architecture.md, read from the includes of
# every production source file (tests/ and benchmarks are not production code).
. tests/lib.sh

# allowed FILE: sets $ok to the include prefixes a production file may use, by the folder it
# is in ($d: its first two folders, e.g. adapters/planner).
allowed() {
    _rest=${1#*/}; d=${1%%/*}/${_rest%%/*}
    case "$1" in
    core/*)     ok="core/ lcmtypes/" ;;
    map/*)      ok="map/ core/ lcmtypes/" ;;
    camera/*)   ok="camera/ map/ core/ lcmtypes/" ;;
    ca/*)       ok="ca/ core/ lcmtypes/" ;;
    hw/*)       ok="hw/ core/ lcmtypes/" ;;
    proto/*)    ok="proto/ core/ lcmtypes/" ;;
    managers/*) ok="managers/ proto/ core/ lcmtypes/" ;;
    adapters/*) ok="$d/ adapters/common/ camera/ hw/ map/ ca/ core/ lcmtypes/" ;;
    sim/*)      ok="sim/ hw/ camera/ map/ core/ lcmtypes/" ;;
    tools/*)    ok="$d/ tools/webcommon/ proto/ map/ ca/ core/ lcmtypes/" ;;
    *)          ok="" ;;
    esac
}

production_files() {
    find core map camera ca hw proto managers adapters sim tools -type f \( -name '*.c' -o -name '*.cpp' -o -name '*.h' \) |
        sort
}

# Prints "file:line: includes X" for every include outside the file's allowed prefixes: the
# files with their prefixes, one a line, into one awk that reads them all.
violations() {
    production_files | while read -r f; do
        allowed "$f"
        printf '%s %s\n' "$f" "$ok"
    done | awk '{
        f = $1; n = 0
        while ((getline line < f) > 0) {
            n++
            if (line !~ /^#include "/) continue
            inc = line; sub(/^#include "/, "", inc); sub(/".*/, "", inc)
            if (inc !~ /\//) continue      # same-folder includes
            fine = 0
            for (i = 2; i <= NF; i++) if (index(inc, $i) == 1) fine = 1
            if (!fine) print f ":" n ": includes " inc
        }
        close(f)
    }'
}

every_include_follows_the_layers() {
    v=$(violations)
    [ -z "$v" ] || { echo "$v"; return 1; }
}

# The rule is live: a file that breaks it is caught (a scratch copy, never committed).
a_violation_is_caught() {
    f=adapters/planner/zz_rule_probe.h
    printf '#include "adapters/localizer/mcl.h"\n#include "tests/proc.h"\n' > "$f"
    v=$(violations | grep zz_rule_probe)
    rm -f "$f"
    [ "$(echo "$v" | grep -c .)" -eq 2 ]
}

# One loop idiom (docs/architecture.md): outside core/, where marie_loop is, no production file
# waits by itself (poll, epoll_wait, select, lcm_handle[_timeout]) or polls with a sleep (usleep,
# nanosleep, sleep: a child is waited for on its pidfd, a deadline is a timer). Benchmarks are not
# production code: their raw-LCM baselines wait the way a plain LCM program does, on purpose.
own_waits() {
    production_files | grep -v '^core/' | xargs grep -nE \
        '(^|[^_a-zA-Z0-9])(poll|epoll_wait|select|lcm_handle|lcm_handle_timeout|usleep|nanosleep|clock_nanosleep|sleep)[[:space:]]*\('
}
no_program_waits_outside_the_loop() {
    v=$(own_waits)
    [ -z "$v" ] || { echo "$v"; return 1; }
}
a_private_wait_is_caught() {
    f=adapters/planner/zz_loop_probe.c
    printf 'static void f(lcm_t *l) { lcm_handle_timeout(l, 50); }\nstatic int g(struct pollfd *p) { return poll(p, 1, 0) + co_sdo_client_poll(0, 0, 0); }\nstatic void h(void) { usleep(20000); marie_sleep_until(0); }\n' > "$f"
    v=$(own_waits | grep zz_loop_probe)
    rm -f "$f"
    [ "$(echo "$v" | grep -c .)" -eq 3 ]
}

# Benchmarks live in bench/ (they may include tests' helpers, which production code may not).
benchmarks_live_in_bench() {
    v=$(production_files | grep '/bench_')
    [ -z "$v" ] || { echo "benchmarks outside bench/: $v"; return 1; }
}

check every_include_follows_the_layers every_include_follows_the_layers
check a_violation_is_caught a_violation_is_caught
check "one loop: no program waits outside marie_loop" no_program_waits_outside_the_loop
check "one loop: a private wait is caught" a_private_wait_is_caught
check "benchmarks live in bench/" benchmarks_live_in_bench
finish
