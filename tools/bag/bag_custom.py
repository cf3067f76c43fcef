"""bag_custom: LCM types with no ROS 2 counterpart (a user's, or one of marie's without a conversion
in bag_conv) carried through a bag as custom ROS 2 messages, field for field (docs/ros2.md). The LCM
type PKG.NAME_t is the ROS 2 message PKG_msgs/msg/Name; its definition goes into the bag, so any
rosbag2 reader (rosbags, Foxglove, ros2 bag with the package built from it) decodes it without
marie, and `marie bag import` turns it back into the same LCM payload."""
import re

import numpy as np
from rosbags.typesys import TypesysError, get_types_from_msg

PRIM = {"int8_t": "int8", "int16_t": "int16", "int32_t": "int32", "int64_t": "int64", "byte": "uint8",
        "boolean": "bool", "float": "float32", "double": "float64", "string": "string"}
NUMPY = {"int8": np.int8, "int16": np.int16, "int32": np.int32, "int64": np.int64, "uint8": np.uint8,
         "bool": np.bool_, "float32": np.float32, "float64": np.float64}
# ROS 2's rule for field names (rosidl): lower case, digits and single underscores, a letter first.
FIELD = re.compile(r"^[a-z](?:[a-z0-9]|_(?!_))*(?<!_)$")


class Unsupported(Exception):
    """A type that has no faithful ROS 2 message; the text says why."""


def ros_name(lcm_name):
    """'ux.reading_t' -> 'ux_msgs/msg/Reading', 'marie.pose2d_t' -> 'marie_msgs/msg/Pose2d'."""
    pkg, _, short = lcm_name.rpartition(".")
    base = short[:-2] if short.endswith("_t") else short
    return "%s_msgs/msg/%s" % (pkg or "lcm", "".join(w[:1].upper() + w[1:] for w in base.split("_") if w))


class Carrier:
    """The custom messages of one export or import, registered in the typestore ts; find(name) is
    marie.types.find (the descriptors of marie's and the users' types)."""

    def __init__(self, ts, find):
        self.ts, self.find, self.done = ts, find, {}

    def register(self, t):
        """t's ROS 2 type name, registered with the types it contains; Unsupported says why not."""
        name = ros_name(t.name)
        if name in self.done:
            if self.done[name] is not t:
                raise Unsupported("%s and %s would both be %s" % (self.done[name].name, t.name, name))
            return name
        lines = []
        for fname, prim, sub, dims in t.fields:
            if not FIELD.match(fname):
                raise Unsupported("%s.%s is not a ROS 2 field name (lower case, a letter first)" % (t.name, fname))
            if len(dims) > 1:
                raise Unsupported("%s.%s is an array of arrays, which ROS 2 messages do not have" % (t.name, fname))
            rtype = self.register(self.find(sub)).replace("/msg/", "/") if prim == "struct" else PRIM[prim]
            size, lenfield = dims[0] if dims else (None, None)
            lines.append("%s%s %s" % (rtype, "" if not dims else "[]" if lenfield is not None else "[%d]" % size, fname))
        try:
            self.ts.register(get_types_from_msg("\n".join(lines) + "\n", name))
        except TypesysError as ex:
            raise Unsupported("%s: %s" % (name, ex)) from None
        self.done[name] = t
        return name

    def to_ros(self, t, m):
        """The ROS 2 message of LCM message m of type t (registered)."""
        kw = {}
        for fname, prim, sub, dims in t.fields:
            v = getattr(m, fname)
            if prim == "struct":
                st = self.find(sub)
                v = [self.to_ros(st, x) for x in v] if dims else self.to_ros(st, v)
            elif dims and prim == "byte":
                v = np.frombuffer(bytes(v), dtype=np.uint8)
            elif dims and prim != "string":
                v = np.array(v, dtype=NUMPY[PRIM[prim]])
            elif dims:
                v = list(v)
            elif prim == "boolean":
                v = bool(v)
            kw[fname] = v
        return self.ts.types[ros_name(t.name)](**kw)

    def from_ros(self, t, r):
        """The LCM message of type t from its ROS 2 message r."""
        m = t.cls()
        for fname, prim, sub, dims in t.fields:
            v = getattr(r, fname)
            if prim == "struct":
                st = self.find(sub)
                v = [self.from_ros(st, x) for x in v] if dims else self.from_ros(st, v)
            elif prim == "byte" and dims:
                v = bytes(bytearray(np.asarray(v, dtype=np.uint8)))
            elif dims:
                v = [_scalar(prim, x) for x in v]
            else:
                v = _scalar(prim, v)
            setattr(m, fname, v)
        return m


def _scalar(prim, v):
    if prim in ("float", "double"):
        return float(v)
    if prim == "boolean":
        return bool(v)
    if prim == "string":
        return str(v)
    return int(v)
