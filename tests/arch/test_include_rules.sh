#!/bin/sh
# test_include_rules: the dependency rule of docs/architecture.md, read from the includes of
# every production source file (tests/ and benchmarks are not production code).
. tests/lib.sh

# allowed FILE: the include prefixes a production file may use, by the folder it is in.
allowed() {
    case "$1" in
    core/*)     echo "core/ lcmtypes/" ;;
    map/*)      echo "map/ core/ lcmtypes/" ;;
    camera/*)   echo "camera/ map/ core/ lcmtypes/" ;;
    ca/*)       echo "ca/ core/ lcmtypes/" ;;
    hw/*)       echo "hw/ core/ lcmtypes/" ;;
    managers/*) echo "managers/ core/ lcmtypes/" ;;
    adapters/*) d=$(echo "$1" | cut -d/ -f1-2); echo "$d/ adapters/common/ camera/ hw/ map/ ca/ core/ lcmtypes/" ;;
    sim/*)      echo "sim/ hw/ camera/ map/ core/ lcmtypes/" ;;
    tools/*)    d=$(echo "$1" | cut -d/ -f1-2); echo "$d/ tools/webcommon/ managers/am_proto.h map/ ca/ core/ lcmtypes/" ;;
    *)          echo "" ;;
    esac
}

production_files() {
    find core map camera ca hw managers adapters sim tools -type f \( -name '*.c' -o -name '*.cpp' -o -name '*.h' \) |
        grep -v '/bench_' | sort
}

# Prints "file:line: includes X" for every include outside the file's allowed prefixes.
violations() {
    production_files | while read -r f; do
        ok=$(allowed "$f")
        grep -n '^#include "' "$f" | while IFS= read -r line; do
            inc=$(echo "$line" | sed 's/^[0-9]*:#include "\([^"]*\)".*/\1/')
            n=${line%%:*}
            case "$inc" in */*) ;; *) continue ;; esac   # same-folder includes
            fine=0
            for p in $ok; do case "$inc" in "$p"*) fine=1 ;; esac; done
            [ "$fine" = 1 ] || echo "$f:$n: includes $inc"
        done
    done
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

check every_include_follows_the_layers every_include_follows_the_layers
check a_violation_is_caught a_violation_is_caught
finish
