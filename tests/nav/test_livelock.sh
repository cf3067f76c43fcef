#!/bin/sh
# Livelock: the planner's map lacks two pillars that stand across its straight path, 0.3 m
# apart, and the planner ignores the laser (use_scan false). Without the progress watch
# (stuck_s 0) the avoid and follow behaviours fight in front of the pillars and the goal is
# never reached; with it the behaviours notice no progress, ask for a new plan, back off,
# rotate and detour, and the robot reaches the goal beyond the pillars without touching them.
. tests/lib.sh
OUT=$B/test-nav-livelock
rm -rf "$OUT"; mkdir -p "$OUT"
trap stop_started EXIT
python3 tests/nav/livelock_worlds.py "$OUT"

run() {   # run NAME STUCK_S SIM_SECONDS: the whole chain in sim time, 8x real time
    _dir=$OUT/$1; mkdir -p "$_dir"; OUT0=$OUT; OUT=$_dir
    start sim $BIN/marie-sim --name sim --param world="$OUT0/pillars.yaml" --param mode=channel --param speed=8 \
        --param start_x=1.5 --param start_y=3.0 --param seed=3
    start planner $BIN/marie-planner --name planner --clock sim --port pose=SIM_TRUTH \
        --param map="$OUT0/box.yaml" --param use_scan=false
    start behaviours $BIN/marie-behaviours --name behaviours --clock sim --port pose=SIM_TRUTH \
        --param input_mode=subscribe --param stuck_s="$2"
    start mission $BIN/marie-mission --name mission --clock sim --port pose=SIM_TRUTH --param sharedmap=false \
        --param goals='[{name: beyond-pillars, x: 8.5, y: 3.0, deadline: 1000}]'
    # Bounded: the mission's goal_reached or the simulated time limit (8x real time, +5 s).
    wait_for $(( $3 / 8 + 5 )) grep -q "event goal_reached" "$OUT/mission.log"
    stop_started; pids=""
    OUT=$OUT0
}

run without 0 240
check "without the progress watch: the robot never gets past the pillars (240 s)" \
    sh -c "! grep -q 'event goal_reached' '$OUT/without/mission.log'"
# The behaviours' closing line: "cycles N: estop E, avoid A, ..."; avoid on a third of them
# or more is the fight (a clear run has avoid on a few).
avoid_share() { sed -n 's/.*cycles \([0-9]*\): estop [0-9]*, avoid \([0-9]*\),.*/\2 \1/p' "$1" |
    awk '{ exit !($2 > 100 && $1 * 3 >= $2) }'; }
check "without the progress watch: avoid won a third of the cycles or more (the livelock)" \
    avoid_share "$OUT/without/behaviours.log"
run with 10 240
check "with it: the goal beyond the pillars is reached" grep -q "event goal_reached" "$OUT/with/mission.log"
check "with it: no progress was detected and a recovery ran" grep -q "event no_progress" "$OUT/with/behaviours.log"
check "with it: the planner was asked to replan" grep -q "makes no progress" "$OUT/with/planner.log"
check "with it: no wall or pillar touched" sh -c "! grep -q 'event collision' '$OUT/with/sim.log'"
finish
