#!/bin/sh
# test_python_component: Python components (python/marie) under marie-am, checked from upstream
# LCM for Python: described and checked before start, restarted after kill -9, paused and
# resumed, a forged order refused, malformed input counted, the simulator's clock followed, a
# pull answered by a Mailbox, messages crossing to and from a C component.
. tests/lib.sh
T=$(mktemp -d /tmp/marie-test-py.XXXXXX)
export MARIE_KEY=$T/key MARIE_SEQ_FILE=$T/seq
M="$BIN/marie"
AM_PID=
cleanup() { [ -n "$AM_PID" ] && kill "$AM_PID" 2>/dev/null; sleep 0.5; rm -rf "$T"; }
trap cleanup EXIT
py=$(scripts/peer-venv.sh) || { echo "LCM for Python is not installed (scripts/peer-venv.sh); failing"; exit 1; }
peer() { PYTHONPATH=$B/python "$py" tests/python/lcm_peer.py "$@"; }
# hbv NAME EXPR: a Python expression over NAME's last heartbeat h (counters in h["counters"])
hbv() { peer hb "$1" 3 | python3 -c "import json,sys; h=json.load(sys.stdin); c=h['counters']; print($2)"; }
field() { ps_field "$1" "$2"; }
is_state() { [ "$(field "$1" state)" = "$2" ]; }
pid_changed() { p=$(field "$1" pid); [ -n "$p" ] && [ "$p" != 0 ] && [ "$p" != "$2" ] && is_state "$1" running; }

"$M" keygen "$T/key"
"$BIN/marie-am" --host alpha --state-dir "$T/am" > "$T/am.log" 2>&1 & AM_PID=$!
sleep 0.3

# a Python component's entry is checked against its --describe like a C component's
sed 's/rate_hz: ${rate}, label/rate_hz: 20, lable/' tests/data/python/system.yaml > "$T/bad.yaml"
bad_entry() { out=$("$M" up "$T/bad.yaml" 2>&1); echo "$out"; echo "$out" | grep -q "bad.yaml:[0-9]*:[0-9]*: unknown parameter 'lable'"; }
check "a Python component's unknown parameter is refused before start" bad_entry
# a bare Python script (no launcher) is described too: it imports marie
cat > "$T/bare.yaml" <<EOF2
system: bare
hosts: [alpha]
components:
  bare:
    exec: $PWD/adapters/example/py/producer.py
    host: alpha
    env: {PYTHONPATH: $PWD/python:$PWD/$B/python, MARIE_RESOLVE: $PWD/$BIN/marie-resolve}
    params: {rate: 3}
EOF2
bare_entry() { out=$("$M" up "$T/bare.yaml" 2>&1); echo "$out"; echo "$out" | grep -q "bare.yaml:[0-9]*:[0-9]*: unknown parameter 'rate'"; }
check "a bare Python script's entry is checked against its --describe" bare_entry
unused_arg() { out=$("$M" up tests/data/python/system.yaml -a rate=20 -a nosuch=1 2>&1); [ $? = 2 ] && echo "$out" | grep -q "launch argument 'nosuch' is not used"; }
check "up -a: an argument the file does not use is refused" unused_arg
# (the manager describes the five programs first: seconds under load)
check "up -a rate=20 starts the Python components" "$M" --timeout 20 up tests/data/python/system.yaml -a rate=20
check "the launch argument reached the component" sh -c "$M param get producer rate_hz | grep -qx '20\(\.0\)\?'"
check "the default of an argument not given too" sh -c "$M param get producer label | grep -qx from-python"
check "producer running" wait_for 10 is_state producer running
check "consumer running" wait_for 10 is_state consumer running
sleep 1.5
c_hears() { n=$(hbv cconsumer 'c.get("received", 0)'); echo "received $n"; [ "$n" -gt 10 ]; }
check "the C consumer receives the Python producer's counters" c_hears
py_hears() { n=$(hbv consumer 'c.get("received", 0) if c.get("gaps", 0) == 0 else -1'); echo "received $n"; [ "$n" -gt 10 ]; }
check "the Python consumer receives them, without gaps" py_hears
pulled() { n=$(hbv consumer 'c.get("pulled", 0)'); echo "pulled $n"; [ "$n" -ge 1 ]; }
check "a pull port is answered by the Mailbox" wait_for 5 pulled

# kill -9: marie-am restarts it
P=$(field producer pid)
kill -9 "$P"
check "kill -9 restarts the Python component" wait_for 20 pid_changed producer "$P"

(timeout 4 "$M" logs -f -n 0 producer > "$T/follow.out" 2>&1 &)
sleep 1.5

# pause / resume: the producer stops publishing while paused
check "pause" "$M" pause producer
check "paused" wait_for 5 is_state producer paused
quiet() { n=$(peer count EXAMPLE 1); echo "$n while paused"; [ "$n" -eq 0 ]; }
check "nothing published while paused" quiet
check "resume" "$M" resume producer
check "running again" wait_for 5 is_state producer running
sleep 2
follow_tagged() {
    cat "$T/follow.out"
    grep -q 'Z info example-producer-py: producer: pause from' "$T/follow.out" && ! grep -q ' err [0-9][0-9]:[0-9][0-9]:' "$T/follow.out"
}
check "logs -f tags a component's info line info, with one time stamp" follow_tagged
talks() { n=$(peer count EXAMPLE 1); echo "$n after resume"; [ "$n" -gt 5 ]; }
check "publishing again after resume" talks

# a forged order (a MAC made with another key) is refused and counted; the component runs on
peer forge producer 8
forged() { is_state producer running && [ "$(hbv producer 'c.get("refused_orders", 0)')" -ge 1 ]; }
check "a forged quit is refused and counted" wait_for 5 forged

# malformed input: each of three bad payloads counted once, under its reason
peer malformed EXAMPLE
bad_counted() {
    v=$(hbv consumer 'c.get("bad_fingerprint", 0), c.get("bad_payload", 0)'); echo "$v"
    [ "$v" = "1 2" ]
}
check "malformed input counted (bad_fingerprint 1, bad_payload 2)" wait_for 5 bad_counted
check "the consumer runs on" is_state consumer running

# marie logs: several components, a group, a component's own log lines tagged by their level
logs_group() { out=$("$M" logs -n 50 py 2>&1); echo "$out" | tail -4; echo "$out" | grep -q '^producer: ' && echo "$out" | grep -q '^consumer: '; }
check "logs -n of a group prints each member's lines, named" logs_group
logs_two() { out=$("$M" logs -n 50 producer consumer 2>&1); echo "$out" | grep -q '^producer: ' && echo "$out" | grep -q '^consumer: '; }
check "logs -n of two components" logs_two
logs_nokey() { out=$(MARIE_KEY=$T/nosuchkey "$M" logs -n 3 producer 2>&1); rc=$?; echo "$out"; [ $rc = 4 ] && echo "$out" | grep -q 'signed with the key'; }
check "logs -n without a key says why (exit 4)" logs_nokey



# the simulator's clock: 2 s of sim time in 0.1 s steps give 20 ticks at 10 Hz; none without it
peer count SIMCOUNT 4 > "$T/simcount" &
CP=$!
sleep 0.3
peer clock 100 0.1 21 20
wait $CP
sim_ticks() { n=$(cat "$T/simcount"); echo "$n ticks for 2 s of sim time"; [ "$n" -ge 19 ] && [ "$n" -le 21 ]; }
check "a Python component follows the simulator's clock" sim_ticks
still() { n=$(peer count SIMCOUNT 1); echo "$n without the clock"; [ "$n" -eq 0 ]; }
check "and stops with it" still

check "down" "$M" down
finish
