#!/bin/sh
# test-light
# test_malformed_inputs: every component binary, fed every kind of malformed payload on every input
# port it declares (pushed, and as pull replies; behaviours in both input modes; the CAs on their
# channels), stays alive, does not act on it, and counts each payload once in its heartbeat.
# Ports are read from each binary's --help, so a new component with inputs must be given a line
# in recipe() below or this test fails. tests/core/malformed_peer.c sends, serves and checks.
. tests/lib.sh
OUT=$B/test-logs/malformed_inputs
rm -rf "$OUT" && mkdir -p "$OUT"
PEER=$B/tests/malformed_peer
SPEC=$OUT/spec
: > "$SPEC"
trap 'stop_started' EXIT

# recipe BINARY: "INSTANCE|ARGS[|subscribe][|UNUSED...]" lines, one per run of that binary; no
# line: no inputs to test. "subscribe": the instance subscribes to its pull ports' channels
# instead. UNUSED: input ports this instance's mode does not listen to (another line's does).
recipe() {
    case $1 in
    marie-behaviours)
        echo "beh_pull|--param input_mode=pull --param rate_hz=5 --param pull_timeout_ms=150"
        echo "beh_sub|--param input_mode=subscribe --param rate_hz=10|subscribe" ;;
    marie-drives) echo "drives|--param can=emu:$OUT/can" ;;
    marie-gyro) echo "gyro|--param can=emu:$OUT/can" ;;
    marie-example-consumer) echo "consumer|" ;;
    marie-localizer) echo "localizer|--param map=sim/worlds/office.yaml --param init_x=2 --param init_y=15" ;;
    marie-mapper) echo "mapper|" ;;
    marie-explore) echo "explore|" ;;
    marie-mission) echo "mission|--param sharedmap=false --param 'goals=[{name: a, x: 2, y: 15}]'" ;;
    marie-odometry) echo "odometry|" ;;
    marie-planner) echo "planner|--param map=sim/worlds/office.yaml" ;;
    marie-sim) echo "sim|--param world=office" ;;
    marie-viewer-server) echo "viewer|--param http_port=0" ;;
    marie-face) echo "face|--param http_port=0" ;;
    marie-vision) echo "vision|" ;;
    marie-ssl) echo "ssl|" ;;
    marie-asr)
        echo "asr|--param input=separated||array"
        echo "asr_array|--param input=array||separated" ;;
    marie-tts) echo "tts|" ;;
    marie-dialogue) echo "dialogue|" ;;
    marie-ros2) echo "ros2|--system tests/ros2/malformed_inputs.yaml" ;;
    marie-audio) echo "audio|--param 'device=\"\"' --param playback=null" ;;   # no capture: the null PCM has no clock
    *) return 1 ;;
    esac
}

# What an output may do while only malformed input arrives: finite (well formed, no NaN),
# zero (and nothing moves), silent (nothing at all).
out_mode() {
    case $1:$2 in
    *:marie.motor_command_t|drives:*|sim:encoders) echo zero ;;
    planner:path|vision:*|viewer:*|face:*) echo silent ;;
    *) echo finite ;;
    esac
}

# The viewer's ports carry raw payloads; these are the types it shows on them.
raw_type() {
    case $1 in
    map) echo marie.occupancy_grid_t ;; pose|truth) echo marie.pose_cov_t ;;
    particles) echo marie.particle_cloud_t ;; laser) echo marie.laser_scan_t ;;
    path) echo marie.path_t ;; goal) echo marie.goal_t ;; arbitration) echo marie.arbitration_t ;;
    event) echo marie.event_t ;; heartbeat) echo marie.heartbeat_t ;; am_status) echo marie.am_status_t ;;
    am_reply) echo marie.am_reply_t ;; tags) echo marie.tag_detections_t ;;
    landmarks) echo marie.landmarks_t ;; map_update) echo marie.occupancy_grid_update_t ;; *) return 1 ;;
    esac
}

names=""; missing=""; skipped=""
# Every port of every component binary gets a channel of its own, so each payload reaches one port.
for bin in "$BIN"/marie-*; do
    prog=$(basename "$bin")
    ports=$(timeout 10 "$bin" --help 2>/dev/null | sed -n '/^ports:/,/^params:/p' | awk '$2 == "in" || $2 == "out" { print $1, $2, $3, $4 }')
    if ! echo "$ports" | grep -q ' in '; then
        skipped="$skipped $prog"
        continue
    fi
    if ! recipe "$prog" > /dev/null; then
        missing="$missing $prog"
        continue
    fi
    recipe "$prog" | while IFS='|' read -r inst args how unused; do
        remap=""
        echo "$ports" | while read -r port dir mech type; do
            ch="$(echo "${inst}_$port" | tr a-z A-Z)"
            [ "$type" = raw ] && type=$(raw_type "$port")
            if [ "$dir" = in ] && echo " $unused " | grep -q " $port "; then
                :
            elif [ "$dir" = in ]; then
                mode=push; [ "$mech" = pull ] && [ "$how" != subscribe ] && mode=pull
                echo "in $inst $type $ch $mode" >> "$SPEC"
            else
                echo "out $inst $type $ch $(out_mode "$inst" "$port")" >> "$SPEC"
            fi
            printf ' --port %s=%s' "$port" "$ch"
        done > "$OUT/$inst.ports"
        echo "$inst|$prog --name $inst $args $(cat "$OUT/$inst.ports")" >> "$OUT/runs"
    done
done

# The Communication Adapters declare no ports: their channels are parameters. Every
# component also takes lifecycle orders.
cat >> "$SPEC" <<EOF
in * marie.lifecycle_command_t MARIE_LIFECYCLE push
in mailbox marie.laser_scan_t MB_IN push
in mailbox marie.pull_request_t MB_IN.PULL push
empty mailbox MB_IN
in splitter marie.pose_cov_t SP_IN push
out splitter marie.pose_cov_t SP_OUT silent
in switch marie.motor_command_t SW_A push
in switch marie.motor_command_t SW_B push
in switch marie.switch_select_t SW_OUT.SELECT push
out switch marie.motor_command_t SW_OUT silent
in sharedmap marie.sharedmap_request_t SM push
EOF
cat >> "$OUT/runs" <<EOF
mailbox|marie-ca mailbox --name mailbox --param channel=MB_IN --param type=marie.laser_scan_t
splitter|marie-ca splitter --name splitter --param input=SP_IN --param type=marie.pose_cov_t --param outputs=[SP_OUT]
switch|marie-ca switch --name switch --param type=marie.motor_command_t --param output=SW_OUT --param 'inputs={a: SW_A, b: SW_B}' --param state_file=$OUT/switch.state
sharedmap|marie-ca sharedmap --name sharedmap --param channel=SM --param state_file=$OUT/sharedmap.log
EOF

recipes_cover_every_component() {
    echo "without inputs on the bus (not fed):$skipped"
    [ -z "$missing" ] || { echo "component binaries with inputs but no recipe:$missing"; return 1; }
}
check "every component binary with input ports has a recipe" recipes_cover_every_component

# The drives and gyro need their CANopen devices: the emulated bus and virtual devices.
start canbus "$BIN/marie-canbus" "$OUT/can"
wait_for 10 test -S "$OUT/can"
start vcan "$BIN/marie-vcan-devices" --can "emu:$OUT/can"

# The peer listens first, so it serves the pulls made at start too.
start peer "$PEER" "$SPEC" 70
sleep 0.5
while IFS='|' read -r inst cmd; do
    eval "start $inst $BIN/$cmd"
    names="$names $inst"
done < "$OUT/runs"

wait "$pid_peer"; peer_rc=$?
cat "$OUT/peer.log"

every_component_counted_and_kept_still() { [ "$peer_rc" -eq 0 ]; }
check "every component counts each malformed payload once and does not act on it" every_component_counted_and_kept_still

all_alive() {
    rc=0
    for n in $names; do
        eval "p=\$pid_$n"
        kill -0 "$p" 2>/dev/null || { echo "$n died:"; tail -5 "$OUT/$n.log"; rc=1; }
    done
    return $rc
}
check "every component is still alive" all_alive

# A clean quit proves nothing was corrupted on the way (sanitizer builds report leaks here).
quits_cleanly() {
    rc=0
    for n in $names; do
        eval "p=\$pid_$n"
        kill -TERM "$p" 2>/dev/null
    done
    for n in $names; do
        eval "p=\$pid_$n"
        wait "$p"; st=$?
        [ "$st" -eq 0 ] || { echo "$n exited with status $st:"; tail -5 "$OUT/$n.log"; rc=1; }
    done
    return $rc
}
check "every component quits cleanly afterwards" quits_cleanly
finish
