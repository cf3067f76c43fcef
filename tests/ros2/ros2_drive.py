"""ros2_drive: a ROS 2 peer (tests/ros2/ros2_peer.py: PyPI cyclonedds and rosbags' definitions)
watches the simulated Spartacus through marie-ros2 and drives it: it decodes /scan, /odom, /map,
/tf and /amcl_pose, turns the robot with /cmd_vel, then sends it to a goal with /goal_pose.
Prints key=value lines for tests/ros2/test_ros2_system.sh.
  ros2_drive.py GOAL_X GOAL_Y TIMEOUT_S
"""
import math
import sys
import time

import ros2_peer as rp

GX, GY, TIMEOUT = float(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3])
p = rp.Peer()
R = {
    "scan": p.reader("/scan", "sensor_msgs/msg/LaserScan", "sensor"),
    "odom": p.reader("/odom", "nav_msgs/msg/Odometry"),
    "map": p.reader("/map", "nav_msgs/msg/OccupancyGrid", "latched"),
    "tf": p.reader("/tf", "tf2_msgs/msg/TFMessage", "tf"),
    "tf_static": p.reader("/tf_static", "tf2_msgs/msg/TFMessage", "latched"),
    "pose": p.reader("/amcl_pose", "geometry_msgs/msg/PoseWithCovarianceStamped"),
    "diag": p.reader("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray"),
}
cmd = p.writer("/cmd_vel", "geometry_msgs/msg/Twist")
goal = p.writer("/goal_pose", "geometry_msgs/msg/PoseStamped")
Twist, Vec = rp.msg_class("geometry_msgs/msg/Twist"), rp.msg_class("geometry_msgs/msg/Vector3")
counts = {k: 0 for k in R}
last = {}
tf = {}
start = time.time()


def out(k, v):
    print("%s=%s" % (k, v), flush=True)


def pump(seconds):
    end = time.time() + seconds
    while time.time() < end:
        for k, r in R.items():
            for s in r.take(N=50):
                counts[k] += 1
                last[k] = s
                if k in ("tf", "tf_static"):
                    for t in s.transforms:
                        tf[(t.header.frame_id, t.child_frame_id)] = t
        time.sleep(0.02)


def compose(a, b):
    """(x, y, yaw) of transform a then b."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2])


def tf2d(t):
    tr = t.transform
    return (tr.translation.x, tr.translation.y, rp.yaw(tr.rotation))


# 1. What a ROS 2 node sees, unconfigured.
need = lambda: all(counts[k] >= n for k, n in (("scan", 10), ("odom", 10), ("map", 1), ("pose", 3))) and \
    ("odom", "base_link") in tf and ("map", "odom") in tf
t0 = time.time()
while time.time() - t0 < 40 and not need():
    pump(0.2)
out("seen_after_s", "%.1f" % (time.time() - t0))
for k in R:
    out("count_" + k, counts[k])
s = last.get("scan")
if s:
    finite = [r for r in s.ranges if math.isfinite(r)]
    out("scan_frame", s.header.frame_id)
    out("scan_beams", len(s.ranges))
    out("scan_span_deg", "%.1f" % math.degrees(s.angle_max - s.angle_min))
    out("scan_in_limits", int(all(s.range_min <= r < s.range_max for r in finite)))
    out("scan_no_return_as_inf", int(all(r == math.inf for r in s.ranges if not math.isfinite(r))))
    out("scan_stamp_s", s.header.stamp.sec + s.header.stamp.nanosec * 1e-9)
m = last.get("map")
if m:
    out("map_size", "%dx%d" % (m.info.width, m.info.height))
    out("map_resolution", "%.3f" % m.info.resolution)
    out("map_frame", m.header.frame_id)
    out("map_values_ok", int(len(m.data) == m.info.width * m.info.height and set(m.data) <= {-1, 0, 100}))
    out("map_occupied_share", "%.3f" % (sum(1 for v in m.data if v == 100) / max(1, len(m.data))))
o = last.get("odom")
if o:
    out("odom_frames", "%s>%s" % (o.header.frame_id, o.child_frame_id))
out("tf_static_laser", int(("base_link", "laser") in tf))
pose = last.get("pose")
if pose and ("map", "odom") in tf and ("odom", "base_link") in tf:
    via_tf = compose(tf2d(tf[("map", "odom")]), tf2d(tf[("odom", "base_link")]))
    pp = pose.pose.pose.position
    out("pose_frame", pose.header.frame_id)
    out("tf_vs_pose_m", "%.3f" % math.hypot(via_tf[0] - pp.x, via_tf[1] - pp.y))
d = last.get("diag")
if d and d.status:
    out("diag_example", d.status[0].name.replace(" ", "_"))

# 2. /cmd_vel: turn on the spot for 3 s (the behaviours' teleop input), then let go.
yaw0 = rp.yaw(last["odom"].pose.pose.orientation) if "odom" in last else 0
turned = 0.0
prev = yaw0
end = time.time() + 3
while time.time() < end:
    cmd.write(Twist(linear=Vec(x=0.0), angular=Vec(z=0.8)))
    pump(0.05)
    y = rp.yaw(last["odom"].pose.pose.orientation)
    turned += math.atan2(math.sin(y - prev), math.cos(y - prev))
    prev = y
out("cmd_vel_turned_rad", "%.2f" % turned)
pump(2.0)
out("omega_after_release", "%.3f" % abs(last["odom"].twist.twist.angular.z))

# 3. /goal_pose in the map frame, as RViz's "2D Goal Pose" sends it.
PS = rp.msg_class("geometry_msgs/msg/PoseStamped")
g = PS()
g.header.frame_id = "map"
g.pose.position.x, g.pose.position.y = GX, GY
g.pose.orientation.w = 1.0
pump(0.5)
goal.write(g)
t0 = time.time()
best = 1e9
while time.time() - t0 < TIMEOUT:
    pump(0.25)
    pp = last["pose"].pose.pose.position
    best = min(best, math.hypot(pp.x - GX, pp.y - GY))
    if best < 0.5 and abs(last["odom"].twist.twist.linear.x) < 0.05:
        break
out("goal_distance_m", "%.2f" % best)
out("goal_after_s", "%.1f" % (time.time() - t0))
for k in ("scan", "odom", "tf"):
    out("final_count_" + k, counts[k])
