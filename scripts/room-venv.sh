#!/bin/sh
# room-venv.sh: the Python venv that speaks and renders rooms for the recognition tests
# (pyroomacoustics, numpy, scipy), in $B/room; idempotent. Prints the venv's python on success.
#   scripts/room-venv.sh        (B=build by default)
set -e
B=${B:-build}
V=$B/room
# Pinned: the rooms a test hears must not change under it.
PKGS="numpy==2.4.6 scipy==1.17.1 Cython==3.3.2 pyroomacoustics==0.10.1"
if [ -x "$V/bin/python" ] && "$V/bin/python" -c 'import pyroomacoustics as p; assert p.__version__ == "0.10.1"' 2>/dev/null; then
    echo "$V/bin/python"; exit 0
fi
python3 -m venv "$V" >&2
"$V/bin/pip" install -q --disable-pip-version-check $PKGS >&2
echo "$V/bin/python"
