# fourhosts: four network namespaces (onboard1-3, laptop) on one bridge br0, LCM with ttl=1,
# and helpers to start a marie-am in each and run marie on the laptop. Sourced by the
# manager tests that need several hosts.
. tests/lib.sh
# marie-test-comp, named bare by the system files in tests/data/managers
export PATH="$(pwd)/$B/tests/bin:$PATH"
T=$(mktemp -d /tmp/marie-test-hosts.XXXXXX)
export MARIE_KEY=$T/key MARIE_SEQ_FILE=$T/seq MARIE_TEST_TRACE=$T/trace
export LCM_DEFAULT_URL='udpm://239.255.76.67:7667?ttl=1'
HOSTS="onboard1 onboard2 onboard3 laptop"
HOLDERS=
cleanup() {
    for h in $HOSTS; do p=$(cat "$T/$h.am" 2>/dev/null) && kill "$p" 2>/dev/null; done
    sleep 1
    for p in $HOLDERS; do kill "$p" 2>/dev/null; done
    rm -rf "$T"
}
trap cleanup EXIT

# -- the network: one bridge in this namespace, one namespace per host
ip link add br0 type bridge
ip link set br0 type bridge mcast_snooping 0 2>/dev/null
ip link set br0 up
i=1
for h in $HOSTS; do
    unshare -n sleep 600 &
    pid=$!
    HOLDERS="$HOLDERS $pid"
    echo "$pid" > "$T/$h.ns"
    sleep 0.05
    ip link add "v$i" type veth peer name "p$i"
    ip link set "p$i" netns "$pid"
    ip link set "v$i" master br0
    ip link set "v$i" up
    nsenter -t "$pid" -n --preserve-credentials sh -c "
        ip link set lo up; ip link set p$i name eth0; ip addr add 10.77.0.$i/24 dev eth0
        ip link set eth0 up; ip route add 224.0.0.0/4 dev eth0"
    i=$((i + 1))
done
on() { h=$1; shift; nsenter -t "$(cat "$T/$h.ns")" -n --preserve-credentials "$@"; }
start_am() {
    # nsenter execs marie-am, so $! is the manager itself
    nsenter -t "$(cat "$T/$1.ns")" -n --preserve-credentials \
        "$BIN/marie-am" --host "$1" --state-dir "$T/state-$1" >> "$T/$1.log" 2>&1 &
    echo $! > "$T/$1.am"
}
M() { on laptop "$BIN/marie" "$@"; }
field() {   # field HOST NAME KEY
    M --json ps --window 0.7 2>/dev/null | python3 -c '
import json, sys
d = json.load(sys.stdin)
for h in d["hosts"]:
    if h["host"] == sys.argv[1]:
        for c in h["components"]:
            if c["name"] == sys.argv[2]:
                print(c[sys.argv[3]])' "$1" "$2" "$3"
}
trace_line() { grep -n " $1 $2 " "$T/trace" | head -1 | cut -d: -f1; }

