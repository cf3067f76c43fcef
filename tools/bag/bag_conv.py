"""bag_conv: marie's messages <-> ROS 2's, as marie-ros2 converts them (adapters/ros2/ros2_conv.c,
docs/ros2.md): REP 103 units and frames, REP 105's map -> odom -> base_link, a laser's "nothing
seen" (a range at range_max) as +inf. The ROS 2 types are rosbags' (its ROS 2 Humble store)."""
import math

import numpy as np
from rosbags.typesys import Stores, get_typestore

TS = get_typestore(Stores.ROS2_HUMBLE)
M = TS.types

# Channels and topics as config/spartacus.yaml's `ros2:` table has them.
TOPICS = {
    "LASER": "/scan", "ODOMETRY": "/odom", "POSE": "/amcl_pose", "MAP": "/map", "PATH": "/plan",
    "MOTOR_COMMAND": "/marie/motor_command", "TELEOP": "/cmd_vel", "ESTOP": "/estop",
    "CAMERA_IMAGE": "/camera/image_raw", "MARIE_CLOCK": "/clock", "MARIE_HEARTBEAT": "/diagnostics",
}
FRAMES = {"map": "map", "odom": "odom", "base": "base_link", "laser": "laser", "camera": "camera"}


def time_of(utime):
    sec, usec = divmod(int(utime), 1000000)
    return M["builtin_interfaces/msg/Time"](sec=sec, nanosec=usec * 1000)


def utime_of(t, fallback):
    u = t.sec * 1000000 + t.nanosec // 1000
    return u if u > 0 else fallback


def header(utime, frame):
    return M["std_msgs/msg/Header"](stamp=time_of(utime), frame_id=frame)


def quat(yaw):
    return M["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))


def yaw_of(q):
    return math.atan2(2 * (q.w * q.z + q.x * q.y), q.w * q.w + q.x * q.x - q.y * q.y - q.z * q.z)


def pose(p):
    return M["geometry_msgs/msg/Pose"](position=M["geometry_msgs/msg/Point"](x=p.x, y=p.y, z=0.0),
                                       orientation=quat(p.theta))


def pose2d(ros_pose, marie):
    p = marie.pose2d_t()
    p.x, p.y, p.theta = ros_pose.position.x, ros_pose.position.y, yaw_of(ros_pose.orientation)
    return p


COV6 = (0, 1, 5)


def cov36(cov9):
    out = np.zeros(36)
    for i in range(3):
        for j in range(3):
            out[COV6[i] * 6 + COV6[j]] = cov9[i * 3 + j]
    return out


def cov9(cov36_):
    return [float(cov36_[COV6[i] * 6 + COV6[j]]) for i in range(3) for j in range(3)]


def tf_msg(utime, parent, child, x, y, yaw):
    t = M["geometry_msgs/msg/TransformStamped"](
        header=header(utime, parent), child_frame_id=child,
        transform=M["geometry_msgs/msg/Transform"](translation=M["geometry_msgs/msg/Vector3"](x=x, y=y, z=0.0),
                                                   rotation=quat(yaw)))
    return M["tf2_msgs/msg/TFMessage"](transforms=[t])


def vec(x=0.0, y=0.0, z=0.0):
    return M["geometry_msgs/msg/Vector3"](x=x, y=y, z=z)


# ---- marie -> ROS 2: fn(msg, state) -> [(topic suffix or None, ros type, message)] ----

def laser_to(m, st):
    r = np.array(m.ranges, dtype=np.float32)
    r[r >= m.range_max] = np.inf
    n = len(r)
    return [(None, "sensor_msgs/msg/LaserScan", M["sensor_msgs/msg/LaserScan"](
        header=header(m.utime, FRAMES["laser"]), angle_min=m.angle_min,
        angle_max=np.float32(m.angle_min + m.angle_increment * max(n - 1, 0)), angle_increment=m.angle_increment,
        time_increment=0.0, scan_time=0.0, range_min=m.range_min, range_max=m.range_max, ranges=r,
        intensities=np.array(m.intensities, dtype=np.float32)))]


def odom_to(m, st):
    st["odom"] = (m.utime, m.pose.x, m.pose.y, m.pose.theta)
    o = M["nav_msgs/msg/Odometry"](
        header=header(m.utime, FRAMES["odom"]), child_frame_id=FRAMES["base"],
        pose=M["geometry_msgs/msg/PoseWithCovariance"](pose=pose(m.pose), covariance=cov36(m.cov)),
        twist=M["geometry_msgs/msg/TwistWithCovariance"](
            twist=M["geometry_msgs/msg/Twist"](linear=vec(x=m.v), angular=vec(z=m.omega)), covariance=np.zeros(36)))
    tf = tf_msg(m.utime, FRAMES["odom"], FRAMES["base"], m.pose.x, m.pose.y, m.pose.theta)
    return [(None, "nav_msgs/msg/Odometry", o), ("/tf", "tf2_msgs/msg/TFMessage", tf)]


def pose_to(m, st):
    frame = "odom" if m.frame == "odom" else FRAMES["map"]
    out = [(None, "geometry_msgs/msg/PoseWithCovarianceStamped", M["geometry_msgs/msg/PoseWithCovarianceStamped"](
        header=header(m.utime, frame),
        pose=M["geometry_msgs/msg/PoseWithCovariance"](pose=pose(m.pose), covariance=cov36(m.cov))))]
    o = st.get("odom")
    if o and frame == FRAMES["map"]:
        th = m.pose.theta - o[3]
        c, s = math.cos(th), math.sin(th)
        x, y = m.pose.x - (c * o[1] - s * o[2]), m.pose.y - (s * o[1] + c * o[2])
        out.append(("/tf", "tf2_msgs/msg/TFMessage",
                    tf_msg(m.utime, FRAMES["map"], FRAMES["odom"], x, y, math.atan2(s, c))))
    return out


def map_to(m, st):
    return [(None, "nav_msgs/msg/OccupancyGrid", M["nav_msgs/msg/OccupancyGrid"](
        header=header(m.utime, FRAMES["map"]),
        info=M["nav_msgs/msg/MapMetaData"](map_load_time=time_of(m.utime), resolution=m.resolution, width=m.width,
                                           height=m.height, origin=pose(m.origin)),
        data=np.array(m.cells, dtype=np.int8)))]


def path_to(m, st):
    h = header(m.utime, FRAMES["map"])
    return [(None, "nav_msgs/msg/Path", M["nav_msgs/msg/Path"](
        header=h, poses=[M["geometry_msgs/msg/PoseStamped"](header=h, pose=pose(p)) for p in m.poses]))]


def twist_to(m, st):
    return [(None, "geometry_msgs/msg/Twist", M["geometry_msgs/msg/Twist"](linear=vec(x=m.v), angular=vec(z=m.omega)))]


def bool_to(m, st):
    return [(None, "std_msgs/msg/Bool", M["std_msgs/msg/Bool"](data=bool(m.pressed)))]


ENCODINGS = {0: ("mono8", 1), 1: ("rgb8", 3), 2: ("bgr8", 3)}


def image_to(m, st):
    data = np.frombuffer(bytes(m.data), dtype=np.uint8)
    if m.format == 3:
        return [("/compressed", "sensor_msgs/msg/CompressedImage", M["sensor_msgs/msg/CompressedImage"](
            header=header(m.utime, FRAMES["camera"]), format="jpeg", data=data))]
    if m.format not in ENCODINGS:
        return []
    return [(None, "sensor_msgs/msg/Image", M["sensor_msgs/msg/Image"](
        header=header(m.utime, FRAMES["camera"]), height=m.height, width=m.width, encoding=ENCODINGS[m.format][0],
        is_bigendian=0, step=m.row_stride, data=data[:m.row_stride * m.height]))]


def clock_to(m, st):
    return [(None, "rosgraph_msgs/msg/Clock", M["rosgraph_msgs/msg/Clock"](clock=time_of(m.utime)))]


STATES = ["created", "ready", "running", "paused", "failed", "exited", "degraded"]


def diag_to(m, st):
    state = STATES[m.state] if 0 <= m.state < len(STATES) else "unknown"
    kv = M["diagnostic_msgs/msg/KeyValue"]
    values = [kv(key="state", value=state)] + [kv(key=k, value=str(getattr(m, k))) for k in
                                                ("pid", "msgs_in", "msgs_out", "drops", "bad_input")]
    values += [kv(key=c.name, value=str(c.value)) for c in m.counters]
    status = M["diagnostic_msgs/msg/DiagnosticStatus"](
        level=0 if m.state == 2 else 2 if m.state == 4 else 1, name="marie: " + m.component,
        message=m.reason or state, hardware_id=m.host, values=values)
    return [(None, "diagnostic_msgs/msg/DiagnosticArray",
             M["diagnostic_msgs/msg/DiagnosticArray"](header=header(m.utime, ""), status=[status]))]


TO_ROS = {
    "laser_scan_t": laser_to, "odometry_t": odom_to, "pose_cov_t": pose_to, "occupancy_grid_t": map_to,
    "path_t": path_to, "motor_command_t": twist_to, "estop_t": bool_to, "image_t": image_to,
    "sim_clock_t": clock_to, "heartbeat_t": diag_to,
}


# ---- ROS 2 -> marie: fn(ros msg, marie module, bag utime) -> marie message or None ----

def finite(*v):
    return all(math.isfinite(float(x)) for x in v)


def laser_from(r, mt, t):
    m = mt.laser_scan_t()
    m.utime = utime_of(r.header.stamp, t)
    m.angle_min, m.angle_increment, m.range_min, m.range_max = r.angle_min, r.angle_increment, r.range_min, r.range_max
    rng = np.array(r.ranges, dtype=np.float32)
    rng[np.isnan(rng) | (rng == np.inf)] = r.range_max
    rng[rng == -np.inf] = 0.0
    m.ranges, m.nranges = [float(v) for v in rng], len(rng)
    m.intensities = [float(v) for v in r.intensities]
    m.nintensities = len(m.intensities)
    return m if finite(m.angle_min, m.angle_increment, m.range_min, m.range_max, *m.intensities) else None


def odom_from(r, mt, t):
    m = mt.odometry_t()
    m.utime = utime_of(r.header.stamp, t)
    m.pose = pose2d(r.pose.pose, mt)
    m.v, m.omega = float(r.twist.twist.linear.x), float(r.twist.twist.angular.z)
    m.cov = cov9(r.pose.covariance)
    return m if finite(m.pose.x, m.pose.y, m.pose.theta, m.v, m.omega, *m.cov) else None


def pose_from(r, mt, t):
    m = mt.pose_cov_t()
    m.utime = utime_of(r.header.stamp, t)
    m.frame = "odom" if r.header.frame_id == FRAMES["odom"] else "map"
    m.pose = pose2d(r.pose.pose, mt)
    m.cov = cov9(r.pose.covariance)
    return m if finite(m.pose.x, m.pose.y, m.pose.theta, *m.cov) else None


def map_from(r, mt, t):
    if r.info.width * r.info.height != len(r.data):
        return None
    m = mt.occupancy_grid_t()
    m.utime = utime_of(r.header.stamp, t)
    m.resolution, m.width, m.height = r.info.resolution, r.info.width, r.info.height
    m.origin = pose2d(r.info.origin, mt)
    m.cells = [int(v) for v in r.data]
    m.ncells = len(m.cells)
    return m


def path_from(r, mt, t):
    m = mt.path_t()
    m.utime = utime_of(r.header.stamp, t)
    m.poses = [pose2d(p.pose, mt) for p in r.poses]
    m.nposes = len(m.poses)
    return m


def twist_from(r, mt, t):
    m = mt.motor_command_t()
    m.utime, m.v, m.omega, m.source = t, float(r.linear.x), float(r.angular.z), "rosbag2"
    return m if finite(m.v, m.omega) else None


def bool_from(r, mt, t):
    m = mt.estop_t()
    m.utime, m.pressed, m.source = t, bool(r.data), "rosbag2"
    return m


def image_from(r, mt, t):
    names = {v[0]: k for k, v in ENCODINGS.items()}
    if r.encoding not in names or r.step * r.height > len(r.data):
        return None
    m = mt.image_t()
    m.utime = utime_of(r.header.stamp, t)
    m.width, m.height, m.row_stride, m.format = r.width, r.height, r.step, names[r.encoding]
    m.data = bytes(r.data[:r.step * r.height])
    m.size = len(m.data)
    return m


def jpeg_from(r, mt, t):
    if "jpeg" not in r.format:
        return None
    m = mt.image_t()
    m.utime, m.format = utime_of(r.header.stamp, t), 3
    m.data = bytes(r.data)
    m.size = len(m.data)
    return m


def clock_from(r, mt, t):
    m = mt.sim_clock_t()
    m.utime, m.speed = r.clock.sec * 1000000 + r.clock.nanosec // 1000, 1.0   # 0 is a time: the sim's start
    return m


FROM_ROS = {
    "sensor_msgs/msg/LaserScan": laser_from, "nav_msgs/msg/Odometry": odom_from,
    "geometry_msgs/msg/PoseWithCovarianceStamped": pose_from, "nav_msgs/msg/OccupancyGrid": map_from,
    "nav_msgs/msg/Path": path_from, "geometry_msgs/msg/Twist": twist_from, "std_msgs/msg/Bool": bool_from,
    "sensor_msgs/msg/Image": image_from, "sensor_msgs/msg/CompressedImage": jpeg_from,
    "rosgraph_msgs/msg/Clock": clock_from,
}
