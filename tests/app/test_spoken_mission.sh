#!/bin/sh
# test-group: robot
# The spoken-command mission in the robot application: config/spartacus.yaml's sim-voice profile
# under the four managers. A person behind the robot, to its left, says "go to room b": the
# phrase is recognized on the tracked speaker's separated stream, the robot turns on the spot
# toward the speaker (the face-the-speaker behaviour of the arbitration, measured on the
# simulator's true heading), answers by speech (the synthesized voice on the bus), and the
# mission, which obeys only signed requests, takes the goal and reaches room b without touching
# a wall. Prints the time from the end of the words to the start of the answer.
. tests/lib.sh
OUT=$B/test-spoken
rm -rf "$OUT"; mkdir -p "$OUT"
export MARIE_KEY=$OUT/key MARIE_SEQ_FILE=$OUT/seq
PATH=$BIN:$PATH
cleanup() {
    marie --timeout 20 down > /dev/null 2>&1
    stop_started
}
trap cleanup EXIT INT TERM
num() { sed -n "s/^$1=\([-0-9.]*\).*/\1/p" "$OUT/probe.txt"; }
speaker=1.2,16.1        # the sim-voice scene's speech source; the robot starts at (2, 15) facing +x

setup "order key" marie keygen "$MARIE_KEY"
start logger lcm-logger -q --lcm-url="${LCM_DEFAULT_URL:-udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608}" "--channel=^(?!PARTICLES|AUDIO|SEPARATED_AUDIO$).*" "$OUT/spoken.lcm"
for h in onboard1 onboard2 onboard3 laptop; do
    mkdir -p "$OUT/state/$h"
    start "am-$h" marie-am --host $h --state-dir "$OUT/state/$h" --key "$MARIE_KEY"
done
hosts() { marie --json ps --window 0.7 2>/dev/null | python3 -c 'import json, sys; sys.exit(len(json.load(sys.stdin)["hosts"]) != 4)'; }
setup "four managers answer" wait_for 10 hosts
start probe "$B/tests/spoken_probe" --speaker $speaker --goal "room b" --timeout 85
setup "marie up --profile sim-voice" marie --timeout 30 up config/spartacus.yaml --profile sim-voice
wait $pid_probe
cp "$OUT/probe.log" "$OUT/probe.txt"
cat "$OUT/probe.txt"

check "\"go to room b\" recognized on the bus" grep -qx "heard=go to room b" "$OUT/probe.txt"
check "dialogue reports where the speaker is" grep -q "^face_event=1" "$OUT/probe.txt"
check "the speaker was well away from the robot's heading when heard (> 60 deg)" le 60 "$(num heading_error_when_heard_deg)"
check "the robot turned toward the speaker (true heading within 25 deg of them)" le "$(num heading_error_min_deg)" 25
check "the face-the-speaker behaviour drove the turn" le 1 "$(num face_speaker_cycles)"
check "the robot answered \"Going to room b.\"" grep -qix "said=going to room b." "$OUT/probe.txt"
check "the answer's voice was on the bus (TTS_AUDIO)" le 10 "$(num tts_blocks)"
check "the answer started within 5 s of the end of the words" le "$(num answer_after_words_s)" 5
check "the mission took the spoken goal (signed request accepted)" grep -qx "goal_started=1" "$OUT/probe.txt"
check "no request refused" grep -qx "requests_refused=0" "$OUT/probe.txt"
check "room b reached" le 0 "$(num reached_after_words_s)"
check "truly in room b (simulator's truth within 0.6 m of 11,10)" python3 -c "
import math, sys; x, y = map(float, sys.argv[1].split(',')); sys.exit(0 if math.hypot(x - 11, y - 10) < 0.6 else 1)" \
    "$(sed -n 's/^truth_final=//p' "$OUT/probe.txt")"
check "no collision" grep -qx "collisions=0" "$OUT/probe.txt"
echo "# spoken mission: answer $(num answer_after_words_s) s after the end of the words" \
     "(the recognizer's end of speech less its 0.45 s wait), room b reached $(num reached_after_words_s) s after"
finish
