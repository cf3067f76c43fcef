#!/bin/sh
# test_exports: every function the production code exports (libraries and programs alike) is
# called from another file (a program, a library, a test or a benchmark), or is named for users
# in tests/arch/exports.allow: a function used in its own file is static, one used nowhere is
# removed (docs/core.md, "Components"). Read from the objects the build left in $B/obj; C++
# members (mangled names) are the classes' business and not checked.
. tests/lib.sh

production() { grep -v -e "^$B/obj/tests/" -e "^$B/obj/bench/" -e "^$B/obj/build/" -e "^$B/obj/gen/"; }

# unused_exports OBJ...: "function object" for each function a production object among OBJ
# defines that no other object among them refers to, less those allowed.
unused_exports() {
    t=$(mktemp -d)
    nm -A -u "$@" | awk '{ sub(/:$/, "", $1); print $NF, $1 }' > "$t/uses"
    nm -A -g --defined-only $(printf '%s\n' "$@" | production) |
        awk '$2 == "T" { sub(/:[0-9a-f]*$/, "", $1); print $3, $1 }' > "$t/defs"
    allowed > "$t/allow"
    awk 'FILENAME == ARGV[1] { ok[$1] = 1; next }
         FILENAME == ARGV[2] { users[$1] = users[$1] " " $2; next }
         $1 == "main" || $1 == "LLVMFuzzerTestOneInput" || $1 ~ /^_Z/ || ($1 in ok) { next }
         { n = split(users[$1], u, " "); other = 0
           for (i = 1; i <= n; i++) other = other || u[i] != $2
           if (!other) print }' "$t/allow" "$t/uses" "$t/defs"
    rm -rf "$t"
}

# The build's objects whose source is still there (a source removed or moved leaves its object).
objects() {
    find "$B/obj" -name '*.o' | sort | while read -r o; do
        s=${o#"$B"/obj/}
        s=${s%.o}
        for e in c cpp cc; do
            [ -e "$s.$e" ] && { echo "$o"; break; }
        done
    done
}
allowed() { sed -e 's/#.*//' -e 's/[[:space:]]//g' -e '/^$/d' "${ALLOW:-tests/arch/exports.allow}"; }

every_export_has_a_caller() {
    [ -n "$(objects)" ] || { echo "no objects in $B/obj: build first"; return 1; }
    v=$(unused_exports $(objects))
    [ -z "$v" ] || { echo "exported, called from no other file (make it static, or remove it):"; echo "$v"; return 1; }
}

# The list only shrinks: a name allowed that is called from another file now, or gone, is taken out.
every_allowed_name_is_still_needed() {
    none=$(mktemp)
    v=$(ALLOW=$none unused_exports $(objects) | awk '{ print $1 }')
    rm -f "$none"
    for s in $(allowed); do
        echo "$v" | grep -qx "$s" || { echo "$s is called from another file or gone: take it out of exports.allow"; return 1; }
    done
}

# The rule is live: a scratch object exporting a function no one calls is caught, and one that
# another object calls is not.
an_unused_export_is_caught() {
    d=$(mktemp -d)
    mkdir -p "$d/obj/tools"
    printf 'int zz_unused(void) { return 1; }\nint zz_used(void) { return 2; }\n' > "$d/a.c"
    printf 'int zz_used(void);\nint zz_caller(void) { return zz_used(); }\n' > "$d/b.c"
    mkdir -p "$d/obj/tests"
    cc -c "$d/a.c" -o "$d/obj/tools/a.o" && cc -c "$d/b.c" -o "$d/obj/tests/b.o" || return 1
    v=$(B="$d" unused_exports "$d/obj/tools/a.o" "$d/obj/tests/b.o")
    rm -rf "$d"
    [ "$(echo "$v" | awk '{ print $1 }')" = "zz_unused" ]
}

check "every exported function is called from another file" every_export_has_a_caller
check "every name in exports.allow is still needed" every_allowed_name_is_still_needed
check "an unused export is caught" an_unused_export_is_caught
finish
