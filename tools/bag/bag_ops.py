"""bag_ops: what `marie bag` does (marie_bag.py reads the command line first, so that --help and
--version answer before rosbags and numpy load). Every LCM payload is checked with the rules of
marie's checked decode (python/marie/types.py) before it is decoded; a malformed one is counted and
reported, never exported."""
import collections
import os
import pathlib
import re
import shutil
import sys

import lcm
from lcmtypes import marie as mt
from marie import types
from rosbags.highlevel import AnyReader
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import StoragePlugin, Writer

import bag_conv as conv
from bag_custom import Carrier, Unsupported, ros_name


def load_types(dirs):
    """{packed fingerprint: MessageType} for marie's types and the users' (MARIE_TYPES_PATH, --types)."""
    for d in os.environ.get("MARIE_TYPES_PATH", "").split(":") + list(dirs or []):
        if d:
            types.add_path(d)
    return {t.packed_fp: t for t in types.known().values()}


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


def converter(t):
    """bag_conv's conversion of a marie type, or None (then it is carried as a custom message)."""
    pkg, _, short = t.name.rpartition(".")
    return conv.TO_ROS.get(short) if pkg == "marie" else None


def default_topic(channel):
    return "/" + re.sub(r"[^a-z0-9_]", "_", channel.lower()).strip("_")


class Export:
    """One export: the messages of a log turned into ROS 2 messages, with what was left out."""

    def __init__(self, args):
        self.types = load_types(args.types)
        self.topics = dict(conv.TOPICS)
        self.topics.update(pairs(args.map, "CHANNEL=TOPIC"))
        self.all, self.only = args.all, args.only
        self.custom = Carrier(conv.TS, types.find)
        self.counts, self.rtypes, self.state = collections.Counter(), {}, {}
        self.unknown, self.bad, self.untabled = collections.Counter(), collections.Counter(), collections.Counter()
        self.uncarried, self.unsupported = collections.Counter(), {}

    def topic(self, channel):
        if self.only and channel not in self.only:
            return None
        return self.topics.get(channel) or (default_topic(channel) if self.all else None)

    def convert(self, channel, data):
        """[(topic, ROS 2 type, message)] for one LCM message, counting what is left out."""
        t = self.types.get(data[:8])
        topic = self.topic(channel)
        if t is None:
            if topic:
                self.unknown[channel] += 1
            return []
        if not topic:
            self.untabled[(channel, t.name)] += 1
            return []
        try:
            m = t.decode(data, finite=False)     # well-formed; NaN is a value a bag carries
        except types.BadMessage:
            self.bad[(channel, t.name)] += 1
            return []
        fn = converter(t)
        if fn:
            return [("/tf" if s == "/tf" else topic + (s or ""), rt, msg) for s, rt, msg in fn(m, self.state)]
        try:
            rtype = self.custom.register(t)
        except Unsupported as ex:
            self.unsupported[t.name] = str(ex)
            self.uncarried[(channel, t.name)] += 1
            return []
        return [(topic, rtype, self.custom.to_ros(t, m))]

    def report(self):
        for topic, n in sorted(self.counts.items()):
            print("%-28s %-44s %7d" % (topic, self.rtypes[topic], n))
        for (ch, name), n in sorted(self.bad.items()):
            print("refused %s: %d malformed %s messages" % (ch, n, name), file=sys.stderr)
        for ch, n in sorted(self.unknown.items()):
            print("skipped %s: %d messages of no type marie can carry (no descriptors for their fingerprint: "
                  "MARIE_TYPES_PATH or --types)" % (ch, n), file=sys.stderr)
        for (ch, name), n in sorted(self.uncarried.items()):
            print("skipped %s: %d %s messages: %s" % (ch, n, name, self.unsupported[name]), file=sys.stderr)
        if self.untabled:
            print("not exported (no topic: --map CHANNEL=TOPIC or --all): " + ", ".join(
                "%s (%s) %d" % (ch, name, n) for (ch, name), n in sorted(self.untabled.items())), file=sys.stderr)


def export(args):
    out = pathlib.Path(args.out)
    if out.exists():
        if not args.force:
            sys.exit("marie bag: %s exists (--force replaces it)" % out)
        shutil.rmtree(out)
    ex = Export(args)
    storage = StoragePlugin.MCAP if args.storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(out, version=8, storage_plugin=storage) as w:
        conns = {}
        for ev in lcm.EventLog(args.log, "r"):
            for topic, rtype, msg in ex.convert(ev.channel, ev.data):
                if topic not in conns:
                    conns[topic] = w.add_connection(topic, rtype, typestore=conv.TS,
                                                    offered_qos_profiles=qos(rtype == "nav_msgs/msg/OccupancyGrid"))
                    ex.rtypes[topic] = rtype
                w.write(conns[topic], ev.timestamp * 1000, conv.TS.serialize_cdr(msg, rtype))
                ex.counts[topic] += 1
    ex.report()
    return 0 if ex.counts else 1


def import_(args):
    channels = {t: c for c, t in conv.TOPICS.items()}
    channels.update(pairs(args.map, "TOPIC=CHANNEL"))
    if os.path.exists(args.out) and not args.force:
        sys.exit("marie bag: %s exists (--force replaces it)" % args.out)
    custom_types = {ros_name(t.name): t for t in load_types(args.types).values() if not converter(t)}
    custom = Carrier(conv.TS, types.find)
    log = lcm.EventLog(args.out, "w", overwrite=True)
    counts, bad = collections.Counter(), collections.Counter()
    with AnyReader([pathlib.Path(args.bag)], default_typestore=conv.TS) as r:
        conns = [c for c in r.connections if c.msgtype in conv.FROM_ROS or c.msgtype in custom_types]
        for c, t_ns, raw in r.messages(connections=conns):
            channel = channels.get(c.topic, c.topic.strip("/").replace("/", "_").upper())
            data = from_ros(r.deserialize(raw, c.msgtype), c.msgtype, custom, custom_types, t_ns // 1000)
            if data is None:
                bad[c.topic] += 1
                continue
            log.write_event(t_ns // 1000, channel, data)
            counts[channel] += 1
    log.close()
    for ch, n in sorted(counts.items()):
        print("%-28s %7d" % (ch, n))
    for topic, n in sorted(bad.items()):
        print("refused %d messages of %s (not finite, inconsistent, or not of marie's definition)" % (n, topic),
              file=sys.stderr)
    return 0 if counts else 1


def from_ros(msg, rtype, custom, custom_types, utime):
    """An LCM payload from a ROS 2 message, or None when it cannot be one."""
    if rtype in conv.FROM_ROS:
        m = conv.FROM_ROS[rtype](msg, mt, utime)
        return m.encode() if m is not None else None
    t = custom_types[rtype]
    try:
        data = custom.from_ros(t, msg).encode()
        t.check(data, finite=False)
    except (AttributeError, TypeError, ValueError, IndexError, types.BadMessage):
        return None
    return data


def info(args):
    p = pathlib.Path(args.path)
    if p.is_file() and p.suffix not in (".mcap", ".db3"):
        return info_log(p, args)
    custom = {ros_name(t.name) for t in load_types(args.types).values()}
    with AnyReader([p], default_typestore=conv.TS) as r:
        print("ROS 2 bag %s: %d messages, %.1f s" % (p, r.message_count, r.duration / 1e9))
        for c in r.connections:
            known = c.msgtype in conv.FROM_ROS or c.msgtype in custom
            print("  %-32s %-44s %7d%s" % (c.topic, c.msgtype, c.msgcount, "" if known else "  (not imported)"))
    return 0


def info_log(p, args):
    known, rows, kinds, first, last = load_types(args.types), collections.Counter(), {}, None, None
    custom = Carrier(conv.TS, types.find)
    for ev in lcm.EventLog(str(p), "r"):
        rows[ev.channel] += 1
        kinds[ev.channel] = known.get(ev.data[:8])
        first = ev.timestamp if first is None else first
        last = ev.timestamp
    print("LCM log %s: %d messages, %.1f s" % (p, sum(rows.values()), ((last or 0) - (first or 0)) / 1e6))
    for ch, n in sorted(rows.items()):
        t = kinds[ch]
        if t is None:
            note = "  (not exported: no descriptors for its type)"
        elif converter(t):
            note = "" if ch in conv.TOPICS else "  (exported with --map or --all)"
        else:
            note = "  (exported as custom %s with --map or --all)" % ros_name(t.name)
            try:
                custom.register(t)
            except Unsupported as ex:
                note = "  (not exported: %s)" % ex
        print("  %-32s %-24s %7d%s" % (ch, t.name if t else "?", n, note))
    return 0
