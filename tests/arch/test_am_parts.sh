#!/bin/sh
# test_am_parts: marie-am's state is split by concern (docs/managers.md, "How marie-am is built"):
# each part of struct am names its one owner file in managers/am.h, and no other file touches it
# (they call the owner's functions). env is read by all and written by am.c alone.
. tests/lib.sh

# "PART FILE" for every member of struct am whose comment names its owner: "am_x.c".
parts() {
    awk '/^struct am \{/ { on = 1; next } on && /^\};/ { on = 0 } on' managers/am.h |
        sed -n 's/^ *[a-z_ ]*[ *]\([a-z_]*\);.*\/\* *\(am[a-z_]*\.c\).*/\1 \2/p'
}

# The same for a component (struct comp): the parts one file owns, as c->PART (a component is
# c, d, to or from in these files).
comp_parts() {
    awk '/^struct comp \{/ { on = 1; next } on && /^\};/ { on = 0 } on' managers/am.h |
        sed -n 's/^ *[}a-z_0-9 ]*[ *]\([a-z_]*\);.*\/\* *\(am[a-z_]*\.c\).*/\1 \2/p'
}

# Prints "file:line: touches am->PART (FILE's)" for every use of a part outside its owner, and
# "file:line: writes am->env" for a write of env outside am.c.
violations() {
    p=$(parts | tr '\n' ' ')
    cp=$(comp_parts | tr '\n' ' ')
    for f in managers/am*.c; do
        awk -v parts="$p" -v cparts="$cp" -v me="${f#managers/}" '
            BEGIN {
                n = split(parts, a, " "); for (i = 1; i < n; i += 2) owner[a[i]] = a[i + 1]
                n = split(cparts, a, " "); for (i = 1; i < n; i += 2) cowner[a[i]] = a[i + 1]
            }
            {
                line = $0
                while (match(line, /am->[a-z_]+/)) {
                    part = substr(line, RSTART + 4, RLENGTH - 4)
                    if (part in owner && owner[part] != me && part != "env")
                        print FILENAME ":" FNR ": touches am->" part " (" owner[part] "'"'"'s)"
                    line = substr(line, RSTART + RLENGTH)
                }
                line = $0
                while (match(line, /[a-z_]+->[a-z_]+/)) {
                    part = substr(line, RSTART, RLENGTH); sub(/.*->/, "", part)
                    base = substr(line, RSTART, RLENGTH); sub(/->.*/, "", base)
                    if (base ~ /^(c|d|to|from)$/ && part in cowner && cowner[part] != me)
                        print FILENAME ":" FNR ": touches a component'"'"'s " part " (" cowner[part] "'"'"'s)"
                    line = substr(line, RSTART + RLENGTH)
                }
                if (me != "am.c" && $0 ~ /am->env\.[a-z_.\[\]]+ *([-+*\/]?=[^=]|\+\+|--)/)
                    print FILENAME ":" FNR ": writes am->env"
            }' "$f"
    done
}

every_part_has_an_owner() {
    n=$(parts | wc -l)
    members=$(awk '/^struct am \{/ { on = 1; next } on && /^\};/ { on = 0 } on && /;/' managers/am.h | wc -l)
    echo "$n of $members parts of struct am name their owner; a component's: $(comp_parts | tr '\n' ' ')"
    [ "$n" -ge 8 ] && [ "$n" -eq "$members" ] && [ "$(comp_parts | wc -l)" -ge 4 ]
}

each_part_is_touched_by_its_owner_only() {
    v=$(violations)
    [ -z "$v" ] || { echo "$v"; return 1; }
}

# The rule is live: a file that reaches into another's part, or writes env, is caught (a
# scratch file, never committed).
a_trespass_is_caught() {
    f=managers/am_zz_probe.c
    printf 'static void f(am_t *am, comp_t *d) { am->system.up = 1; am->env.status_hz = 3; (void)am->orders.refused; d->out.seq = 0; }\n' > "$f"
    v=$(violations | grep am_zz_probe)
    rm -f "$f"
    echo "$v"
    [ "$(echo "$v" | grep -c .)" -eq 4 ]
}

check "every part of struct am names its owner" every_part_has_an_owner
check "each part is touched by its owner only" each_part_is_touched_by_its_owner_only
check "a trespass is caught" a_trespass_is_caught
finish
