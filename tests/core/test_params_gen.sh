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

# Linked against the tree's libmarie: with its sanitizers when make built it with them.
SANFLAGS=""
[ "${SAN:-0}" = 1 ] && SANFLAGS="-fsanitize=address,undefined"
generates() {
    python3 core/params_gen.py "$T/demo.params.yaml" "$T/demo_params.h" &&
        ${CC:-cc} -std=gnu11 -Wall -Werror $SANFLAGS -I. -I"$B/gen/c" -I"$T" -D_GNU_SOURCE $(pkg-config --cflags lcm glib-2.0 libfyaml) \
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

# A library's parameters in a file of their own, with its defaults as an initializer; a
# component that takes them as a member, one default of its own.
mkdir -p "$T/lib"
cat > "$T/lib/filt.params.yaml" <<'YAML'
struct: filt_params_t
defaults: FILT_PARAMS_DEFAULTS
tables:
  FILT_PARAMS:
    gain: [double, "0.05", "per step"]
    count: [int, "40", ""]
    on: [bool, "true", ""]
    name: [string, "'text'", ""]
YAML
cat > "$T/comp.params.yaml" <<YAML
struct: comp_params_t
members:
  filt: {file: $T/lib/filt.params.yaml, defaults: {count: "7"}}
tables:
  COMP_PARAMS:
    rate_hz: [double, "10", ""]
YAML
cat > "$T/comp.c" <<'C'
#include <stdio.h>
#include "core/component.h"
#include "comp_params.h"
static const marie_param_spec_t params[] = COMP_PARAMS;
static const marie_component_def_t def = { .kind = "comp", .params = params, .params_size = sizeof(comp_params_t) };
int main(int argc, char **argv)
{
    const filt_params_t d = FILT_PARAMS_DEFAULTS;
    printf("defaults %g %ld %d %s\n", d.gain, (long)d.count, d.on, d.name);
    marie_errors_t errs = { 0 };
    marie_component_t *c = marie_component_create(&def, argc, argv, NULL, &errs);
    if (!c) {
        marie_errors_print(&errs, stderr);
        return 1;
    }
    const comp_params_t *q = marie_component_params(c);
    printf("values %g %g %ld %d %s\n", q->rate_hz, q->filt.gain, (long)q->filt.count, q->filt.on, q->filt.name);
    marie_component_destroy(c);
    return 0;
}
C
members_build() {
    python3 core/params_gen.py "$T/lib/filt.params.yaml" "$T/lib/filt_params.h" &&
        python3 core/params_gen.py "$T/comp.params.yaml" "$T/comp_params.h" &&
        grep -q "lib/filt.params.yaml" "$T/comp_params.d" &&
        ${CC:-cc} -std=gnu11 -Wall -Werror $SANFLAGS -I. -I"$B/gen/c" -I"$T" -D_GNU_SOURCE \
            $(pkg-config --cflags lcm glib-2.0 libfyaml) -o "$T/comp" "$T/comp.c" "$B/lib/libmarie.a" \
            $(pkg-config --libs lcm glib-2.0 libfyaml libsodium) -lm -lpthread
}
check "a member's header compiles; make learns the member's file (comp_params.d)" members_build
check "defaults: the library's initializer holds its table's defaults" \
    test "$("$T/comp" | sed -n 1p)" = "defaults 0.05 40 1 text"
check "a member's parameters land in the member, with the component's own default" \
    test "$("$T/comp" | sed -n 2p)" = "values 10 0.05 7 1 text"
check "a member's parameter is set by its own name" \
    test "$("$T/comp" --param gain=2.5 --param name=x | sed -n 2p)" = "values 10 2.5 7 1 x"
check "a member's parameters are in --describe" test "$("$T/comp" --describe | grep -c '"name": "gain"')" = 1

check "a member file that does not exist" fails 3 "struct: s_t
members:
  m: no/such.params.yaml
tables:
  S: {}"
check "a member default for a parameter it does not have" fails 3 "struct: s_t
members:
  m: {file: $T/lib/filt.params.yaml, defaults: {nosuch: \"1\"}}
tables:
  S: {}"
check "a parameter that a member has too" fails 6 "struct: s_t
members:
  m: $T/lib/filt.params.yaml
tables:
  S:
    gain: [double, \"1\", help]"
check "defaults: with two tables" fails 2 "struct: s_t
defaults: D
tables:
  S: {}
  T: {}"
check "defaults: a value that is no plain literal" fails 5 "struct: s_t
defaults: D
tables:
  S:
    n: [node, \"[]\", help]"

# A member's file with a member of its own (a library that takes a lower layer's parameters):
# the lower layer's struct inside the member, its parameters under their own names in the
# component's table, its defaults in both initializers, a default given from the top.
cat > "$T/lib/stage.params.yaml" <<YAML
struct: stage_params_t
defaults: STAGE_PARAMS_DEFAULTS
members:
  filt: $T/lib/filt.params.yaml
tables:
  STAGE_PARAMS:
    depth: [int, "3", ""]
YAML
cat > "$T/comp2.params.yaml" <<YAML
struct: comp2_params_t
members:
  stage: {file: $T/lib/stage.params.yaml, defaults: {count: "9"}}
tables:
  COMP2_PARAMS:
    rate_hz: [double, "10", ""]
YAML
cat > "$T/comp2.c" <<'C'
#include <stdio.h>
#include "core/component.h"
#include "comp2_params.h"
static const marie_param_spec_t params[] = COMP2_PARAMS;
static const marie_component_def_t def = { .kind = "comp2", .params = params, .params_size = sizeof(comp2_params_t) };
int main(int argc, char **argv)
{
    const stage_params_t d = STAGE_PARAMS_DEFAULTS;
    printf("defaults %ld %g %ld\n", (long)d.depth, d.filt.gain, (long)d.filt.count);
    marie_errors_t errs = { 0 };
    marie_component_t *c = marie_component_create(&def, argc, argv, NULL, &errs);
    if (!c) {
        marie_errors_print(&errs, stderr);
        return 1;
    }
    const comp2_params_t *q = marie_component_params(c);
    printf("values %g %ld %g %ld\n", q->rate_hz, (long)q->stage.depth, q->stage.filt.gain, (long)q->stage.filt.count);
    marie_component_destroy(c);
    return 0;
}
C
nested_build() {
    python3 core/params_gen.py "$T/lib/stage.params.yaml" "$T/lib/stage_params.h" &&
        python3 core/params_gen.py "$T/comp2.params.yaml" "$T/comp2_params.h" &&
        grep -q "lib/stage.params.yaml .*lib/filt.params.yaml" "$T/comp2_params.d" &&
        ${CC:-cc} -std=gnu11 -Wall -Wextra -Werror $SANFLAGS -I. -I"$B/gen/c" -I"$T" -D_GNU_SOURCE \
            $(pkg-config --cflags lcm glib-2.0 libfyaml) -o "$T/comp2" "$T/comp2.c" "$B/lib/libmarie.a" \
            $(pkg-config --libs lcm glib-2.0 libfyaml libsodium) -lm -lpthread
}
check "a member's member compiles; make learns both files (comp2_params.d)" nested_build
check "... the library's initializer holds its member's defaults" \
    test "$("$T/comp2" | sed -n 1p)" = "defaults 3 0.05 40"
check "... its parameters land in the member's member, with the component's default" \
    test "$("$T/comp2" | sed -n 2p)" = "values 10 3 0.05 9"
check "... and are set by their own names" \
    test "$("$T/comp2" --param gain=2.5 --param count=1 | sed -n 2p)" = "values 10 3 2.5 1"
check "a parameter that a member's member has too" fails 6 "struct: s_t
members:
  m: $T/lib/stage.params.yaml
tables:
  S:
    gain: [double, \"1\", help]"
check "a file that takes itself as a member" fails 3 "struct: s_t
members:
  m: $T/bad.params.yaml
tables:
  S: {}"
# A program that is not a component: its options from a file with cli:, a member taken with a
# prefix, fields that are no parameter, and defaults: over the members.
cat > "$T/lib/dev.params.yaml" <<'YAML'
struct: dev_cfg_t
defaults: DEV_DEFAULTS
fields:
  node: [uint8_t, "set by the code"]
tables:
  DEV_PARAMS:
    bias: [double, "0.01", "rad/s", {range: [-1, 1], metavar: R}]
    seed: [int, "1", "noise seed", {range: [1, 100]}]
YAML
cat > "$T/emu.params.yaml" <<YAML
struct: emu_cfg_t
defaults: EMU_DEFAULTS
cli: EMU_CLI
members:
  dev: {file: $T/lib/dev.params.yaml, prefix: gyro_, defaults: {seed: "7"}}
fields:
  external: bool
tables:
  EMU_PARAMS:
    can: [string, null, "the bus", {metavar: URL}]
    rate_hz: [double, "10", "scans per second", {option: rate, range: [0.01, 1000]}]
    units: [string, "mm", "units", {choices: [mm, cm]}]
    quiet: [bool, "false", "say nothing"]
    hidden: [int, "3", "not an option", {option: no}]
YAML
cat > "$T/emu.c" <<'C'
#include <stdio.h>
#include <unistd.h>
#include "emu_params.h"
int main(int argc, char **argv)
{
    emu_cfg_t cfg = EMU_DEFAULTS;
    const marie_cli_opt_t opts[] = { EMU_CLI(&cfg) { NULL } };
    int rc = marie_cli_parse("emu", opts, argc, argv);
    if (rc >= 0)
        return rc;
    printf("%s %g %s %d %lld %g %lld %d %d\n", cfg.can ? cfg.can : "-", cfg.rate_hz, cfg.units, cfg.quiet,
           (long long)cfg.hidden, cfg.dev.bias, (long long)cfg.dev.seed, cfg.dev.node, cfg.external);
    return 0;
}
C
cli_build() {
    python3 core/params_gen.py "$T/lib/dev.params.yaml" "$T/lib/dev_params.h" &&
        python3 core/params_gen.py "$T/emu.params.yaml" "$T/emu_params.h" &&
        ${CC:-cc} -std=gnu11 -Wall -Werror $SANFLAGS -I. -I"$B/gen/c" -I"$T" -D_GNU_SOURCE \
            $(pkg-config --cflags lcm glib-2.0 libfyaml) -o "$T/emu" "$T/emu.c" "$B/lib/libmarie.a" \
            $(pkg-config --libs lcm glib-2.0 libfyaml libsodium) -lm -lpthread
}
check "cli: a program's options compile from the file, with a member's and its fields" cli_build
check "cli: the defaults, a member's with the file's own override, fields zero" \
    test "$("$T/emu")" = "- 10 mm 0 3 0.01 7 0 0"
check "cli: options by their names (rate for rate_hz, gyro-bias for the prefixed member's bias, a flag)" \
    test "$("$T/emu" --can emu:/x --rate 20 --units cm --quiet --gyro-bias=-0.5 --gyro-seed 9)" = "emu:/x 20 cm 1 3 -0.5 9 0 0"
check "cli: out of range, not a choice, and option: no are refused with status 2" \
    sh -c "! '$T/emu' --rate 0 2>/dev/null && ! '$T/emu' --units km 2>/dev/null && ! '$T/emu' --hidden 4 2>/dev/null &&
           '$T/emu' --rate 0 2>/dev/null; [ \$? -eq 2 ]"
usage_has() { "$T/emu" --help | grep -q -- "$1"; }
check "cli: the usage says the value's name, the help, the default and the choices" \
    usage_has "--rate  *X    scans per second (default 10)"
check "... choices" usage_has "--units  *TEXT units (default mm) \[mm|cm\]"
check "... a prefixed member's option" usage_has "--gyro-bias  *R    rad/s (default 0.01)"

check "an option without its range" fails 5 "struct: s_t
cli: S_CLI
tables:
  S:
    a: [double, \"5\", help]"
check "a flag that defaults to true" fails 5 "struct: s_t
cli: S_CLI
tables:
  S:
    a: [bool, \"true\", help]"
check "an unknown option key" fails 4 "struct: s_t
tables:
  S:
    a: [double, \"5\", help, {ragne: [0, 1]}]"
check "choices on a number" fails 4 "struct: s_t
tables:
  S:
    a: [double, \"5\", help, {choices: [a, b]}]"
check "two options of one name" fails 6 "struct: s_t
cli: S_CLI
tables:
  S:
    a_b: [int, \"5\", help, {range: [0, 9]}]
    c: [int, \"5\", help, {range: [0, 9], option: a-b}]"
check "a field named like a parameter" fails 3 "struct: s_t
fields:
  a: int
tables:
  S:
    a: [int, \"5\", help]"
check "a prefixed member parameter named like a parameter" fails 6 "struct: s_t
members:
  m: {file: $T/lib/dev.params.yaml, prefix: x_}
tables:
  S:
    x_bias: [int, \"5\", help]"
dynamic_ok() {
    printf 'struct: s_t\ntables:\n  S:\n    a: [double, "5", help, dynamic]\n' > "$T/dyn.params.yaml"
    python3 core/params_gen.py "$T/dyn.params.yaml" "$T/dyn_params.h" && grep -q "MARIE_PARAM_AT(s_t, a, DOUBLE" "$T/dyn_params.h"
}
check "dynamic: a fourth item marie param set reads" dynamic_ok
check "a fourth item that is neither dynamic nor options" fails 4 "struct: s_t
tables:
  S:
    a: [double, \"5\", help, static]"
finish
