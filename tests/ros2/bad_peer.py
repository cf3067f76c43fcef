"""bad_peer: a ROS 2 peer that feeds marie-ros2 bad input (tests/ros2/test_ros2_bad_input.sh),
then one good /cmd_vel. Types under the ROS 2 names with other layouts are declared here, as a
careless or hostile node would.
  bad_peer.py
"""
import dataclasses
import math
import time
import types

import ros2_peer as rp
from cyclonedds.idl import IdlStruct
from cyclonedds.idl import types as t
from cyclonedds.pub import DataWriter
from cyclonedds.topic import Topic


def struct(typename, **annots):
    cls = types.new_class("X", (IdlStruct,), {"typename": typename}, lambda ns: ns.update({"__annotations__": annots}))
    return dataclasses.dataclass(cls)


p = rp.Peer()
Twist, Vec = rp.msg_class("geometry_msgs/msg/Twist"), rp.msg_class("geometry_msgs/msg/Vector3")
good = p.writer("/cmd_vel", "geometry_msgs/msg/Twist")
goal = p.writer("/goal_pose", "geometry_msgs/msg/PoseStamped")
# Malformed CDR: 4 bytes under the name of a 48-byte Twist, on /cmd_vel (another participant, as
# another node would be).
p2 = rp.Peer()
Short = struct("geometry_msgs::msg::dds_::Twist_", a=t.int32)
short = DataWriter(p2.dp, Topic(p2.dp, "rt/cmd_vel", Short), qos=rp.QOS["default"])
# A lying sequence length: a LaserScan that announces a million ranges and carries none.
Lying = struct("sensor_msgs::msg::dds_::LaserScan_", sec=t.int32, nanosec=t.uint32, frame=str,
               f0=t.float32, f1=t.float32, f2=t.float32, f3=t.float32, f4=t.float32, f5=t.float32, f6=t.float32,
               nranges=t.uint32)
lying = DataWriter(p.dp, Topic(p.dp, "rt/scan_in", Lying), qos=rp.QOS["sensor"])
# A wrong type under a known name: TwistStamped on /cmd_vel (what ROS 2 Jazzy's teleop can send).
TS = rp.msg_class("geometry_msgs/msg/TwistStamped")
p3 = rp.Peer()
wrong = DataWriter(p3.dp, Topic(p3.dp, "rt/cmd_vel", TS), qos=rp.QOS["default"])
time.sleep(2.0)     # discovery

for _ in range(3):
    good.write(Twist(linear=Vec(x=float("nan"))))                  # NaN
    good.write(Twist(angular=Vec(z=math.inf)))                     # infinity
    g = rp.msg_class("geometry_msgs/msg/PoseStamped")()
    g.header.frame_id = "odom"                                     # a goal not in the map frame
    g.pose.orientation.w = 1.0
    goal.write(g)
    short.write(Short(a=7))
    lying.write(Lying(sec=1, nanosec=0, frame="laser", f0=0, f1=0, f2=0, f3=0, f4=0, f5=0, f6=0, nranges=1000000))
    wrong.write(TS())
    time.sleep(0.1)
time.sleep(0.5)
good.write(Twist(linear=Vec(x=0.25)))
time.sleep(1.5)
print("sent", flush=True)
