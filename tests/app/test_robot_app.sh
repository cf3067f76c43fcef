#!/bin/sh
# test-timeout: 600
# test-group: robot
# The robot application in simulation under the managers: the mission completes with
# localization within bounds and no collision, the robot stops within 0.3 s of the e-stop
# because the software chain acted (the simulator brakes by itself when its e-stop is pressed,
# so the stop alone proves nothing): the e-stop behaviour's zero command and the drives
# reporting e-stop, each within 0.3 s (sim) and after the press,
# SIGKILLed components come back and the mission still completes (every goal with a kill
# every 2 s, the drivers among the victims), and replaying the log into a fresh localizer
# reproduces its poses.
. tests/lib.sh
out=$B/test-app
rm -rf "$out"; mkdir -p "$out"


# 1. Nominal mission, with the e-stop pressed once two goals are reached.
$BIN/marie-demo --quiet --out "$out/nominal" --timeout 240 --estop-after-goal 2 > "$out/nominal.txt" 2>&1
s=$out/nominal/summary.json
cat "$out/nominal.txt"
check "mission completes in sim" test "$(json $s mission_done)" = True
check "every goal reached" test "$(json $s reached)" = "$(json $s goals)"
check "at least 5 goals" le 5 "$(json $s goals)"
check "localization RMS < 0.15 m" le "$(json $s rms)" 0.15
check "localization max < 0.5 m" le "$(json $s max)" 0.5
check "localizer poses compared" le 100 "$(json $s pose_samples)"
check "no collision" test "$(json $s collisions)" = 0
check "e-stop seen and robot stopped after it (latency > 0)" lt 0 "$(json $s estop_stop_s)"
check "robot stops within 0.3 s of the e-stop" le "$(json $s estop_stop_s)" 0.3
check "e-stop chain: zero command from the e-stop behaviour and drives in e-stop, each within 0.3 s" \
    $B/tests/estop_check "$out/nominal/demo.lcm" 0.3
check "summary line printed" grep -q "^demo: [0-9]*/[0-9]* goals reached, localization RMS .* m (max .* m), restarts [0-9]*, [0-9]* s$" "$out/nominal.txt"
goals=$(sed -n '/^profiles:/q; s/.*{name: [^,]*, x: \([-0-9.]*\), y: \([-0-9.]*\),.*/\1,\2/p' config/spartacus.yaml)
tolerance=$(sed -n '/^  mission:/,/^  [a-z]/s/^ *tolerance: \([0-9.]*\)$/\1/p' config/spartacus.yaml | head -1)
check "trajectory PNG: the office map with every goal and the true path through each" \
    python3 tests/app/traj_png_check.py "$out/nominal/trajectories.png" sim/worlds/office.pgm 0.05 "$tolerance" $goals

# 2. Replay the recorded sensor data into a fresh localizer (same seed, following the log's clock).
$BIN/marie-localizer --name replay --clock sim --port pose=POSE_REPLAY --port particles=PARTICLES_REPLAY \
    --param map=sim/worlds/office.yaml --param init_x=2.0 --param init_y=15.0 > "$out/replay-localizer.log" 2>&1 &
loc=$!
sleep 1
dur=$(json $s sim_s)
play=$(python3 -c "print(int(float('$dur') / 4 + 15))")
$B/tests/replay_check "$out/nominal/demo.lcm" "$play" > "$out/replay.txt" 2>&1 &
chk=$!
sleep 0.5
lcm-logplayer -s 4 -e '^(ODOMETRY|LASER|MARIE_CLOCK)$' "$out/nominal/demo.lcm" > /dev/null 2>&1
wait $chk; rc=$?
kill $loc 2>/dev/null; wait $loc 2>/dev/null
cat "$out/replay.txt"
check "replayed log reproduces the localizer's poses" test $rc = 0

# 3. Chaos: a random non-simulator component is SIGKILLed every 2 s, the laser driver first (the
# nominal run takes 20-25 s here: about ten kills). The laser driver dies mid-stream while the
# virtual LMS200 streams on at 500 kbaud; its successor must find it and publish again.
$BIN/marie-demo --quiet --out "$out/chaos" --timeout 300 --chaos 2 --chaos-first laser > "$out/chaos.txt" 2>&1
c=$out/chaos/summary.json
cat "$out/chaos.txt"
check "chaos: components were killed" le 2 "$(json $c kills)"
check "chaos: the laser driver was among the victims" grep -q "SIGKILL laser" "$out/chaos.txt"
check "chaos: the mission still completes" test "$(json $c mission_done)" = True
check "chaos: every goal reached" test "$(json $c reached)" = "$(json $c goals)"
check "chaos: at least 5 goals" le 5 "$(json $c goals)"
check "chaos: the summary counts the restarts" le "$(json $c kills)" "$(json $c restarts)"
check "chaos: the run says its seed, and the summary keeps it" \
    grep -q "seed $(json $c seed) (--seed $(json $c seed) draws" "$out/chaos.txt"
finish
