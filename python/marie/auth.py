"""auth: lifecycle orders signed with the system's key, checked as core/auth.c checks them.

HMAC-SHA256 (Python's hmac and hashlib: the same function libsodium's crypto_auth_hmacsha256
computes) over the order encoded with an empty MAC; then the freshness window and the per-sender
sequence numbers of marie_auth_check_command (docs/managers.md has the threat model)."""
import hashlib
import hmac
import os
import stat
import time

KEY_LEN = 32
MAC_LEN = 32
LIFETIME_US = 10_000_000
MAX_SKEW_US = 5_000_000


class KeyError_(Exception):
    pass


def load_key(path):
    """The key in a file of 64 hex digits or 32 raw bytes that only its owner may read."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_CLOEXEC)
    except OSError as e:
        raise KeyError_("key file %s: %s" % (path, e.strerror)) from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise KeyError_("key file %s is not a regular file" % path)
        if st.st_mode & 0o077:
            raise KeyError_("key file %s has mode %04o: group or others may read it (chmod 600)"
                            % (path, st.st_mode & 0o7777))
        raw = os.read(fd, 256)
    finally:
        os.close(fd)
    hexdigits = b"0123456789abcdefABCDEF"
    if len(raw) == KEY_LEN and (raw[0] not in hexdigits or raw[1] not in hexdigits or b"\0" in raw):
        return raw
    digits = bytes(b for b in raw if b not in b" \n\r\t")
    try:
        key = bytes.fromhex(digits.decode("ascii"))
    except (ValueError, UnicodeDecodeError):
        key = b""
    if len(key) != KEY_LEN:
        raise KeyError_("key file %s: expected 64 hex digits or 32 raw bytes" % path)
    return key


def mac_of(key, msg):
    """The MAC of an order: over its encoding with mac_len 0 (every other field, seq included)."""
    saved = msg.mac_len, msg.mac
    msg.mac_len, msg.mac = 0, b""
    try:
        data = msg.encode()
    finally:
        msg.mac_len, msg.mac = saved
    return hmac.new(key, data, hashlib.sha256).digest()


def sign(key, msg):
    msg.mac = mac_of(key, msg)
    msg.mac_len = MAC_LEN
    return msg


def wall_us():
    return time.time_ns() // 1000


class Replay:
    """Per-sender marks, in memory: a component's table starts at its own start (its epoch), so
    nothing signed before is obeyed after a restart."""

    def __init__(self):
        self.epoch = wall_us()
        self.last = {}

    def fresh(self, sender, utime, seq):
        if not sender or "\n" in sender or len(sender.encode()) > 256:
            return "forged"
        now = wall_us()
        oldest, newest = now - LIFETIME_US - MAX_SKEW_US, now + MAX_SKEW_US
        if utime < oldest or seq < oldest:
            return "stale"
        if utime > newest or seq > newest:
            return "future"
        if seq <= self.epoch or seq <= self.last.get(sender, 0):
            return "replayed"
        self.last[sender] = seq
        for s in [s for s, v in self.last.items() if v < oldest]:
            del self.last[s]
        return "ok"


def check(key, replay, msg):
    """'ok', or why the order is refused: unsigned, forged, replayed, stale, future."""
    if msg.mac_len <= 0:
        return "unsigned"
    if len(msg.mac) != MAC_LEN or not hmac.compare_digest(mac_of(key, msg), bytes(msg.mac)):
        return "forged"
    return replay.fresh(msg.sender, msg.utime, msg.seq)
