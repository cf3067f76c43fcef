#!/usr/bin/env python3
"""example consumer in Python: counts the producer's messages and the gaps in their numbering,
takes notes on an event port (held while not running) and, once a second, pulls the newest
counter from the channel's Mailbox, as a component that only needs the latest value does."""
import marie


class Consumer(marie.Component):
    kind = "example-consumer-py"
    ports = [marie.In("in", "marie.counter_t", channel="EXAMPLE"),
             marie.In("notes", "marie.event_t", marie.EVENT, channel="EXAMPLE_NOTES"),
             marie.In("latest", "marie.counter_t", marie.PULL, channel="EXAMPLE")]

    def on_init(self):
        self.last = 0
        self.port("in").on_message(self.on_counter)
        self.port("notes").on_message(lambda msg, info: self.count("notes"))
        self.every(1.0, self.pull_latest)

    def on_counter(self, msg, info):
        self.count("received")
        if self.last and msg.value > self.last + 1:
            self.count("gaps", msg.value - self.last - 1)
        self.last = msg.value

    def pull_latest(self, overruns):
        def done(status, msg, age_us):
            self.count("pulled" if status == "ok" else "pull_" + status)
        self.port("latest").pull_async(200, done)


if __name__ == "__main__":
    raise SystemExit(marie.main(Consumer))
