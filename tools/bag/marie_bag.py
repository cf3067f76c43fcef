#!/usr/bin/env python3
"""marie bag: LCM logs <-> ROS 2 bags (rosbag2: MCAP or sqlite3 storage, CDR messages), with the
conversions of marie-ros2 (docs/ros2.md). Runs in the venv scripts/bag-venv.sh makes.

  marie bag export LOG.lcm OUT [--map CHANNEL=TOPIC]... [--only CHANNEL]... [--storage mcap|sqlite3]
  marie bag import BAG OUT.lcm [--map TOPIC=CHANNEL]...     (BAG: a rosbag2 folder, .mcap or .db3)
  marie bag info PATH                                     (a rosbag2 bag or an LCM log)

Export writes the channels of known types that config/spartacus.yaml's `ros2:` table names (or
--map adds), plus /tf from odometry (odom -> base_link) and poses (map -> odom). Import reads
every topic of a type marie has, onto the channel the table gives it (or --map, else the topic's
name in capitals: /front/scan -> FRONT_SCAN). Exit status: 0, 1 on failure, 2 on usage.
"""
import argparse
import collections
import os
import pathlib
import shutil
import sys

import lcm
import marie
from rosbags.highlevel import AnyReader
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import StoragePlugin, Writer

import bag_conv as conv


def marie_types():
    """fingerprint -> (name, class) for every marie type."""
    out = {}
    for name in dir(marie):
        cls = getattr(marie, name)
        if isinstance(cls, type) and hasattr(cls, "_get_packed_fingerprint"):
            out[cls._get_packed_fingerprint()] = (name, cls)
    return out


def pairs(items, what):
    out = {}
    for it in items or []:
        if "=" not in it:
            sys.exit("marie bag: --map %s: expected %s" % (it, what))
        k, v = it.split("=", 1)
        out[k] = v
    return out


def qos(latched):
    never = QosTime(sec=0x7FFFFFFF, nsec=0xFFFFFFFF)
    return [Qos(history=QosHistory.KEEP_LAST, depth=1 if latched else 10, reliability=QosReliability.RELIABLE,
                durability=QosDurability.TRANSIENT_LOCAL if latched else QosDurability.VOLATILE,
                deadline=never, lifespan=never, liveliness=QosLiveliness.AUTOMATIC,
                liveliness_lease_duration=never, avoid_ros_namespace_conventions=False)]


def export(args):
    topics = dict(conv.TOPICS)
    topics.update(pairs(args.map, "CHANNEL=TOPIC"))
    if args.only:
        topics = {c: t for c, t in topics.items() if c in args.only}
    types = marie_types()
    out = pathlib.Path(args.out)
    if out.exists():
        if not args.force:
            sys.exit("marie bag: %s exists (--force replaces it)" % out)
        shutil.rmtree(out)
    storage = StoragePlugin.MCAP if args.storage == "mcap" else StoragePlugin.SQLITE3
    counts, skipped, state = collections.Counter(), collections.Counter(), {}
    with Writer(out, version=8, storage_plugin=storage) as w:
        conns = {}
        for ev in lcm.EventLog(args.log, "r"):
            if ev.channel not in topics:
                continue
            t = types.get(ev.data[:8])
            fn = t and conv.TO_ROS.get(t[0])
            if not fn:
                skipped[ev.channel] += 1
                continue
            for suffix, rtype, msg in fn(t[1].decode(ev.data), state):
                topic = suffix if suffix == "/tf" else topics[ev.channel] + (suffix or "")
                if topic not in conns:
                    conns[topic] = w.add_connection(topic, rtype, typestore=conv.TS,
                                                    offered_qos_profiles=qos(rtype == "nav_msgs/msg/OccupancyGrid"))
                w.write(conns[topic], ev.timestamp * 1000, conv.TS.serialize_cdr(msg, rtype))
                counts[topic] += 1
    for topic, n in sorted(counts.items()):
        print("%-28s %7d" % (topic, n))
    for ch, n in sorted(skipped.items()):
        print("skipped %s: %d messages of no known type" % (ch, n), file=sys.stderr)
    return 0 if counts else 1


def import_(args):
    channels = {t: c for c, t in conv.TOPICS.items()}
    channels.update(pairs(args.map, "TOPIC=CHANNEL"))
    if os.path.exists(args.out) and not args.force:
        sys.exit("marie bag: %s exists (--force replaces it)" % args.out)
    log = lcm.EventLog(args.out, "w", overwrite=True)
    counts, bad = collections.Counter(), collections.Counter()
    with AnyReader([pathlib.Path(args.bag)], default_typestore=conv.TS) as r:
        conns = [c for c in r.connections if c.msgtype in conv.FROM_ROS]
        for c, t_ns, raw in r.messages(connections=conns):
            channel = channels.get(c.topic, c.topic.strip("/").replace("/", "_").upper())
            m = conv.FROM_ROS[c.msgtype](r.deserialize(raw, c.msgtype), marie, t_ns // 1000)
            if m is None:
                bad[c.topic] += 1
                continue
            log.write_event(t_ns // 1000, channel, m.encode())
            counts[channel] += 1
    log.close()
    for ch, n in sorted(counts.items()):
        print("%-28s %7d" % (ch, n))
    for topic, n in sorted(bad.items()):
        print("refused %d messages of %s (not finite or inconsistent)" % (n, topic), file=sys.stderr)
    return 0 if counts else 1


def info(args):
    p = pathlib.Path(args.path)
    if p.is_file() and p.suffix not in (".mcap", ".db3"):
        types, rows, first, last = marie_types(), collections.Counter(), None, None
        kinds = {}
        for ev in lcm.EventLog(str(p), "r"):
            rows[ev.channel] += 1
            kinds[ev.channel] = types.get(ev.data[:8], ("?",))[0]
            first = ev.timestamp if first is None else first
            last = ev.timestamp
        print("LCM log %s: %d messages, %.1f s" % (p, sum(rows.values()), ((last or 0) - (first or 0)) / 1e6))
        for ch, n in sorted(rows.items()):
            print("  %-32s %-20s %7d%s" % (ch, kinds[ch], n, "" if kinds[ch] in conv.TO_ROS else "  (not exported)"))
        return 0
    with AnyReader([p], default_typestore=conv.TS) as r:
        print("ROS 2 bag %s: %d messages, %.1f s" % (p, r.message_count, r.duration / 1e9))
        for c in r.connections:
            print("  %-32s %-44s %7d%s" % (c.topic, c.msgtype, c.msgcount,
                                          "" if c.msgtype in conv.FROM_ROS else "  (not imported)"))
    return 0


def main():
    ap = argparse.ArgumentParser(prog="marie bag", description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    e = sub.add_parser("export", help="LCM log -> rosbag2")
    e.add_argument("log")
    e.add_argument("out")
    e.add_argument("--map", action="append", metavar="CHANNEL=TOPIC")
    e.add_argument("--only", action="append", metavar="CHANNEL")
    e.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap")
    e.add_argument("--force", action="store_true")
    i = sub.add_parser("import", help="rosbag2 (MCAP or sqlite3) -> LCM log")
    i.add_argument("bag")
    i.add_argument("out")
    i.add_argument("--map", action="append", metavar="TOPIC=CHANNEL")
    i.add_argument("--force", action="store_true")
    n = sub.add_parser("info", help="what a bag or an LCM log holds")
    n.add_argument("path")
    args = ap.parse_args()
    try:
        return {"export": export, "import": import_, "info": info}[args.cmd](args)
    except (OSError, ValueError, KeyError) as ex:
        print("marie bag: %s" % ex, file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
