#!/usr/bin/env python3
"""shm_burst: a Python component for test_python_shm.sh. It publishes images on a channel the
system file puts on shared memory (SHM_A) and one on the fast path (LOC_A), where C Splitters
read them and forward them to SHM_B and LOC_B through their rings; it reads those back. A burst
of BURST images goes out on each path; it prints, per path, how many came back and how many
were byte for byte what it sent, and quits. An image larger than the channels' max_size is
refused and counted, as a C port's is."""
import sys

import marie

BURST = 24
SIZE = 100_000              # two LCM fragments each


class Burst(marie.Component):
    kind = "shm-burst-py"
    ports = [marie.Out("shm_out", "marie.image_t", channel="SHM_A"),
             marie.In("shm_in", "marie.image_t", channel="SHM_B"),
             marie.Out("local_out", "marie.image_t", channel="LOC_A"),
             marie.In("local_in", "marie.image_t", channel="LOC_B")]

    def on_init(self):
        self.sent = {"shm": {}, "local": {}}
        self.got = {"shm": [], "local": []}
        for path in self.got:
            self.port(path + "_in").on_message(lambda msg, info, path=path: self.got[path].append(info.raw))

    def image(self, path, k, size=SIZE):
        data = bytes((i * 7 + k * 13 + (path == "local")) & 0xFF for i in range(256)) * (size // 256)
        m = self.port(path + "_out").new(utime=k, width=len(data), height=1, row_stride=len(data),
                                         format=0, size=len(data), data=data)
        self.sent[path][k] = m.encode()
        return m

    def on_start(self):
        self.after(1.0, lambda: self.send("shm", 1, BURST + 1))
        self.after(2.0, lambda: self.send("local", 1, BURST + 1))
        self.after(2.5, lambda: self.port("shm_out").publish(self.image("shm", 0, 250_000)))
        self.after(3.5, self.report)

    def send(self, path, first, end):
        for k in range(first, end):
            self.port(path + "_out").publish(self.image(path, k))

    def report(self):
        for path, got in self.got.items():
            burst = {self.sent[path][k] for k in range(1, BURST + 1)}
            exact = len({bytes(raw) for raw in got} & burst)
            print("%s burst %d received %d exact %d" % (path, BURST, len(got), exact))
        print("publish_too_big %d" % self.counter("publish_too_big"))
        sys.stdout.flush()
        self.command(8)


if __name__ == "__main__":
    raise SystemExit(marie.main(Burst))
