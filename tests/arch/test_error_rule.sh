#!/bin/sh
# test_error_rule: one error rule (docs/architecture.md): a production function fails with -1 (or
# NULL) and errno, never by returning a negative errno. Production code is everything but tests/,
# bench/, fuzz/, the build and third-party code. Files not converted yet are named in
# tests/arch/error_rule.allow (managers/ only), printed at every run.
. tests/lib.sh
ALLOW=tests/arch/error_rule.allow

allowed() { grep -v '^#' "$ALLOW" | grep .; }

sources() {
    (cd "$1" && find . \( -path ./tests -o -path ./bench -o -path ./build -o -path ./fuzz -o -path ./.git \
        -o -name third_party -o -name vendor \) -prune -o -type f \
        \( -name '*.c' -o -name '*.cpp' -o -name '*.cc' -o -name '*.h' -o -name '*.hpp' \) -print) |
        sed 's|^\./||' | sort
}

E='-E[A-Z][A-Z0-9]*([^A-Za-z0-9_]|$)'     # a negative errno constant (-EXACT_MAX is none)
# violations ROOT: "file:line: code" for each return of a negative errno constant (`return
# -EINVAL;`, `return ok ? 0 : -EIO;`) and each `rc = -EINVAL;` under ROOT, comments left out.
# A comparison is not one (ALSA's calls return negative errnos: `n == -EAGAIN` reads them).
violations() {
    sources "$1" | (cd "$1" && xargs -r grep -nHE \
        -e "(^|[^A-Za-z0-9_])return[[:space:]]+$E" -e "(^|[^A-Za-z0-9_])return[^;]*[?:][[:space:]]*$E" \
        -e "[^=!<>]=[[:space:]]*-E[A-Z][A-Z0-9]*[[:space:]]*;") |
        grep -vE '^[^:]+:[0-9]+:[[:space:]]*(\*|/\*|//)'
}

no_negative_errno_is_returned() {
    v=$(violations .)
    for f in $(allowed); do
        n=$(echo "$v" | grep -c "^$f:")
        [ "$n" -gt 0 ] && echo "allowed until converted: $f ($n)"
        v=$(echo "$v" | grep -v "^$f:")
    done
    [ -z "$v" ] || { echo "$v"; echo "fail with errno instead: return marie_fail(EINVAL); (core/err.h)"; return 1; }
}

every_allowed_file_is_in_managers_and_needs_it() {
    v=$(violations .)
    for f in $(allowed); do
        case "$f" in managers/*) ;; *) echo "$f: only managers/ files may be allowed"; return 1 ;; esac
        echo "$v" | grep -q "^$f:" || { echo "$f follows the rule now: take it out of $ALLOW"; return 1; }
    done
}

# The rule is live: planted violations are caught in a scratch tree (never in the sources), and
# what is not one is left alone: a comment, a constant that only starts with E, a comparison,
# a test.
a_violation_is_caught() {
    t=$(mktemp -d)
    mkdir -p "$t/adapters/zz" "$t/tests/zz"
    cat > "$t/adapters/zz/probe.c" <<'C'
static int a(int x) { if (x) return -EINVAL; return 0; }
static int b(int x) { return x ? 0 : -EIO; }
static int c(int x) { int rc = 0; if (x) rc = -ENOMEM; return rc; }
/* returns -EINVAL when x is odd */
static int d(int x) { return x < -EXACT_MAX ? 1 : x == -EAGAIN; }
C
    echo 'static int e(void) { return -EINVAL; }' > "$t/tests/zz/probe.c"
    v=$(violations "$t")
    rm -rf "$t"
    echo "$v"
    [ "$(echo "$v" | grep -c '^adapters/zz/probe.c:[123]:')" -eq 3 ] && [ "$(echo "$v" | grep -c .)" -eq 3 ]
}

check "no production function returns a negative errno" no_negative_errno_is_returned
check "the allow-list names only managers/ files that still need it" every_allowed_file_is_in_managers_and_needs_it
check "a violation is caught" a_violation_is_caught
finish
