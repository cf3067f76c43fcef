#!/bin/sh
# test_install: what make install puts in a prefix works from there, away from the source tree:
# a component built with the README's pkg-config line, a user's type made by the installed
# marie-types-gen, the installed Python component, man pages and bash completion for every
# installed program, marie bag (with its libraries, away from the build's venv), and the
# installed marie-demo run from an empty directory (its first status line says what it waits for).
. tests/lib.sh
T=$(mktemp -d /tmp/marie-test-install.XXXXXX)
cleanup() { rm -rf "$T"; }
trap cleanup EXIT
P=$T/prefix
setup "make install PREFIX=$P" sh -c "make --no-print-directory -s install B=$B SAN=${SAN:-0} PREFIX=$P > $T/install.log 2>&1 || { tail -20 $T/install.log; exit 1; }"
export PKG_CONFIG_PATH=$P/lib/pkgconfig
cat > "$T/hello.c" <<'C'
#include "core/component.h"
static const marie_port_spec_t ports[] = {{"out", &marie_type_counter_t, MARIE_OUT, MARIE_PUSH, "HELLO"}, {0}};
static const marie_component_def_t def = {.kind = "hello", .ports = ports};
int main(int argc, char **argv) { return marie_main(&def, argc, argv, NULL); }
C
check "the README's pkg-config line builds a component" sh -c "cd $T && ${CC:-cc} hello.c -o hello \$(pkg-config --cflags --libs marie) && ./hello --describe | grep -q '\"kind\": \"hello\"'"
cp tests/data/types/reading.lcm "$T/"
check "the installed marie-types-gen makes a user's types" sh -c "cd $T && $P/bin/marie-types-gen -o gen reading.lcm --lang c,python > /dev/null && test -f gen/lib/libmarie-types-ux.so"
check "and a component built on them" sh -c "cd $T && ${CC:-cc} -Igen/c \$(pkg-config --cflags marie) $PWD/tests/data/types/ux_probe.c gen/c/lcmtypes/*.c -o probe \$(pkg-config --libs marie) && ./probe --describe | grep -q ux.reading_t"
check "the installed Python component describes itself" sh -c "cd $T && $P/bin/marie-example-producer-py --describe | grep -q '\"kind\": \"example-producer-py\"'"
check "man pages from --help" sh -c "man -l $P/share/man/man1/marie-topic.1 2>/dev/null | grep -q 'marie topic list' || grep -q 'marie topic list' $P/share/man/man1/marie-topic.1"
check "bash completion of marie's commands" bash -c ". $P/share/bash-completion/completions/marie && COMP_WORDS=(marie topi) COMP_CWORD=1 && _marie && [ \"\${COMPREPLY[*]}\" = topic ]"
mkdir "$T/empty"
every_man() {
    n=0; for p in "$P"/bin/*; do
        n=$((n + 1)); b=${p##*/}
        [ -s "$P/share/man/man1/$b.1" ] && [ -s "$P/share/bash-completion/completions/$b" ] || { echo "no man page or completion: $b"; return 1; }
    done
    echo "$n programs, each with its man page and completion"
}
check "every installed program has a man page and a bash completion" every_man
check "marie bag is installed: marie bag --version" sh -c "$P/bin/marie bag --version | grep -q '^marie-bag (marie '"
installed_bag() {
    # a log written with the LCM library installed beside marie bag, then read and exported by it
    PYTHONPATH=$P/lib/marie/bag/site:$P/lib/marie/python python3 - "$T/c.lcm" <<'PY' || return 1
import sys
import lcm
from lcmtypes.marie import estop_t
log = lcm.EventLog(sys.argv[1], "w", overwrite=True)
for i in range(3):
    m = estop_t(); m.utime = i; m.pressed = i == 1; m.source = "test"
    log.write_event(1000 + i, "ESTOP", m.encode())
log.close()
PY
    (cd "$T/empty" && "$P/bin/marie" bag info "$T/c.lcm" && "$P/bin/marie" bag export "$T/c.lcm" "$T/c_bag") > "$T/bag.out" 2>&1
    rc=$?; cat "$T/bag.out"
    [ $rc -eq 0 ] && grep -q '^  ESTOP  *marie.estop_t  *3$' "$T/bag.out" && grep -q '^/estop  *std_msgs/msg/Bool  *3$' "$T/bag.out"
}
check "the installed marie bag reads and exports a log, away from the build tree" installed_bag
demo() {
    (cd "$T/empty" && timeout 120 "$OLDPWD/scripts/netns-run" "$P/bin/marie-demo" --timeout 60 --out demo > "$T/demo.log" 2>&1)
    rc=$?; head -5 "$T/demo.log"; tail -3 "$T/demo.log"
    [ $rc = 0 ] && grep -q 'goals reached' "$T/demo.log" && test -f "$T/empty/demo/summary.json"
}
check "the installed demo runs from an empty directory" demo
check "its first status line says what it waits for (no 'goal 1 of 0', no nan)" sh -c "! grep -q 'goal 1 of 0\|nan m' $T/demo.log"
finish
