#!/bin/sh
# test_liblcm_lazy: a program that marie's own bus serves does not load liblcm (nor glib and
# pcre2 with it), and one whose bus asks for liblcm loads it at that moment and sends through
# it (docs/managers.md, "What one start costs"). The loader's own trace (LD_DEBUG=files) says
# which libraries a run opened; tests/core/test_lcm_python_peer.sh checks, with upstream LCM
# for Python, that what liblcm sends so arrives.
# test-light
. tests/lib.sh
URL="udpm://239.255.76.81:7681?ttl=0"

# loads URL [VAR=VALUE]: lcm_send sends three messages; prints the libraries it opened (those
# the loader mapped: "generating link map"; a look for one in place that finds none is not).
loads() {
    env ${2:+"$2"} LD_DEBUG=files "$B/tests/lcm_send" "$1" LAZY_PROBE 10 70000 10 2>&1 >/dev/null |
        grep -A1 -E 'file=lib' | grep -B1 'generating link map' |
        grep -oE 'file=[^ ]+' | sort -u
    env ${2:+"$2"} "$B/tests/lcm_send" "$1" LAZY_PROBE 10 70000 10 >/dev/null 2>&1 || echo "send failed"
}

own_bus_loads_no_liblcm() {
    v=$(loads "$URL")
    echo "$v"
    ! echo "$v" | grep -qE 'liblcm|libglib|libpcre2|send failed'
}
liblcm_sending_loads_it() {
    v=$(loads "$URL" MARIE_LCM_SEND=liblcm)
    echo "$v"
    echo "$v" | grep -q 'file=liblcm.so' && ! echo "$v" | grep -q 'send failed'
}
liblcm_reading_loads_it() {
    v=$(loads "$URL" MARIE_LCM_RECEIVE=liblcm)
    echo "$v"
    echo "$v" | grep -q 'file=liblcm.so' && ! echo "$v" | grep -q 'send failed'
}
a_url_only_liblcm_reads_loads_it() {
    v=$(loads "memq://")
    echo "$v"
    echo "$v" | grep -q 'file=liblcm.so' && ! echo "$v" | grep -q 'send failed'
}

check own_bus_loads_no_liblcm own_bus_loads_no_liblcm
check liblcm_sending_loads_it liblcm_sending_loads_it
check liblcm_reading_loads_it liblcm_reading_loads_it
check a_url_only_liblcm_reads_loads_it a_url_only_liblcm_reads_loads_it
finish
