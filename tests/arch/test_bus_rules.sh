#!/bin/sh
# test_bus_rules: one transport under ports (docs/transport.md, docs/architecture.md): outside
# core/, no production file subscribes to the bus but through core/bus/bus.h, so every
# subscription sees the channels a system file moves to shared memory or the fast path.
. tests/lib.sh

production_files() {
    find core map camera ca hw proto managers adapters sim tools -type f \( -name '*.c' -o -name '*.cpp' -o -name '*.h' \) |
        sort
}

# Subscriptions that bypass the bus: liblcm's (lcm_subscribe), lcm-gen's typed ones
# (marie_X_t_subscribe, C++'s lcm::LCM), and the shared-memory reader's own.
direct_subscriptions() {
    production_files | grep -v '^core/' | xargs grep -nE \
        '((^|[^_a-zA-Z0-9])lcm_subscribe|_t_subscribe|marie_shm_sub_create)[[:space:]]*\(|lcm::LCM'
}

no_direct_subscription_outside_core() {
    v=$(direct_subscriptions)
    [ -z "$v" ] || { echo "$v"; return 1; }
}

# The rule is live: a file that breaks it is caught (a scratch copy, never committed).
a_direct_subscription_is_caught() {
    f=tools/map/zz_bus_probe.c
    printf 'static void f(lcm_t *l) { lcm_subscribe(l, "POSE", h, 0); }\nstatic void g(lcm_t *l) { marie_pose2d_t_subscribe(l, "POSE", h2, 0); }\nstatic void k(lcm_t *l) { marie_bus_subscribe(l, "POSE", h, 0); }\n' > "$f"
    v=$(direct_subscriptions | grep zz_bus_probe)
    rm -f "$f"
    [ "$(echo "$v" | grep -c .)" -eq 2 ]
}

check "no direct subscription outside core" no_direct_subscription_outside_core
check "a direct subscription is caught" a_direct_subscription_is_caught
finish
