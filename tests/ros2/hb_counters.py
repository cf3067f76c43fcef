"""hb_counters: the last heartbeat counters of a component in an LCM log, as NAME=VALUE lines
(upstream LCM's Python log reader and marie's types from lcm-gen --python).
  hb_counters.py LOG COMPONENT [CHANNEL_COUNTS...]
"""
import sys

import lcm
from marie import heartbeat_t

log, name = sys.argv[1], sys.argv[2]
counts = {c: 0 for c in sys.argv[3:]}
last = None
for ev in lcm.EventLog(log, "r"):
    if ev.channel in counts:
        counts[ev.channel] += 1
    if ev.channel == "MARIE_HEARTBEAT":
        hb = heartbeat_t.decode(ev.data)
        if hb.component == name:
            last = hb
if last:
    print("state=%d" % last.state)
    print("bad_input=%d" % last.bad_input)
    for c in last.counters:
        print("%s=%d" % (c.name, c.value))
for c, n in counts.items():
    print("channel_%s=%d" % (c, n))
