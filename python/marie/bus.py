"""bus: LCM's UDP multicast (udpm://) read and sent by marie itself, as core/bus/udpm*.c do in C.

One socket joined to the group reads every channel; a second, unbound, sends. Subscriptions are
exact channel names (ports are bound to channels, not patterns) or a regular expression for the
tools. Fragmented messages (LC03) are put together per sender; a message whose fragments do not
all come is given up and counted. Nothing here blocks: the component's loop polls fileno().
"""
import re
import socket
import struct
import time
import urllib.parse

MAGIC_SHORT = 0x4C433032        # "LC02"
MAGIC_LONG = 0x4C433033         # "LC03"
SHORT_MAX = 65499               # channel, its NUL and payload in one datagram
FRAG_PAYLOAD = 65487
DEFAULT_URL = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608"
_SHORT = struct.Struct(">II")
_LONG = struct.Struct(">IIIIHH")


class BusError(Exception):
    pass


def parse_url(url):
    """(group, port, ttl, recv_buf_size) of a udpm:// URL; BusError for anything else."""
    u = urllib.parse.urlparse(url)
    if u.scheme != "udpm":
        raise BusError("%s: only udpm:// URLs are read by marie's Python bus" % url)
    try:
        group, port = u.hostname or "239.255.76.67", u.port or 7667
        q = dict(urllib.parse.parse_qsl(u.query))
        ttl = int(q.get("ttl", 0))
        rcvbuf = int(q.get("recv_buf_size", 2 << 20))
        socket.inet_aton(group)
    except (ValueError, OSError) as e:
        raise BusError("%s: %s" % (url, e)) from None
    if not 0 <= ttl <= 255:
        raise BusError("%s: ttl must be 0..255" % url)
    return group, port, ttl, rcvbuf


class Bus:
    """An LCM bus: subscribe(channel, cb) with cb(channel, data, recv_utime), publish(), and
    handle() to call when fileno() is readable."""

    def __init__(self, url=None, clock=None):
        import os
        self.url = url or os.environ.get("LCM_DEFAULT_URL") or DEFAULT_URL
        group, port, ttl, rcvbuf = parse_url(self.url)
        self._time_us = clock or (lambda: time.time_ns() // 1000)
        self._to = (group, port)
        self.rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.rx.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.rx.bind(("", port))
        mreq = socket.inet_aton(group) + socket.inet_aton("0.0.0.0")
        self.rx.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, mreq)
        try:
            self.rx.setsockopt(socket.SOL_SOCKET, 33, rcvbuf)     # SO_RCVBUFFORCE (root)
        except OSError:
            self.rx.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        self.rx.setblocking(False)
        self.tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.tx.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, ttl)
        self.tx.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP, 1)
        self._seq = 0
        self._subs = {}             # channel -> [callbacks]
        self._patterns = []         # (compiled regex, callback)
        self._frags = {}            # sender -> [seqno, size, channel, bytearray, got, count, seen]
        self._chbytes = {}          # channel -> its bytes and NUL, as sent
        self.stats = {"bad_datagrams": 0, "given_up": 0, "received": 0, "sent": 0, "send_failed": 0}

    def fileno(self):
        return self.rx.fileno()

    def close(self):
        self.rx.close()
        self.tx.close()

    def subscribe(self, channel, cb):
        self._subs.setdefault(channel, []).append(cb)
        return (channel, cb)

    def subscribe_regex(self, regex, cb):
        sub = (re.compile(regex), cb)
        self._patterns.append(sub)
        return sub

    def unsubscribe(self, sub):
        if sub in self._patterns:
            self._patterns.remove(sub)
        elif sub[0] in self._subs and sub[1] in self._subs[sub[0]]:
            self._subs[sub[0]].remove(sub[1])

    def publish(self, channel, data):
        """Sends one message; False (counted) when the kernel refused it."""
        ch = self._chbytes.get(channel)
        if ch is None:
            ch = self._chbytes[channel] = channel.encode() + b"\0"
        seq = self._seq
        self._seq = (self._seq + 1) & 0xFFFFFFFF
        try:
            if len(ch) + len(data) <= SHORT_MAX:
                self.tx.sendto(_SHORT.pack(MAGIC_SHORT, seq) + ch + data, self._to)
            else:
                self._send_fragments(seq, ch, data)
        except OSError:
            self.stats["send_failed"] += 1
            return False
        self.stats["sent"] += 1
        return True

    def _send_fragments(self, seq, ch, data):
        n = len(data)
        first = FRAG_PAYLOAD - len(ch)
        count = 1 + (max(0, n - first) + FRAG_PAYLOAD - 1) // FRAG_PAYLOAD
        off, no = 0, 0
        while no < count:
            room = first if no == 0 else FRAG_PAYLOAD
            chunk = data[off:off + room]
            hdr = _LONG.pack(MAGIC_LONG, seq, n, off, no, count)
            self.tx.sendto(hdr + (ch if no == 0 else b"") + chunk, self._to)
            off += len(chunk)
            no += 1

    def handle(self, limit=1):
        """Reads at most `limit` datagrams and calls the subscribers; returns the number of
        messages delivered. One a call by default, as the C loop reads the bus: a loop calls it
        when fileno() is readable, and asking the socket whether more waits (EAGAIN raised as
        an exception) cost 6 us, more than the rest of a message's path."""
        delivered = 0
        for _ in range(limit):
            try:
                pkt, sender = self.rx.recvfrom(65536)
            except (BlockingIOError, InterruptedError):
                break
            delivered += self._datagram(pkt, sender)
        return delivered

    def _datagram(self, pkt, sender):
        if len(pkt) >= 8:
            magic = _SHORT.unpack_from(pkt)[0]
            if magic == MAGIC_SHORT:
                end = pkt.find(b"\0", 8)
                if end > 8:
                    self._deliver(pkt[8:end], pkt[end + 1:])
                    return 1
            elif magic == MAGIC_LONG and len(pkt) >= 20:
                return self._fragment(pkt, sender)
        self.stats["bad_datagrams"] += 1
        return 0

    def _fragment(self, pkt, sender):
        _, seq, size, off, no, count = _LONG.unpack_from(pkt)
        body = pkt[20:]
        st = self._frags.get(sender)
        if st is None or st[0] != seq:
            if st is not None:
                self.stats["given_up"] += 1
            if size > (64 << 20) or count == 0:
                self.stats["bad_datagrams"] += 1
                return 0
            st = self._frags[sender] = [seq, size, None, bytearray(size), 0, count, set()]
        if no == 0:
            end = body.find(b"\0")
            if end <= 0:
                self.stats["bad_datagrams"] += 1
                return 0
            st[2] = body[:end]
            body = body[end + 1:]
        if no in st[6] or off + len(body) > st[1] or count != st[5]:
            self.stats["bad_datagrams"] += 1
            return 0
        st[3][off:off + len(body)] = body
        st[6].add(no)
        st[4] += len(body)
        if len(st[6]) == st[5] and st[4] == st[1] and st[2] is not None:
            del self._frags[sender]
            self._deliver(st[2], bytes(st[3]))
            return 1
        return 0

    def _deliver(self, channel_b, data):
        self.stats["received"] += 1
        channel = channel_b.decode("utf-8", "replace")
        utime = self._time_us()
        subs = self._subs.get(channel)
        if subs:
            for cb in tuple(subs):
                cb(channel, data, utime)
        for rx, cb in tuple(self._patterns):
            if rx.fullmatch(channel):
                cb(channel, data, utime)
