#!/bin/sh
# peer-venv.sh: the Python venv of independent peers (PyPI packages marie's tests use as
# witnesses), in $B/peers; idempotent. Prints the venv's python on success.
#   scripts/peer-venv.sh        (B=build by default)
set -e
B=${B:-build}
V=$B/peers
# Pinned: a witness must not change under the tests.
# cyclonedds: the DDS binding with its own Cyclone build (11.x), a ROS 2 peer of marie-ros2 on
# Debian's 0.10.x; rosbags: ROS 2's message definitions, CDR and rosbag2 (MCAP, sqlite3).
PKGS="canopen==2.4.1 python-can==4.6.1 lcm==1.5.1 cyclonedds==11.0.1 rosbags==0.11.9 numpy==2.4.6"
if [ -x "$V/bin/python" ] && "$V/bin/python" -c 'import canopen, can, lcm, cyclonedds, rosbags, importlib.metadata as m
assert canopen.__version__ == "2.4.1" and m.version("rosbags") == "0.11.9" and m.version("cyclonedds") == "11.0.1"' 2>/dev/null; then
    echo "$V/bin/python"; exit 0
fi
python3 -m venv "$V" >&2
"$V/bin/pip" install -q --disable-pip-version-check --only-binary cyclonedds $PKGS >&2
echo "$V/bin/python"
