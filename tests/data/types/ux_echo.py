#!/usr/bin/env python3
"""ux_echo: a user's Python component on a user's type (tests/tools/test_user_types.sh): every
ux.reading_t heard on `in` goes out again on `out` with its value doubled."""
import marie


class Echo(marie.Component):
    kind = "ux-echo"
    ports = [marie.In("in", "ux.reading_t", channel="READING"),
             marie.Out("out", "ux.reading_t", channel="READING_ECHO")]

    def on_init(self):
        self.port("in").on_message(self.on_reading)

    def on_reading(self, msg, info):
        self.count("received")
        msg.value *= 2
        self.port("out").publish(msg)


if __name__ == "__main__":
    raise SystemExit(marie.main(Echo))
