#!/usr/bin/env python3
# test-light
"""test_xml_peer: a peer of marie-xml-bridge written only from docs/xml-bridge.md with Python's
standard library (socket + xml.etree). It round-trips a random message of every type the bridge
describes (XML -> bus -> XML, field by field), pulls latest values, and checks that bad input,
stalled documents and too many clients each get an error reply or a closed connection while the
bridge keeps serving everyone else."""
import base64
import math
import os
import random
import socket
import struct
import subprocess
import sys
import time
import xml.etree.ElementTree as ET

B = os.environ.get("B", "build")
PORT = 7671
ok_count = 0
bad_count = 0


def check(name, fn):
    global ok_count, bad_count
    print("[ RUN      ] %s" % name, flush=True)
    try:
        fn()
        print("[       OK ] %s" % name, flush=True)
        ok_count += 1
    except Exception as e:  # a failed case is reported and the others still run
        import traceback
        traceback.print_exc()
        print("[  FAILED  ] %s: %s" % (name, e), flush=True)
        bad_count += 1


class Peer:
    """One connection: documents go out as XML text, come back one per line."""

    def __init__(self, rcvbuf=0):
        self.s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        if rcvbuf:
            self.s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        self.s.settimeout(5)
        self.s.connect(("127.0.0.1", PORT))
        self.buf = b""
        self.closed = False

    def send(self, doc):
        if isinstance(doc, ET.Element):
            doc = ET.tostring(doc, encoding="utf-8")
        if isinstance(doc, str):
            doc = doc.encode()
        self.s.sendall(doc)

    def recv(self, timeout=5):
        """The next document as an Element, or None when the bridge closed the connection."""
        end = time.time() + timeout
        while b"\n" not in self.buf:
            self.s.settimeout(max(0.01, end - time.time()))
            try:
                data = self.s.recv(65536)
            except (ConnectionResetError, BrokenPipeError):
                data = b""
            if not data:
                self.closed = True
                return None
            self.buf += data
        line, self.buf = self.buf.split(b"\n", 1)
        return ET.fromstring(line)

    def recv_until(self, tag, timeout=5):
        while True:
            d = self.recv(timeout)
            if d is None or d.tag == tag:
                return d

    def request(self, doc):
        self.send(doc)
        d = self.recv()
        assert d is not None, "connection closed"
        return d

    def close(self):
        self.s.close()


PEER_PARAMS = ["stall_ms=500", "max_clients=150", "max_document=65536", "max_depth=16", "queue=32",
               "sndbuf=4096", "max_per_address=0"]


def start_bridge(params=PEER_PARAMS, log="xml_bridge_peer.stderr"):
    """Starts marie-xml-bridge on PORT with these --param settings; returns once it accepts."""
    args = [os.path.join(B, "bin", "marie-xml-bridge"), "--name", "xml_bridge_test",
            "--param", "port=%d" % PORT]
    for kv in params:
        args += ["--param", kv]
    p = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=open(os.path.join(B, "test-logs", log), "w"))
    end = time.time() + 10
    while time.time() < end:
        try:
            socket.create_connection(("127.0.0.1", PORT), timeout=1).close()
            return p
        except OSError:
            time.sleep(0.05)
    p.kill()
    raise RuntimeError("bridge did not start")


# ---- values from the bridge's own type descriptions ----

types = {}


def describe(peer, name):
    if name not in types:
        d = peer.request('<describe type="%s"/>' % name)
        assert d.tag == "type", ET.tostring(d)
        types[name] = d
        for f in d.findall("field"):
            if f.get("type").startswith("marie."):
                describe(peer, f.get("type"))
    return types[name]


INT_RANGES = {"int8_t": 8, "int16_t": 16, "int32_t": 32, "int64_t": 64}


def rand_scalar(t, rng):
    if t in INT_RANGES:
        bits = INT_RANGES[t]
        return rng.choice([-(1 << (bits - 1)), (1 << (bits - 1)) - 1, rng.randrange(-(1 << (bits - 1)), 1 << (bits - 1))])
    if t == "byte":
        return rng.randrange(256)
    if t == "boolean":
        return rng.random() < 0.5
    if t in ("float", "double"):
        v = rng.choice([0.0, -1.5, float("inf"), float("nan"), rng.uniform(-1e6, 1e6), rng.uniform(-1, 1) * 1e-8])
        return struct.unpack("f", struct.pack("f", v))[0] if t == "float" else v
    if t == "string":
        return "".join(rng.choice(["a", "Z", " ", "<", ">", "&", '"', "'", "\t", "\n", "é", "€", "𝄞", "\x01"])
                       for _ in range(rng.randrange(10)))
    raise ValueError(t)


def dims_of(f):
    d = f.get("dims")
    return [] if not d else d.strip("[]").split("][")


def rand_struct(tname, rng, depth=0):
    t = types[tname]
    fields = t.findall("field")
    lengths = {}
    for f in fields:
        for d in dims_of(f):
            if not d.isdigit() and d not in lengths:
                lengths[d] = 0 if depth > 2 else rng.randrange(4 if f.get("type") != "byte" else 30)
    v = {}
    for f in fields:
        name, ft = f.get("name"), f.get("type")
        dims = dims_of(f)
        if not dims:
            if name in lengths:
                v[name] = lengths[name]
            elif ft.startswith("marie."):
                v[name] = rand_struct(ft, rng, depth + 1)
            else:
                v[name] = rand_scalar(ft, rng)
            continue
        n = 1
        for d in dims:
            n *= int(d) if d.isdigit() else lengths[d]
        if ft == "byte":
            v[name] = bytes(rng.randrange(256) for _ in range(n))
        elif ft.startswith("marie."):
            v[name] = [rand_struct(ft, rng, depth + 1) for _ in range(n)]
        else:
            v[name] = [rand_scalar(ft, rng) for _ in range(n)]
    return v


def fmt_real(x):
    if math.isnan(x):
        return "NaN"
    if math.isinf(x):
        return "INF" if x > 0 else "-INF"
    return repr(x)


def fmt(t, x):
    if t == "boolean":
        return "true" if x else "false"
    if t in ("float", "double"):
        return fmt_real(x)
    return str(x)


def put_string(el, s):
    # XML cannot carry control characters, and a CR would be read back as LF: base64 then.
    if any(ord(c) < 0x20 and c not in "\t\n" for c in s):
        el.set("encoding", "base64")
        el.text = base64.b64encode(s.encode()).decode()
    else:
        el.text = s


def to_xml(parent, tname, v, lengths_too):
    t = types[tname]
    length_names = {d for f in t.findall("field") for d in dims_of(f) if not d.isdigit()}
    for f in t.findall("field"):
        name, ft = f.get("name"), f.get("type")
        if name in length_names and not lengths_too:
            continue            # the bridge counts the array
        el = ET.SubElement(parent, name)
        x = v[name]
        if not dims_of(f):
            if ft.startswith("marie."):
                to_xml(el, ft, x, lengths_too)
            elif ft == "string":
                put_string(el, x)
            else:
                el.text = fmt(ft, x)
        elif ft == "byte":
            el.text = base64.b64encode(x).decode()
        elif ft.startswith("marie."):
            for item in x:
                to_xml(ET.SubElement(el, "item"), ft, item, lengths_too)
        elif ft == "string":
            for item in x:
                put_string(ET.SubElement(el, "item"), item)
        else:
            el.text = " ".join(fmt(ft, i) for i in x)


def parse_scalar(t, text):
    text = (text or "").strip()
    if t == "boolean":
        return text in ("true", "1")
    if t == "float":    # the text is the shortest that reads back to the same float32
        return struct.unpack("f", struct.pack("f", float(text.replace("INF", "inf"))))[0]
    if t == "double":
        return float(text.replace("INF", "inf"))
    return int(text)


def get_string(el):
    if el.get("encoding") == "base64":
        return base64.b64decode(el.text or "").decode()
    return el.text or ""


def from_xml(el, tname):
    t = types[tname]
    v = {}
    for f in t.findall("field"):
        name, ft = f.get("name"), f.get("type")
        c = el.find(name)
        assert c is not None, "field %s missing" % name
        if not dims_of(f):
            if ft.startswith("marie."):
                v[name] = from_xml(c, ft)
            elif ft == "string":
                v[name] = get_string(c)
            else:
                v[name] = parse_scalar(ft, c.text)
        elif ft == "byte":
            v[name] = base64.b64decode(c.text or "")
        elif ft.startswith("marie."):
            v[name] = [from_xml(i, ft) for i in c.findall("item")]
        elif ft == "string":
            v[name] = [get_string(i) for i in c.findall("item")]
        else:
            v[name] = [parse_scalar(ft, x) for x in (c.text or "").split()]
    return v


def same(a, b, path="msg"):
    if isinstance(a, dict):
        assert set(a) == set(b), "%s: fields %s vs %s" % (path, sorted(a), sorted(b))
        for k in a:
            same(a[k], b[k], path + "." + k)
    elif isinstance(a, list):
        assert len(a) == len(b), "%s: %d vs %d elements" % (path, len(a), len(b))
        for i, (x, y) in enumerate(zip(a, b)):
            same(x, y, "%s[%d]" % (path, i))
    elif isinstance(a, float) and math.isnan(a):
        assert isinstance(b, float) and math.isnan(b), "%s: NaN vs %r" % (path, b)
    else:
        assert a == b, "%s: sent %r, got %r" % (path, a, b)


# ---- cases ----

def case_every_type_round_trips():
    p = Peer()
    assert p.recv().tag == "hello"
    tl = p.request("<types/>")
    names = [t.get("name") for t in tl.findall("type")]
    assert "marie.pose_cov_t" in names and len(names) >= 20, names
    rng = random.Random(7)
    for name in names:
        describe(p, name)
    for name in names:
        ch = "PY." + name.split(".")[1]
        r = p.request('<subscribe channel="%s" type="%s"/>' % (ch, name))
        assert r.tag == "ok", ET.tostring(r)
        for k in range(3):
            v = rand_struct(name, rng)
            doc = ET.Element("publish", channel=ch, type=name, id="%s-%d" % (name, k))
            to_xml(doc, name, v, lengths_too=(k == 2))
            p.send(doc)
            got = {}
            while "ok" not in got or "message" not in got:
                d = p.recv()
                assert d is not None and d.tag in ("ok", "message"), ET.tostring(d) if d is not None else "closed"
                got[d.tag] = d
            m = got["message"]
            assert m.get("channel") == ch and m.get("type") == name
            same(v, from_xml(m, name), name)
        assert p.request('<unsubscribe channel="%s"/>' % ch).tag == "ok"
    p.close()


def case_pull_latest():
    p = Peer()
    p.recv()
    assert p.request('<subscribe channel="PY.LATEST" type="marie.motor_command_t" mode="latest"/>').tag == "ok"
    r = p.request('<pull channel="PY.LATEST" id="1"/>')
    assert r.tag == "error" and r.get("code") == "no-data", ET.tostring(r)
    q = Peer()
    q.recv()
    for i in range(5):
        q.send('<publish channel="PY.LATEST" type="motor_command_t" ack="false"><utime>%d</utime><v>0.5</v><source>teleop</source></publish>' % i)
    assert q.request('<ping/>').tag == "ok"
    end = time.time() + 3
    while True:
        r = p.request('<pull channel="PY.LATEST" type="marie.motor_command_t" id="2"/>')
        if r.tag == "message" and r.find("utime").text == "4":
            break
        assert time.time() < end, ET.tostring(r)
        time.sleep(0.05)
    assert r.get("to") == "pull" and r.get("id") == "2" and int(r.get("age_us")) >= 0
    assert r.find("source").text == "teleop" and float(r.find("v").text) == 0.5
    r = p.request('<pull channel="PY.NEVER"/>')
    assert r.tag == "error" and r.get("code") == "not-subscribed"
    p.close()
    q.close()


def expect_reply_error(doc, code):
    p = Peer()
    p.recv()
    r = p.request(doc)
    assert r.tag == "error" and r.get("code") == code, ET.tostring(r)
    assert r.get("reason"), "an error says why"
    assert p.request('<ping id="after"/>').get("id") == "after"   # still served
    p.close()


def expect_closed(data, code, wait=5):
    p = Peer()
    p.recv()
    p.send(data)
    last = None
    while True:
        d = p.recv(timeout=wait)
        if d is None:
            break
        last = d
    assert p.closed
    assert last is not None and last.tag == "error" and last.get("code") == code, \
        ET.tostring(last) if last is not None else "no reply"
    p.close()


def case_bad_input():
    witness = Peer()
    witness.recv()
    expect_reply_error('<publish channel="X" type="marie.no_such_t"/>', "unknown-type")
    expect_reply_error('<pull channel="NO.SUCH.CHANNEL"/>', "not-subscribed")
    expect_reply_error('<publish channel="X" type="pose2d_t"><x>north</x></publish>', "bad-value")
    expect_reply_error('<publish channel="X" type="gyro_t"><status>300</status></publish>', "bad-value")
    expect_reply_error('<publish channel="X" type="pose2d_t"><altitude>1</altitude></publish>', "unknown-field")
    expect_reply_error('<publish channel="X" type="laser_scan_t"><nranges>5</nranges><ranges>1 2</ranges></publish>', "bad-length")
    expect_reply_error('<publish channel="X" type="image_t"><data>%%%</data></publish>', "bad-value")
    expect_reply_error('<teleport/>', "unknown-request")
    expect_closed(b'<publish channel="X" type="pose2d_t"><x>1</y></publish>', "malformed")
    expect_closed(b'\x00\x01\x02garbage', "malformed")
    expect_closed(b'<a>' * 40, "too-deep")
    expect_closed(b'<publish channel="X" type="event_t"><text>' + b'x' * 70000 + b'</text></publish>', "too-large")
    expect_closed(b'<publish channel="X" type="pose2d_t"><x>1', "stalled")
    assert witness.request('<ping id="w"/>').get("id") == "w"
    witness.close()


def case_hundreds_of_clients():
    peers = [Peer() for _ in range(200)]
    served, refused = [], 0
    for p in peers:
        d = p.recv()
        if d is not None and d.tag == "error" and d.get("code") == "busy":
            assert p.recv() is None         # then closed
            refused += 1
        else:
            assert d is not None and d.tag == "hello", ET.tostring(d) if d is not None else "closed"
            served.append(p)
    assert len(served) == 150 and refused == 50, (len(served), refused)
    for i, p in enumerate(served):
        p.send('<subscribe channel="PY.MANY" type="pose2d_t" id="%d"/>' % i)
    for p in served:
        assert p.recv_until("ok") is not None
    served[0].send('<publish channel="PY.MANY" type="pose2d_t" ack="false"><x>42</x></publish>')
    for p in served:
        m = p.recv_until("message")
        assert m is not None and float(m.find("x").text) == 42.0
    for p in peers:
        p.close()
    end = time.time() + 5           # the bridge frees the slots once it sees the closes
    while True:
        p = Peer()
        d = p.recv()
        p.close()
        if d is not None and d.tag == "hello":
            break
        assert d is not None and d.get("code") == "busy" and time.time() < end, \
            ET.tostring(d) if d is not None else "closed"
        time.sleep(0.05)


def case_slow_reader_loses_oldest():
    slow = Peer(rcvbuf=4096)
    slow.recv()
    assert slow.request('<subscribe channel="PY.FLOOD" type="pose2d_t"/>').tag == "ok"
    fast = Peer()
    fast.recv()
    assert fast.request('<subscribe channel="PY.FLOOD" type="pose2d_t"/>').tag == "ok"
    n = 2000
    fast_lost = 0
    for i in range(0, n, 16):       # publish through the bridge; the slow peer reads nothing
        fast.send("".join('<publish channel="PY.FLOOD" type="pose2d_t" ack="false"><x>%d</x></publish>' % k
                          for k in range(i, i + 16)))
        while True:                 # the fast peer keeps up: it hears its own burst
            m = fast.recv()
            assert m is not None
            if m.tag == "dropped":
                fast_lost += int(m.get("count"))
            if m.tag == "message" and float(m.find("x").text) == i + 15:
                break
    assert fast_lost == 0, fast_lost
    assert fast.request('<ping id="f"/>').get("id") == "f"
    got, lost, last = 0, 0, None
    while True:
        try:
            d = slow.recv(timeout=1)
        except socket.timeout:
            break                   # all read
        if d is None:
            raise AssertionError("slow reader was closed")
        if d.tag == "dropped":      # count: lost since the previous notice; total: so far
            assert int(d.get("count")) == int(d.get("total")) - lost, ET.tostring(d)
            lost += int(d.get("count"))
        elif d.tag == "message":
            got += 1
            last = float(d.find("x").text)
    print("slow reader: %d delivered, %d dropped" % (got, lost))
    assert lost > 0 and last == n - 1, (got, lost, last)
    assert got + lost <= n
    slow.close()
    fast.close()


def case_heartbeat_counts_bad_input():
    p = Peer()
    p.recv()
    assert p.request('<subscribe channel="MARIE_HEARTBEAT" type="heartbeat_t"/>').tag == "ok"
    end = time.time() + 5
    while time.time() < end:
        m = p.recv_until("message", timeout=3)
        assert m is not None
        if m.find("component").text != "xml_bridge_test":
            continue
        counters = {c.find("name").text: int(c.find("value").text) for c in m.find("counters").findall("item")}
        bad = int(m.find("bad_input").text)
        if bad > 0:
            print("heartbeat: bad_input=%d drops=%s counters=%s" % (bad, m.find("drops").text, counters))
            assert int(m.find("drops").text) > 0      # the slow reader's losses
            return
    raise AssertionError("no heartbeat with bad input counted")


def case_error_table_matches_schema_and_code():
    """docs/xml-bridge.md's error table, the XSD's errorCode and the codes the bridge's source
    sends are one set, each code in one row."""
    import re
    root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
    doc = open(os.path.join(root, "docs", "xml-bridge.md")).read()
    table = doc[doc.index("## Errors"):]
    table = table[:table.index("\n\n", table.index("| code |"))]
    rows = [r for r in table.splitlines() if r.startswith("| `")]
    in_doc = [c for r in rows for c in re.findall(r"`([a-z-]+)`", r.split("|")[1])]
    assert len(in_doc) == len(set(in_doc)), "codes in two rows: %s" % sorted(c for c in in_doc if in_doc.count(c) > 1)
    xsd = open(os.path.join(root, "docs", "xml-bridge.xsd")).read()
    enum = xsd[xsd.index('<xs:simpleType name="errorCode">'):]
    enum = enum[:enum.index("</xs:simpleType>")]
    in_xsd = set(re.findall(r'<xs:enumeration value="([a-z-]+)"/>', enum))
    sent = set()
    for name in os.listdir(os.path.join(root, "adapters", "xml_bridge")):
        if name.endswith(".c"):
            src = open(os.path.join(root, "adapters", "xml_bridge", name)).read()
            sent |= set(re.findall(r'(?:reply_error|client_fail)\(\w+,\s*(?:\w+,\s*)?"([a-z-]+)"', src))
            sent |= set(re.findall(r'\b(?:xb_error_set|fail)\([^,()]+,\s*"([a-z-]+)"', src))
            sent |= set(re.findall(r'code=\\"([a-z-]+)\\"', src))
    assert set(in_doc) == in_xsd, ("table only", set(in_doc) - in_xsd, "schema only", in_xsd - set(in_doc))
    assert sent <= in_xsd, ("sent but not documented", sent - in_xsd)
    assert len(sent) >= 15, sorted(sent)     # the patterns above still find the bridge's codes


def main():
    os.makedirs(os.path.join(B, "test-logs"), exist_ok=True)
    bridge = start_bridge()
    try:
        check("error_table_matches_schema_and_code", case_error_table_matches_schema_and_code)
        check("every_type_round_trips_through_the_bus", case_every_type_round_trips)
        check("pull_gives_the_latest_value", case_pull_latest)
        check("bad_input_gets_an_error_or_a_close", case_bad_input)
        check("hundreds_of_clients_bounded", case_hundreds_of_clients)
        check("slow_reader_loses_oldest_not_the_others", case_slow_reader_loses_oldest)
        check("heartbeat_counts_bad_input_and_drops", case_heartbeat_counts_bad_input)
        check("bridge_still_running", lambda: (bridge.poll() is None) or (_ for _ in ()).throw(AssertionError("bridge exited")))
    finally:
        bridge.terminate()
        try:
            bridge.wait(5)
        except subprocess.TimeoutExpired:
            bridge.kill()
    print("[  PASSED  ] %d test(s)." % ok_count)
    if bad_count:
        print("[  FAILED  ] %d test(s)." % bad_count)
        sys.exit(1)


if __name__ == "__main__":
    main()
