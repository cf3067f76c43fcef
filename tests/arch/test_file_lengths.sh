#!/bin/sh
# test_file_lengths: no production file is over 800 lines (docs/architecture.md): a file that
# grows past it is split along its seams. Nothing is exempt.
. tests/lib.sh
MAX=800

production_files() {
    find core map camera ca hw managers adapters sim tools scripts -type f \
        \( -name '*.c' -o -name '*.cpp' -o -name '*.h' -o -name '*.py' -o -name '*.js' -o -name '*.sh' \) | sort
}

too_long() {
    production_files | xargs wc -l | awk -v max="$MAX" '$2 != "total" && $1 > max { print $2 ": " $1 " lines" }'
}

no_production_file_is_over_800_lines() {
    v=$(too_long)
    [ -z "$v" ] || { echo "$v"; return 1; }
}

# The rule is live: a long file is caught (a scratch copy, never committed).
a_long_file_is_caught() {
    f=tools/map/zz_length_probe.c
    seq 1 $((MAX + 1)) | sed 's|^|// |' > "$f"
    v=$(too_long | grep zz_length_probe)
    rm -f "$f"
    [ -n "$v" ]
}

check "no production file is over $MAX lines" no_production_file_is_over_800_lines
check "a long file is caught" a_long_file_is_caught
finish
