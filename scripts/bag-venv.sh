#!/bin/sh
# bag-venv.sh: the Python venv of `marie bag` (tools/bag): rosbags (rosbag2 in MCAP and sqlite3,
# ROS 2's CDR and message definitions) and upstream LCM's Python log reader, in $B/venv-bag;
# idempotent. Prints the venv's python on success.
#   scripts/bag-venv.sh        (B=build by default)
set -e
B=${B:-build}
V=$B/venv-bag
# Pinned: a bag written today must read the same tomorrow.
PKGS="rosbags==0.11.9 lcm==1.5.1 numpy==2.4.6"
if [ -x "$V/bin/python" ] && "$V/bin/python" -c 'import lcm, importlib.metadata as m
assert m.version("rosbags") == "0.11.9" and m.version("lcm") == "1.5.1"' 2>/dev/null; then
    echo "$V/bin/python"; exit 0
fi
python3 -m venv "$V" >&2
"$V/bin/pip" install -q --disable-pip-version-check $PKGS >&2
echo "$V/bin/python"
