"""domain_peer: whether a ROS 2 peer on domain D hears marie-ros2's /tf_static within S seconds.
  domain_peer.py D S      prints heard=0|1
"""
import sys
import time

import ros2_peer as rp

r = rp.Peer(int(sys.argv[1])).reader("/tf_static", "tf2_msgs/msg/TFMessage", "latched")
end = time.time() + float(sys.argv[2])
heard = 0
while time.time() < end and not heard:
    heard = int(len(r.take(N=1)) > 0)
    time.sleep(0.05)
print("heard=%d" % heard)
