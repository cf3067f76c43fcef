#!/usr/bin/env python3
"""odometer: how far the robot has travelled, from its pose estimates, and how much of its path
is left (pulled from the PATH Mailbox once a report): a counter_t in millimetres on `distance`,
an event at every milestone. A small Python component of the robot's application."""
import math

import marie


class Odometer(marie.Component):
    kind = "odometer-py"
    ports = [marie.In("pose", "marie.pose_cov_t", channel="POSE"),
             marie.In("path", "marie.path_t", marie.PULL, channel="PATH"),
             marie.Out("distance", "marie.counter_t", channel="ODOMETER")]
    params = "odometer.params.yaml"

    def on_init(self):
        if not self.params.report_hz > 0 or not self.params.milestone_m > 0:
            raise marie.Refused("report_hz and milestone_m must be positive")
        self.last = None
        self.travelled = 0.0
        self.path_left = None
        self.port("pose").on_message(self.on_pose)
        self.every(self.params.report_hz, self.report)

    def on_param(self, name, value):
        if name == "report_hz":
            if not value > 0:
                raise marie.Refused("report_hz must be positive")
            self.every(value, self.report)

    def on_pose(self, msg, info):
        p = (msg.pose.x, msg.pose.y)
        if self.last is not None:
            step = math.hypot(p[0] - self.last[0], p[1] - self.last[1])
            if step > self.params.max_step_m:
                self.count("jumps")
            else:
                before = int(self.travelled / self.params.milestone_m)
                self.travelled += step
                if int(self.travelled / self.params.milestone_m) > before:
                    self.event(marie.SEV_INFO, "milestone", "%.0f m travelled" % self.travelled)
        self.last = p

    def report(self, overruns):
        out = self.port("distance")
        out.publish(out.new(name="travelled_mm", value=int(self.travelled * 1000)))
        self.port("path").pull_async(100, self.on_path)

    def on_path(self, status, msg, age_us):
        if status != "ok" or self.last is None:
            return
        left, at = 0.0, self.last
        for q in msg.poses:
            left += math.hypot(q.x - at[0], q.y - at[1])
            at = (q.x, q.y)
        self.path_left = left
        out = self.port("distance")
        out.publish(out.new(name="path_left_mm", value=int(left * 1000)))


if __name__ == "__main__":
    raise SystemExit(marie.main(Odometer))
