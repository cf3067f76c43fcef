"""stall_client: stalled clients beside a live page: connections that send half a request and
wait, pages that open their WebSocket and never read. Meanwhile it times a file fetch and a new
page's hello and records the longest silence on the live page. Prints a JSON object."""
import json
import socket
import sys
import time
import urllib.request

sys.path.insert(0, "tests/viewer")
from wsclient import WsClient  # noqa: E402

port = int(sys.argv[1])
half_requests, stalled_pages = int(sys.argv[2]), int(sys.argv[3])
origin = "http://127.0.0.1:%d" % port
out = {}

live = WsClient("127.0.0.1", port, origin=origin)
out["live_hello"] = bool(live.until(lambda m: m["type"] == "hello"))

held = []
for _ in range(half_requests):
    s = socket.create_connection(("127.0.0.1", port), timeout=5)
    s.sendall(b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n")        # and never the blank line
    held.append(s)
for _ in range(stalled_pages):
    s = socket.socket()
    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 2048)     # a window that fills at once
    s.settimeout(5)
    s.connect(("127.0.0.1", port))
    s.sendall(("GET /ws HTTP/1.1\r\nHost: 127.0.0.1:%d\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
               "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
               "Origin: %s\r\n\r\n" % (port, origin)).encode())
    try:
        status = s.recv(12).decode(errors="replace")
    except OSError as e:
        status = str(e)
    out.setdefault("stalled_status", []).append(status)
    held.append(s)                                             # not read again

t = time.monotonic()
try:
    body = urllib.request.urlopen("http://127.0.0.1:%d/viewer.js" % port, timeout=10).read()
    out["fetch_s"] = round(time.monotonic() - t, 3) if len(body) > 1000 else None
except OSError as e:
    out["fetch_s"], out["fetch_error"] = None, str(e)

t = time.monotonic()
try:
    other = WsClient("127.0.0.1", port, origin=origin, timeout=10)
    out["page_s"] = round(time.monotonic() - t, 3) if other.until(lambda m: m["type"] == "hello", 10) else None
except OSError as e:
    out["page_s"], out["page_error"] = None, str(e)

# The live page, for 6 s: every frame's arrival.
live.sock.settimeout(10)
last, gap, frames, end = time.monotonic(), 0.0, 0, time.monotonic() + 6
try:
    while time.monotonic() < end:
        live.recv()
        now = time.monotonic()
        gap, last, frames = max(gap, now - last), now, frames + 1
except OSError as e:
    out["live_error"] = str(e)
    gap = max(gap, time.monotonic() - last)
out["live_frames"], out["live_max_gap_s"] = frames, round(gap, 3)
print(json.dumps(out))
