#!/usr/bin/env python3
"""bench_python: a 64-byte message one way through a Python component's ports (python/marie: its
bus, the payload check, lcm-gen's decoder, the handler) against upstream LCM for Python's raw
publish and subscribe with lcm-gen's decoder, in the same process and run, blocks interleaved.

One way: from publish to the subscriber's handler, through the kernel's multicast loopback; the
sender and the receiver share the process (and so the clock), as in bench_ports' raw baseline.
Rows as bench/bench.h's bench_row() prints them: bench metric value unit baseline ratio."""
import os
import select
import statistics
import sys
import time

import lcm

import marie
from lcmtypes.marie import counter_t

BLOCKS, PER_BLOCK, WARMUP = 20, 200, 200
URL = os.environ.get("LCM_DEFAULT_URL", "udpm://239.255.76.67:7667?ttl=0")


def row(metric, value, unit, baseline):
    if baseline and baseline > 0:
        print("bench_python\t%s\t%.6g\t%s\t%.6g\t%.3f" % (metric, value, unit, baseline, value / baseline))
    else:
        print("bench_python\t%s\t%.6g\t%s\t-\t-" % (metric, value, unit))
    sys.stdout.flush()


class Loopback(marie.Component):
    kind = "bench-python"
    ports = [marie.Out("out", "marie.counter_t", channel="BENCH_PY"),
             marie.In("in", "marie.counter_t", channel="BENCH_PY")]


def message():
    m = counter_t()
    m.name = "x" * 43            # 8 fingerprint + 4 + 44 string + 8 value = 64 bytes
    return m


def raw_block(lc, n, out):
    got = []
    m = message()
    sub = lc.subscribe("BENCH_RAW", lambda ch, data: got.append(counter_t.decode(data)))
    fd = lc.fileno()
    for _ in range(n):
        del got[:]
        t0 = time.perf_counter_ns()
        m.value = t0
        lc.publish("BENCH_RAW", m.encode())
        while not got:
            select.select([fd], [], [], 1.0)
            lc.handle()
        out.append(time.perf_counter_ns() - t0)
    lc.unsubscribe(sub)


def marie_block(c, n, out):
    got = []
    c.port("in").on_message(lambda msg, info: got.append(msg))
    p = c.port("out")
    m = p.new(name="x" * 43)
    bus = c.bus
    fd = bus.fileno()
    for _ in range(n):
        del got[:]
        t0 = time.perf_counter_ns()
        m.value = t0
        p.publish(m)
        while not got:
            select.select([fd], [], [], 1.0)
            bus.handle()
        out.append(time.perf_counter_ns() - t0)


def main():
    lc = lcm.LCM(URL)
    c = Loopback(["--url", URL, "--name", "bench-python"])
    c.command(1)
    c.command(2)
    assert len(message().encode()) == 64
    raw, mar = [], []
    raw_block(lc, WARMUP, [])
    marie_block(c, WARMUP, [])
    for _ in range(BLOCKS):
        raw_block(lc, PER_BLOCK, raw)
        marie_block(c, PER_BLOCK, mar)
    for name, q in (("p50", 0.5), ("p90", 0.9)):
        r = statistics.quantiles(raw, n=100)[int(q * 100) - 1] / 1000
        m = statistics.quantiles(mar, n=100)[int(q * 100) - 1] / 1000
        row("oneway_64B_%s_python_port" % name, m, "us", r)
        row("oneway_64B_%s_pip_lcm_raw" % name, r, "us", 0)
    bad = c.bad_inputs
    row("python_port_bad_input", bad, "count", 0)
    return 0 if bad == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
