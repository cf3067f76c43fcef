"""controls_client: drives the viewer's controls over its WebSocket as the page does, and
checks what comes back (exit 0 when every expectation held; prints each)."""
import sys
sys.path.insert(0, "tests/viewer")
from wsclient import WsClient  # noqa: E402

port, pin = int(sys.argv[1]), sys.argv[2]
ok = True


def expect(name, cond):
    global ok
    print(("ok   " if cond else "FAIL ") + name, flush=True)
    ok = ok and bool(cond)


c = WsClient("127.0.0.1", port, origin="http://127.0.0.1:%d" % port)
hello = c.until(lambda m: m["type"] == "hello")
expect("hello with controls enabled", hello and hello["controls"])
hb = lambda state: (lambda m: m["type"] == "msg" and m.get("k") == "hb" and m["msg"]["component"] == "walker"
                    and m["msg"]["state"] == state)
expect("walker running", c.until(hb(2), 10))
c.send({"op": "order", "cmd": "pause", "target": "walker", "pin": pin})
expect("order sent notice", c.until(lambda m: m["type"] == "notice" and "order sent: pause walker" in m["text"]))
expect("manager accepted the signed order", c.until(lambda m: m.get("k") == "reply" and m["msg"]["ok"] is True, 5))
expect("walker paused (heartbeat)", c.until(hb(3), 5))
c.send({"op": "order", "cmd": "resume", "target": "walker", "pin": pin})
expect("walker running again", c.until(hb(2), 5))
c.send({"op": "goal", "x": 3.5, "y": 2.25, "th": 0.5, "pin": pin})
g = c.until(lambda m: m["type"] == "msg" and m.get("k") == "goal" and m["msg"]["id"] >= 900000, 5)
g = g and g["msg"]
expect("signed goal request obeyed: the mission's goal", g and g["pose"]["x"] == 3.5 and g["pose"]["y"] == 2.25 and g["name"] == "viewer")
c.send({"op": "bogus"})
expect("unknown command answered", c.until(lambda m: m["type"] == "notice" and m["level"] == "error"))
c.close()

try:
    WsClient("127.0.0.1", port, origin="http://evil.example")
    expect("WebSocket from a foreign origin refused", False)
except ConnectionError:
    expect("WebSocket from a foreign origin refused", True)
sys.exit(0 if ok else 1)
