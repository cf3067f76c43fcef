"""pin_guess: a guesser of a page's PIN, as the peers that found the touch page's did: a WebSocket
client (no browser, so no Origin) that sends requests with wrong PINs. Prints one JSON object of
what the server said, for test_face_pin.sh and test_viewer_controls.sh.

    pin_guess.py PORT RIGHT_PIN FLOOD_SECONDS [OP]

1. flood: wrong PINs as fast as the server answers, for FLOOD_SECONDS;
2. patient: wrong PINs, each once the server said it may try again, until it says locked;
3. the right PIN at once (locked out: refused);
4. the right PIN from another address (127.0.0.2), which no lockout of 127.0.0.1 concerns.
OP is the request ("stop" for the touch page; "order" for the viewer's controls)."""
import json
import re
import sys
import time

sys.path.insert(0, "tests/viewer")
from wsclient import WsClient  # noqa: E402

port, right, flood_s = int(sys.argv[1]), sys.argv[2], float(sys.argv[3])
op = sys.argv[4] if len(sys.argv) > 4 else "stop"
out = {}


def request(c, pin):
    c.send({"op": op, "cmd": "pause", "target": "nobody", "pin": pin})
    m = c.until(lambda m: m["type"] == "notice", 5)
    return (m or {}).get("text", "no answer")


def kind(text):
    return "wrong" if text.startswith("wrong PIN") else "locked" if text.startswith("locked") else \
        "too soon" if text.startswith("too soon") else "accepted"


c = WsClient("127.0.0.1", port)
c.until(lambda m: m["type"] == "hello")
said, guess, t0 = {}, 0, time.time()
while time.time() - t0 < flood_s:
    guess += 1
    k = kind(request(c, "%06d" % guess))
    said[k] = said.get(k, 0) + 1
out["flood"] = dict(said, tries=guess, tries_per_s=guess / (time.time() - t0))
patient, t1 = [], time.time()
while time.time() - t1 < 60 and len(patient) < 20:
    guess += 1
    text = request(c, "%06d" % guess)
    patient.append(kind(text))
    if "locked" in text:
        out["lock_text"] = text
        break
    wait = re.search(r"try again in ([0-9.]+) s", text)
    time.sleep(float(wait.group(1)) + 0.05 if wait else 0)
out["patient"] = patient
out["right_pin_when_locked"] = request(c, right)
other = WsClient("127.0.0.1", port, source="127.0.0.2")
other.until(lambda m: m["type"] == "hello")
for _ in range(5):      # the short wait every address shares after wrong PINs, then in
    text = request(other, right)
    wait = re.search(r"^too soon.*try again in ([0-9.]+) s", text)
    if not wait:
        break
    time.sleep(float(wait.group(1)) + 0.05)
out["right_pin_other_address"] = text
print(json.dumps(out))
