"""marie: components in Python, with the contract of marie's C components (docs/python.md).

    import marie

    class Hello(marie.Component):
        kind = "hello"
        ports = [marie.Out("out", "marie.counter_t", channel="HELLO")]
        params = "hello.params.yaml"            # NAME: [TYPE, DEFAULT, HELP], as in C

        def on_init(self):
            self.every(self.params.rate_hz, self.tick)

        def tick(self, overruns):
            self.port("out").publish(self.port("out").new(name="hello", value=self.now()))

    if __name__ == "__main__":
        raise SystemExit(marie.main(Hello))
"""
from .bus import Bus, BusError
from .component import (Component, In, Out, Port, Params, Refused, PullError, main, IN, OUT, PUSH, PULL, EVENT,
                        STATES, SEV_DEBUG, SEV_INFO, SEV_WARN, SEV_ERROR)
from .types import BadMessage, find as find_type, add_path as add_types_path

__version__ = "0.1.0"
