#!/usr/bin/env python3
"""livelock_worlds: the pillar trap of tests/nav/test_livelock.sh, written into a directory.

pillars: a 10 x 6 m hall with two pillars across the straight line y = 3 at x 5.0-5.4, 0.3 m
apart (too narrow for the robot); box: the same hall without them, the planner's stale map.
"""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "sim"))
from mkworld import Grid  # noqa: E402

out = sys.argv[1]
for name, pillars in (("pillars", True), ("box", False)):
    g = Grid(10.0, 6.0, 0.05)
    g.border(0.1)
    if pillars:
        g.rect(5.0, 2.35, 5.4, 2.85)
        g.rect(5.0, 3.15, 5.4, 3.65)
    g.write(out, name, "livelock test hall" + (" with two pillars" if pillars else ""))
