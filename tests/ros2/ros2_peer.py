"""ros2_peer: a ROS 2 peer that is not marie code, for marie-ros2's tests and benchmark.

DDS is the `cyclonedds` Python binding from PyPI (its own Cyclone build and its own CDR codec,
written in Python); the message layouts are rosbags' ROS 2 Humble type store (rosbags' copy of
ros2/common_interfaces), turned into DDS types under the names rmw_cyclonedds registers
(`pkg::msg::dds_::Type_`). Nothing here reads marie's field lists or IDL.
"""
import dataclasses
import os
import types

from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl import types as t
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration
from rosbags.typesys import Stores, get_typestore

STORE = get_typestore(Stores.ROS2_HUMBLE)
BASE = {"bool": bool, "byte": t.uint8, "char": t.uint8, "int8": t.int8, "uint8": t.uint8, "int16": t.int16,
        "uint16": t.uint16, "int32": t.int32, "uint32": t.uint32, "int64": t.int64, "uint64": t.uint64,
        "float32": t.float32, "float64": t.float64, "string": str}
_classes = {}


def _annot(node):
    kind, spec = node
    if kind == 1:                   # base type
        return BASE[spec[0]]
    if kind == 2:                   # a message
        return msg_class(spec)
    inner = _annot(spec[0])
    return t.array[inner, spec[1]] if kind == 3 else t.sequence[inner]


def _default(node):
    kind, spec = node
    if kind == 1:
        return (lambda: "") if spec[0] == "string" else (lambda: False) if spec[0] == "bool" else (lambda: 0)
    if kind == 2:
        return msg_class(spec)
    if kind == 3:
        d = _default(spec[0])
        return lambda: [d() for _ in range(spec[1])]
    return list


def msg_class(name):
    """The DDS type of ROS 2 message `pkg/msg/Type`, from rosbags' definition."""
    if name in _classes:
        return _classes[name]
    pkg, _, typ = name.split("/")
    fields = STORE.fielddefs[name][1]
    annots = {f: _annot(node) for f, node in fields}
    cls = types.new_class(typ + "_", (IdlStruct,), {"typename": "%s::msg::dds_::%s_" % (pkg, typ)},
                          lambda ns: ns.update({"__annotations__": annots}))
    cls = dataclasses.dataclass(cls)
    for f, node in fields:      # every field optional in the constructor, as in rclpy
        cls.__dataclass_fields__[f].default_factory = _default(node)
    cls.__init__ = _make_init(cls, fields)
    _classes[name] = cls
    return cls


def _make_init(cls, fields):
    names = [f for f, _ in fields]
    defaults = {f: _default(node) for f, node in fields}

    def init(self, **kw):
        for n in names:
            object.__setattr__(self, n, kw[n] if n in kw else defaults[n]())
    return init


QOS = {
    "sensor": Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(5)),
    "default": Qos(Policy.Reliability.Reliable(duration(seconds=1)), Policy.History.KeepLast(10)),
    "latched": Qos(Policy.Reliability.Reliable(duration(seconds=1)), Policy.History.KeepLast(1),
                   Policy.Durability.TransientLocal),
    "tf": Qos(Policy.Reliability.Reliable(duration(seconds=1)), Policy.History.KeepLast(100)),
}


class Peer:
    """One DDS participant on ROS_DOMAIN_ID, with readers and writers of ROS 2 topics."""

    def __init__(self, domain=None):
        self.dp = DomainParticipant(int(os.environ.get("ROS_DOMAIN_ID", "0")) if domain is None else domain)
        self.topics = {}

    def _topic(self, name, ros_type):
        if name not in self.topics:
            self.topics[name] = Topic(self.dp, "rt" + name, msg_class(ros_type))
        return self.topics[name]

    def reader(self, name, ros_type, qos="default"):
        return DataReader(self.dp, self._topic(name, ros_type), qos=QOS[qos])

    def writer(self, name, ros_type, qos="default"):
        return DataWriter(self.dp, self._topic(name, ros_type), qos=QOS[qos])


def yaw(q):
    import math
    return math.atan2(2 * (q.w * q.z + q.x * q.y), q.w * q.w + q.x * q.x - q.y * q.y - q.z * q.z)
