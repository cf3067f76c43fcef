#!/bin/sh
# test_params_gen: a NAME.params.yaml becomes a struct and spec tables that a component uses
# (core/params_gen.py); a mistake in the file is reported as FILE:LINE and writes nothing.
. tests/lib.sh
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT

cat > "$T/demo.params.yaml" <<'YAML'
struct: demo_params_t
tables:
  DEMO_A_PARAMS:
    rate_hz: [double, "10", "publish rate"]
    label: [string, "'a \"quoted\" label'", "text"]
    map: [string, null, "required: no default"]
  DEMO_B_PARAMS:
    rate_hz: [double, "2", "publish rate"]
    count: [int, "3", ""]
    on: [bool, "true", "enabled"]
    extra: [node, "[]", "any YAML"]
    shared: [string, !c DEMO_SHARED_DEFAULT, "from a C macro"]
YAML
cat > "$T/demo.c" <<'C'
#include <stdio.h>
#include "core/spec.h"
#define DEMO_SHARED_DEFAULT "from-c"
#include "demo_params.h"
static const marie_param_spec_t a[] = DEMO_A_PARAMS;
static const marie_param_spec_t b[] = DEMO_B_PARAMS;
int main(int argc, char **argv)
{
    marie_component_def_t def = { .kind = "demo", .params = argc > 1 ? b : a, .params_size = sizeof(demo_params_t) };
    marie_spec_describe(&def, stdout);
    return 0;
}
C

generates() {
    python3 core/params_gen.py "$T/demo.params.yaml" "$T/demo_params.h" &&
        ${CC:-cc} -std=gnu11 -Wall -Werror -I. -I"$B/gen/c" -I"$T" -D_GNU_SOURCE $(pkg-config --cflags lcm glib-2.0 libfyaml) \
            -o "$T/demo" "$T/demo.c" "$B/lib/libmarie.a" $(pkg-config --libs lcm glib-2.0 libfyaml libsodium) -lm -lpthread
}
check "the generated struct and tables compile against the component runtime" generates

# param TABLE NAME FIELD: one field of a parameter in the program's --describe.
param() {
    "$T/demo" $1 | python3 -c '
import json, sys
d = json.load(sys.stdin)
print([p for p in d["params"] if p["name"] == sys.argv[1]][0][sys.argv[2]])' "$2" "$3"
}
check "table A: rate_hz defaults to 10" test "$(param "" rate_hz default)" = 10
check "table B: rate_hz defaults to 2" test "$(param b rate_hz default)" = 2
check "a default keeps its YAML quoting" test "$(param "" label default)" = "'a \"quoted\" label'"
check "null: a required parameter" test "$(param "" map default)" = None
check "!c: a default from a C macro" test "$(param b shared default)" = from-c
check "types reach --describe" test "$(param b on type) $(param b extra type) $(param b count type)" = "bool node int"

# fails LINE TEXT: the file holding TEXT is refused with FILE:LINE, and no header is written.
fails() {
    line=$1
    printf '%s\n' "$2" > "$T/bad.params.yaml"
    rm -f "$T/bad_params.h"
    out=$(python3 core/params_gen.py "$T/bad.params.yaml" "$T/bad_params.h" 2>&1)
    rc=$?
    echo "$out"
    [ "$rc" -eq 1 ] && [ ! -e "$T/bad_params.h" ] && echo "$out" | grep -q "^$T/bad.params.yaml:$line: "
}
check "an unquoted default" fails 4 "struct: s_t
tables:
  S:
    a: [double, 5, help]"
check "an unknown type" fails 4 "struct: s_t
tables:
  S:
    a: [float, \"5\", help]"
check "one name with two types" fails 6 "struct: s_t
tables:
  S:
    a: [double, \"5\", help]
  T:
    a: [int, \"5\", help]"
check "a name given twice" fails 5 "struct: s_t
tables:
  S:
    a: [double, \"5\", help]
    a: [double, \"6\", help]"
check "a name that is not a C identifier" fails 4 "struct: s_t
tables:
  S:
    a-b: [double, \"5\", help]"
check "an entry that is not [TYPE, DEFAULT, HELP]" fails 4 "struct: s_t
tables:
  S:
    a: [double, \"5\"]"
check "a YAML syntax error" fails 5 "struct: s_t
tables:
  S:
    a: [double, \"5\", help"
check "no tables" fails 1 "struct: s_t"
finish
