#!/usr/bin/env python3
"""lcm_peer: the other side of the Python component tests, on upstream LCM for Python (PyPI `lcm`,
which marie did not write) and lcm-gen's classes: heartbeats heard, orders forged, malformed
payloads sent, the simulator's clock played, messages counted.

  lcm_peer.py hb NAME [SECONDS]            NAME's last heartbeat as JSON (state, counters, ...)
  lcm_peer.py forge TARGET CMD             a lifecycle order with a MAC made with another key
  lcm_peer.py malformed CHANNEL            three bad counter_t payloads: wrong type, cut, no NUL
  lcm_peer.py clock START_S STEP_S N HZ    N clock messages from START_S, STEP_S apart, HZ a second
  lcm_peer.py count CHANNEL SECONDS        how many messages CHANNEL carried meanwhile
"""
import json
import os
import select
import struct
import sys
import time

import lcm
from lcmtypes.marie import counter_t, heartbeat_t, lifecycle_command_t, sim_clock_t

STATES = ("created", "ready", "running", "paused", "failed", "exited", "degraded")


def spin(lc, seconds, done=lambda: False):
    end = time.time() + seconds
    while time.time() < end and not done():
        if select.select([lc.fileno()], [], [], 0.05)[0]:
            lc.handle()


def hb(lc, name, seconds=2.0):
    got = {}

    def on(ch, data):
        m = heartbeat_t.decode(data)
        if m.component == name:
            got["hb"] = {"state": STATES[m.state], "pid": m.pid, "reason": m.reason, "msgs_in": m.msgs_in,
                         "msgs_out": m.msgs_out, "bad_input": m.bad_input, "drops": m.drops,
                         "counters": {c.name: c.value for c in m.counters}}
    lc.subscribe("MARIE_HEARTBEAT", on)
    spin(lc, float(seconds), lambda: "hb" in got)
    print(json.dumps(got.get("hb")))
    return 0 if "hb" in got else 1


def forge(lc, target, cmd):
    o = lifecycle_command_t()
    now = int(time.time() * 1e6)
    o.utime, o.request_id, o.sender, o.target, o.command, o.seq = now, 77, "intruder", target, int(cmd), now
    o.mac = os.urandom(32)
    o.mac_len = 32
    lc.publish("MARIE_LIFECYCLE", o.encode())
    return 0


def malformed(lc, channel):
    good = counter_t()
    good.name, good.value = "x", 1
    data = good.encode()
    lc.publish(channel, b"\x01" * 8 + data[8:])            # another type's fingerprint
    lc.publish(channel, data[:-3])                          # cut short
    lc.publish(channel, data[:8] + struct.pack(">i", 2) + b"xy" + data[14:])   # a string without its NUL
    return 0


def clock(lc, start, step, n, hz):
    start_us, step_us = round(float(start) * 1e6), round(float(step) * 1e6)
    for i in range(int(n)):
        m = sim_clock_t()
        m.utime, m.speed = start_us + i * step_us, 1.0
        lc.publish("MARIE_CLOCK", m.encode())
        time.sleep(1.0 / float(hz))
    return 0


def count(lc, channel, seconds):
    n = [0]
    lc.subscribe(channel, lambda ch, data: n.__setitem__(0, n[0] + 1))
    spin(lc, float(seconds))
    print(n[0])
    return 0


if __name__ == "__main__":
    verb, args = sys.argv[1], sys.argv[2:]
    lc = lcm.LCM(os.environ.get("LCM_DEFAULT_URL", "udpm://239.255.76.67:7667?ttl=0"))
    sys.exit({"hb": hb, "forge": forge, "malformed": malformed, "clock": clock, "count": count}[verb](lc, *args))
