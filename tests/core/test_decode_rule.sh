#!/bin/sh
# test-light
# test_decode_rule: no production source runs lcm-gen's decoder on bus bytes except core's checked path.
# lcm-gen's C decoders trust the wire (a lying array count or string length is a crash), so
# every payload from outside a process must go through marie_decode_checked() /
# marie_decode_input() (core/typeinfo.c), or the CAs' zero-copy ca_view_* readers. This test
# greps every C/C++ source outside tests/ and build/ for the generated decode entry points:
#   marie_X_t_decode(...)  __marie_X_t_decode_array(...)  ->decode(  .decode(
#   marie_X_t_subscribe(...) (the generated typed subscription decodes unchecked)
# Benchmarks (bench/, bench_*.c) read only what they send themselves in their own namespace and
# are not installed; they are reported but not failed. Run from the source root (or ROOT=dir).
. tests/lib.sh
ROOT=${ROOT:-.}

# Every matching line as file:line:text, outside tests/ and build*/ and the checked path.
offenders() {
    (cd "$ROOT" && grep -rnE --include='*.c' --include='*.cpp' --include='*.h' --include='*.hpp' \
        -e 'marie_[a-z0-9_]+_t_decode(_array)?[[:space:]]*\(' \
        -e '(->|\.)[[:space:]]*decode[[:space:]]*\(' \
        -e 'marie_[a-z0-9_]+_t_subscribe[[:space:]]*\(' \
        --exclude-dir=tests --exclude-dir='build*' --exclude-dir=.git . |
        sed 's|^\./||' |
        grep -v '^core/typeinfo\.c:')
}

production() { offenders | grep -vE '^bench/|(^|/)bench_[^/:]*:'; }

# The patterns must see what they are meant to: a canary of each kind is caught.
canaries_caught() {
    d=$(mktemp -d) || return 1
    mkdir -p "$d/adapters/x" "$d/core"
    printf '%s\n' 'if (t->decode(buf, 0, n, &m) < 0)' 'marie_estop_t_decode(buf, 0, n, &e);' \
        'marie_laser_scan_t_subscribe(lcm, "L", cb, NULL);' 'msg.decode(buf, 0, n);' > "$d/adapters/x/a.c"
    printf '%s\n' 'return t->decode(buf, 0, (int)len, out);' > "$d/core/typeinfo.c"
    n=$(ROOT=$d offenders | grep -c '^adapters/x/a.c:')
    allowed=$(ROOT=$d offenders | grep -c '^core/')
    rm -rf "$d"
    [ "$n" -eq 4 ] && [ "$allowed" -eq 0 ]
}

no_unchecked_decode() {
    out=$(production)
    [ -z "$out" ] && return 0
    echo "generated decoders called outside core's checked path (use marie_decode_input or marie_decode_checked):"
    echo "$out" | sed 's/^/    /'
    return 1
}

# Cleanup calls (decode_cleanup) free what the checked path decoded: they must stay allowed.
cleanup_not_flagged() { ! offenders | grep -q '_decode_cleanup'; }

check "the patterns catch every kind of direct decode" canaries_caught
check "no production source decodes bus bytes outside the checked path" no_unchecked_decode
check "decode_cleanup calls are not mistaken for decodes" cleanup_not_flagged
echo "benchmarks with their own decoders (not failed): $(offenders | grep -cE '^bench/|(^|/)bench_[^/:]*:')"
finish
