#!/bin/sh
# test_params_once: no parameter is copied by hand into a second struct (docs/core.md,
# "Parameters: declared once"): tests/arch/params_copies.py reads every production source, and
# what it finds must be in tests/arch/params_copies.allow, which only shrinks. The rule is live:
# a scratch tree with the copies marie-drives made by hand before is caught, line by line.
. tests/lib.sh
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
SCAN="python3 tests/arch/params_copies.py"

no_new_copies() {
    out=$($SCAN --allow tests/arch/params_copies.allow .)
    rc=$?
    [ -n "$out" ] && echo "$out"
    [ "$rc" -eq 0 ]
}
check "no parameter copied by hand, and no stale entry in params_copies.allow" no_new_copies

# A scratch tree: a library's params file and a component that fills another struct from it.
mkdir -p "$T/hw/drives"
cat > "$T/hw/drives/drives.params.yaml" <<'YAML'
struct: drives_params_t
tables:
  DRIVES_PARAMS:
    left_node: [int, "1", "CANopen node id of the left drive"]
    cmd_timeout: [double, "0.5", "s without a motor command before the wheels stop"]
    ticks_per_rev: [int, "4096", "encoder increments per wheel revolution"]
    allow_unwatched: [bool, "false", "drive a drive that cannot watch us"]
    track_width: [double, "0.5", "m"]
YAML
cat > "$T/hw/drives/drives_main.c" <<'C'
static const drives_params_t *params_of(const marie_component_t *c) { return marie_component_params(c); }
static int on_init(marie_component_t *c)
{
    const drives_params_t *p = params_of(c);
    drives_cfg_t cfg;
    cfg.ticks_per_rev = (int32_t)params_of(c)->ticks_per_rev;
    cfg.cmd_timeout_us = (int64_t)(params_of(c)->cmd_timeout * 1e6);
    cfg.allow_unwatched = p->allow_unwatched;
    lms200_driver_cfg_t l = { .ticks_per_rev = p->ticks_per_rev, .other = 3 };
    double half = params_of(c)->track_width / 2;
    int64_t ln = params_of(c)->left_node;
    cfg.node[0] = (uint8_t)ln;
    marie_goal_t g = { .id = 1,
                       .pose = { 0, 0, 0 }, .cmd_timeout = p->cmd_timeout };
    drives_cfg_t d = { .node = { 1, 2 },
                       .cmd_timeout = p->cmd_timeout };
    return drives_ctl_create(&p->ctl, half) ? 0 : -1;
}
C
mkdir -p "$T/lcmtypes"
printf 'package marie;\nstruct goal_t\n{\n    int32_t id;\n}\n' > "$T/lcmtypes/goal_t.lcm"
$SCAN "$T" > "$T/found"
found() { grep -q "^hw/drives/drives_main.c:$1: $2 copies the parameter $3 by hand$" "$T/found" || { cat "$T/found"; return 1; }; }
check "a field filled from the parameter of its name is caught, with file and line" \
    found 6 "ticks_per_rev = (int32_t)params_of(c)->ticks_per_rev" ticks_per_rev
check "... through a change of unit (s to us)" found 7 "cmd_timeout_us = (int64_t)(params_of(c)->cmd_timeout \* 1e6)" cmd_timeout
check "... from a pointer to the params struct" found 8 "allow_unwatched = p->allow_unwatched" allow_unwatched
check "... in a designated initializer" found 9 "ticks_per_rev = p->ticks_per_rev" ticks_per_rev
check "... in an initializer of several lines" found 16 "cmd_timeout = p->cmd_timeout" cmd_timeout
check "reading a parameter, handing the struct over, or a message carrying it is no copy" \
    test "$(wc -l < "$T/found")" -eq 5
check "the scan fails on a copy" sh -c "! $SCAN '$T' > /dev/null"

echo "hw/drives/drives_main.c: ticks_per_rev = ticks_per_rev" > "$T/allow"
echo "hw/drives/drives_main.c: gone_field = gone_field" >> "$T/allow"
stale() { $SCAN --allow "$T/allow" "$T" | grep -q "hw/drives/drives_main.c: stale allow entry gone_field = gone_field"; }
check "an allow entry whose copy is gone is reported" stale
check "an allowed copy is not reported" sh -c "! $SCAN --allow '$T/allow' '$T' | grep -q ':6: ticks_per_rev'"
finish
