"""bag_roundtrip: witnesses for tests/tools/test_marie_bag.sh, on rosbags (not marie code) and
upstream LCM's Python log reader.
  bag_roundtrip.py readback BAG LOG        rosbags reads every message of marie's bag; counts and
                                           scans agree with the log
  bag_roundtrip.py same LOG BACK           BACK (export then import) holds LOG's messages
  bag_roundtrip.py write LOG BAG           rosbags' own Writer makes a sqlite3 bag of LOG's
                                           /scan, /odom and /clock (its own conversion, below)
Prints what it found; exit status 0 when it agrees.
"""
import collections
import math
import pathlib
import sys

import lcm
import marie
import numpy as np
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

TS = get_typestore(Stores.ROS2_HUMBLE)
CARRIED = {"LASER": ("/scan", "laser_scan_t"), "ODOMETRY": ("/odom", "odometry_t"),
           "POSE": ("/amcl_pose", "pose_cov_t"), "PATH": ("/plan", "path_t"),
           "MOTOR_COMMAND": ("/marie/motor_command", "motor_command_t"), "ESTOP": ("/estop", "estop_t"),
           "CAMERA_IMAGE": ("/camera/image_raw", "image_t"), "MARIE_CLOCK": ("/clock", "sim_clock_t")}
# What a ROS 2 message has no field for (docs/ros2.md, "What a conversion keeps").
LOST = {"odometry_t": {"distance"}, "path_t": {"goal_id", "status"}, "motor_command_t": {"utime", "source"},
        "estop_t": {"utime", "source"}, "sim_clock_t": {"speed"}}
ANGLES = {"theta"}


def events(path):
    return list(lcm.EventLog(path, "r"))


def readback(bag, log):
    want = collections.Counter(e.channel for e in events(log))
    got, scans_ok, n_inf = collections.Counter(), True, 0
    with AnyReader([pathlib.Path(bag)], default_typestore=TS) as r:
        for c, t, raw in r.messages():
            m = r.deserialize(raw, c.msgtype)
            got[c.topic] += 1
            if c.msgtype == "sensor_msgs/msg/LaserScan":
                rng = np.asarray(m.ranges)
                n_inf += int(np.isinf(rng).sum())
                scans_ok &= bool(np.all(np.isinf(rng) | ((rng >= m.range_min) & (rng < m.range_max))))
                scans_ok &= m.header.frame_id == "laser" and len(rng) == 181
    ok = True
    for ch, (topic, _) in CARRIED.items():
        print("%-14s log %6d  bag %-22s %6d" % (ch, want[ch], topic, got[topic]))
        ok &= want[ch] == got[topic]
    print("tf %d (odometry %d + poses %d), scans in limits or +inf: %s (%d beams +inf)" %
          (got["/tf"], want["ODOMETRY"], want["POSE"], scans_ok, n_inf))
    ok &= scans_ok and got["/tf"] >= want["ODOMETRY"]
    return ok


def fields(msg, lost, prefix=""):
    out = {}
    for name in msg.__slots__:
        if name in lost:
            continue
        v = getattr(msg, name)
        if hasattr(v, "__slots__"):
            out.update(fields(v, set(), prefix + name + "."))
        elif isinstance(v, (list, tuple)) and v and hasattr(v[0], "__slots__"):
            for i, x in enumerate(v):
                out.update(fields(x, set(), "%s%s[%d]." % (prefix, name, i)))
        else:
            out[prefix + name] = v
    return out


def equal(a, b, key):
    if key.split(".")[-1].split("[")[0] in ANGLES:
        return abs(math.remainder(a - b, 2 * math.pi)) < 1e-9
    if isinstance(a, float) and isinstance(b, float):
        return a == b or (math.isnan(a) and math.isnan(b))
    return list(a) == list(b) if isinstance(a, (list, tuple, bytes)) else a == b


def same(log, back):
    a = collections.defaultdict(list)
    b = collections.defaultdict(list)
    for e in events(log):
        if e.channel in CARRIED:
            a[e.channel].append(e)
    for e in events(back):
        b[e.channel].append(e)
    ok = True
    for ch, (_, tname) in CARRIED.items():
        # a bag is in time order; a log is in arrival order, which a recorder's clock may not follow
        a[ch].sort(key=lambda e: e.timestamp)
        cls = getattr(marie, tname)
        diff = 0
        if len(a[ch]) != len(b[ch]):
            diff = -1
        else:
            for x, y in zip(a[ch], b[ch]):
                fx, fy = fields(cls.decode(x.data), LOST.get(tname, set())), fields(cls.decode(y.data), LOST.get(tname, set()))
                if x.timestamp != y.timestamp or fx.keys() != fy.keys() or \
                        not all(equal(fx[k], fy[k], k) for k in fx):
                    diff += 1
        print("%-14s %6d messages, %s" % (ch, len(a[ch]), "same" if diff == 0 else
                                          "count differs (%d back)" % len(b[ch]) if diff < 0 else "%d differ" % diff))
        ok &= diff == 0 and len(a[ch]) > 0
    return ok


def write(log, bag):
    """A bag written by rosbags itself: LASER, ODOMETRY and MARIE_CLOCK as ROS 2 messages."""
    M = TS.types
    stamp = lambda u: M["builtin_interfaces/msg/Time"](sec=u // 1000000, nanosec=u % 1000000 * 1000)
    hdr = lambda u, f: M["std_msgs/msg/Header"](stamp=stamp(u), frame_id=f)
    vec = lambda x=0.0, z=0.0: M["geometry_msgs/msg/Vector3"](x=x, y=0.0, z=z)
    n = 0
    with Writer(pathlib.Path(bag), version=8, storage_plugin=StoragePlugin.SQLITE3) as w:
        con = {"/scan": w.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=TS),
               "/odom": w.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=TS),
               "/clock": w.add_connection("/clock", "rosgraph_msgs/msg/Clock", typestore=TS)}
        for e in events(log):
            if e.channel == "LASER":
                s = marie.laser_scan_t.decode(e.data)
                r = np.array(s.ranges, dtype=np.float32)
                r[r >= s.range_max] = np.nan        # "no return" the other way REP 117 allows
                msg, topic = M["sensor_msgs/msg/LaserScan"](
                    header=hdr(s.utime, "laser"), angle_min=s.angle_min,
                    angle_max=s.angle_min + s.angle_increment * (len(r) - 1), angle_increment=s.angle_increment,
                    time_increment=0.0, scan_time=0.1, range_min=s.range_min, range_max=s.range_max, ranges=r,
                    intensities=np.array([], dtype=np.float32)), "/scan"
            elif e.channel == "ODOMETRY":
                o = marie.odometry_t.decode(e.data)
                q = M["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(o.pose.theta / 2), w=math.cos(o.pose.theta / 2))
                pose = M["geometry_msgs/msg/Pose"](position=M["geometry_msgs/msg/Point"](x=o.pose.x, y=o.pose.y, z=0.0),
                                                   orientation=q)
                msg, topic = M["nav_msgs/msg/Odometry"](
                    header=hdr(o.utime, "odom"), child_frame_id="base_link",
                    pose=M["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
                    twist=M["geometry_msgs/msg/TwistWithCovariance"](
                        twist=M["geometry_msgs/msg/Twist"](linear=vec(o.v), angular=vec(z=o.omega)),
                        covariance=np.zeros(36))), "/odom"
            elif e.channel == "MARIE_CLOCK":
                msg, topic = M["rosgraph_msgs/msg/Clock"](clock=stamp(marie.sim_clock_t.decode(e.data).utime)), "/clock"
            else:
                continue
            w.write(con[topic], e.timestamp * 1000, TS.serialize_cdr(msg, msg.__msgtype__))
            n += 1
    print("rosbags wrote %d messages to %s" % (n, bag))
    return n > 0


if __name__ == "__main__":
    cmd = sys.argv[1]
    fn = {"readback": readback, "same": same, "write": write}[cmd]
    sys.exit(0 if fn(*sys.argv[2:]) else 1)
