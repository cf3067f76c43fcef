#!/usr/bin/env python3
"""example producer in Python: publishes a numbered counter_t at a fixed rate, as
marie-example-producer does in C."""
import marie


class Producer(marie.Component):
    kind = "example-producer-py"
    ports = [marie.Out("out", "marie.counter_t", channel="EXAMPLE")]
    params = "producer.params.yaml"

    def on_init(self):
        if not 0 < self.params.rate_hz <= 10000:
            raise marie.Refused("rate_hz must be in (0, 10000]")
        self.seq = 0
        self.every(self.params.rate_hz, self.tick)

    def on_param(self, name, value):
        if name == "rate_hz":
            if not 0 < value <= 10000:
                raise marie.Refused("rate_hz must be in (0, 10000]")
            self.every(value, self.tick)

    def tick(self, overruns):
        self.seq += 1
        out = self.port("out")
        out.publish(out.new(name=self.params.label, value=self.seq))


if __name__ == "__main__":
    raise SystemExit(marie.main(Producer))
