#!/bin/sh
# peer-venv.sh: the Python venv of independent peers (PyPI packages marie's tests use as
# witnesses), in $B/peers; idempotent. Prints the venv's python on success.
#   scripts/peer-venv.sh        (B=build by default)
set -e
B=${B:-build}
V=$B/peers
# Pinned: a witness must not change under the tests.
PKGS="canopen==2.4.1 python-can==4.6.1 lcm==1.5.1"
if [ -x "$V/bin/python" ] && "$V/bin/python" -c 'import canopen, can, lcm; assert canopen.__version__ == "2.4.1"' 2>/dev/null; then
    echo "$V/bin/python"; exit 0
fi
python3 -m venv "$V" >&2
"$V/bin/pip" install -q --disable-pip-version-check $PKGS >&2
echo "$V/bin/python"
