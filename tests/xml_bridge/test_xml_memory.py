#!/usr/bin/env python3
# test-light
"""test_xml_memory: marie-xml-bridge's memory stays linear in what its clients send. A hundred
clients each leave a 1 MB text node unfinished (under the 1 MiB document limit); the bridge's
resident memory stays under 200 MB and another client keeps getting publish/pull round trips
within a bounded time. A bridge with a small memory budget closes the clients over their share
with a `no-memory` error, largest first, and keeps serving the others."""
import os
import select
import socket
import sys
import time
import xml.etree.ElementTree as ET

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import test_xml_peer as peer  # noqa: E402  (Peer, check, start_bridge)

peer.PORT = 7672
CLIENTS = int(os.environ.get("XB_MEMORY_CLIENTS", "100"))   # fewer to try old builds safely
TEXT = 1000000
RSS_LIMIT = 200 * 1000 * 1000
ROUND_TRIP_LIMIT = 2.5      # seconds: a shared, loaded CPU adds ~0.8 s; a quadratic stall adds more
HEAD = b'<publish channel="MEM.HOLD" type="event_t"><text>'


def rss(pid):
    with open("/proc/%d/status" % pid) as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    raise AssertionError("no VmRSS for %d" % pid)


def unread_bytes(port):
    """Bytes the bridge has not read yet on its accepted sockets (rx_queue in /proc/net/tcp)."""
    total = 0
    for name in ("/proc/net/tcp", "/proc/net/tcp6"):
        try:
            with open(name) as f:
                rows = f.readlines()[1:]
        except OSError:
            continue
        for row in rows:
            cols = row.split()
            if int(cols[1].split(":")[1], 16) == port and cols[3] == "01":    # ESTABLISHED
                total += int(cols[4].split(":")[1], 16)
    return total


class Witness:
    """A client that publishes a value and pulls it back through the bridge's Mailbox."""

    def __init__(self):
        self.p = peer.Peer()
        assert self.p.recv().tag == "hello"
        assert self.p.request('<subscribe channel="MEM.W" type="pose2d_t" mode="latest"/>').tag == "ok"
        self.k = 0
        self.worst = 0.0

    def round_trip(self):
        self.k += 1
        t0 = time.time()
        d = self.p.request('<publish channel="MEM.W" type="pose2d_t" id="%d"><x>%d</x></publish>'
                           % (self.k, self.k))
        assert d.tag == "ok", ET.tostring(d)
        while True:     # the bridge hears its own publish on the bus, then answers the pull
            m = self.p.request('<pull channel="MEM.W"/>')
            if m.tag == "message" and float(m.find("x").text) == self.k:
                break
            assert time.time() - t0 < 10, "value never came back"
        dt = time.time() - t0
        self.worst = max(self.worst, dt)
        return dt


def feed_unfinished(socks, witness, deadline):
    """Sends every client its unfinished document, round-robin; a witness round trip every
    50 ms meanwhile. Returns when all bytes are sent."""
    doc = memoryview(HEAD + b"x" * TEXT)
    sent = {s: 0 for s in socks}
    next_rt = time.time()
    while sent:
        assert time.time() < deadline, "could not send the documents in time"
        _, w, _ = select.select([], list(sent), [], 0.05)
        for s in w:
            sent[s] += s.send(doc[sent[s]:sent[s] + 65536])
            if sent[s] == len(doc):
                del sent[s]
        if time.time() >= next_rt:
            witness.round_trip()
            next_rt = time.time() + 0.05


def connect_all(n):
    socks = []
    for _ in range(n):
        s = socket.create_connection(("127.0.0.1", peer.PORT), timeout=5)
        s.setblocking(False)
        socks.append(s)
    return socks


def replies(s, wait, lines=None):
    """Lines the bridge sent on s within `wait` seconds, until it closes or the given number of
    lines came; and whether it closed."""
    data = b""
    end = time.time() + wait
    while time.time() < end and (lines is None or data.count(b"\n") < lines):
        r, _, _ = select.select([s], [], [], max(0.0, end - time.time()))
        if not r:
            break
        try:
            got = s.recv(65536)
        except (ConnectionResetError, BlockingIOError):
            got = b""
        if not got:
            return data.splitlines(), True
        data += got
    return data.splitlines(), False


def case_hundred_unfinished_documents():
    bridge = peer.start_bridge(["stall_ms=600000", "max_clients=512", "max_per_address=0"], "xml_bridge_memory.stderr")
    try:
        base = rss(bridge.pid)
        witness = Witness()
        socks = connect_all(CLIENTS)
        feed_unfinished(socks, witness, time.time() + 120)
        end = time.time() + 60
        while unread_bytes(peer.PORT) > 0:      # the bridge has taken in every byte
            assert time.time() < end, "bridge did not read the documents"
            witness.round_trip()
            time.sleep(0.05)
        held = rss(bridge.pid)
        for _ in range(10):
            witness.round_trip()
        print("%d clients x %d-byte unfinished text: bridge RSS %.1f MB (%.1f MB before), "
              "worst witness round trip %.1f ms" % (CLIENTS, TEXT, held / 1e6, base / 1e6, witness.worst * 1e3))
        assert held < RSS_LIMIT, "RSS %.1f MB" % (held / 1e6)
        assert witness.worst < ROUND_TRIP_LIMIT, "witness waited %.3f s" % witness.worst
        for s in socks:                         # every holder is still connected, told nothing
            lines, closed = replies(s, 0.01)
            assert not closed and [ET.fromstring(x).tag for x in lines] == ["hello"], lines
        # Finishing the documents publishes them: the bridge held the text, not a copy per chunk.
        for s in socks[:3]:
            s.setblocking(True)
            s.sendall(b"</text></publish>")
            lines, _ = replies(s, 5, 1)
            assert [ET.fromstring(x).tag for x in lines][-1:] == ["ok"], lines
        for s in socks:
            s.close()
        witness.round_trip()
        assert bridge.poll() is None, "bridge exited"
    finally:
        bridge.terminate()
        bridge.wait(10)


def case_budget_closes_the_largest():
    budget = 8 << 20
    bridge = peer.start_bridge(["stall_ms=600000", "max_memory=%d" % budget], "xml_bridge_budget.stderr")
    try:
        witness = Witness()
        socks = connect_all(12)
        for s in socks:         # 12 x 800 kB does not fit in 8 MiB
            s.setblocking(True)
            s.sendall(HEAD + b"y" * 800000)
        end = time.time() + 30
        while unread_bytes(peer.PORT) > 0:
            assert time.time() < end, "bridge did not read the documents"
            time.sleep(0.05)
        closed, kept = 0, []
        for s in socks:
            lines, eof = replies(s, 0.5)
            docs = [ET.fromstring(x) for x in lines]
            if eof:
                assert docs[-1].tag == "error" and docs[-1].get("code") == "no-memory", lines
                closed += 1
            else:
                kept.append(s)
        print("budget %d bytes: %d clients closed with no-memory, %d kept" % (budget, closed, len(kept)))
        # The largest holders go first, only as many as it takes: most clients stay.
        assert closed >= 2 and len(kept) >= 6 and len(kept) * 800000 <= budget, (closed, len(kept))
        for s in kept:          # the survivors finish their documents and are served
            s.sendall(b"</text></publish>")
            lines, _ = replies(s, 5, 1)
            assert [ET.fromstring(x).tag for x in lines][-1:] == ["ok"], lines
        witness.round_trip()
        for s in socks:
            s.close()
    finally:
        bridge.terminate()
        bridge.wait(10)


def main():
    os.makedirs(os.path.join(peer.B, "test-logs"), exist_ok=True)
    peer.check("hundred_unfinished_1MB_documents_stay_linear", case_hundred_unfinished_documents)
    peer.check("memory_budget_closes_clients_over_their_share", case_budget_closes_the_largest)
    print("[  PASSED  ] %d test(s)." % peer.ok_count)
    if peer.bad_count:
        print("[  FAILED  ] %d test(s)." % peer.bad_count)
        sys.exit(1)


if __name__ == "__main__":
    main()
