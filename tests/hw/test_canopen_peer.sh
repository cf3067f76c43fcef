#!/bin/sh
# python-canopen (PyPI, in the venv scripts/peer-venv.sh makes) as an independent CANopen
# master against marie-vcan-devices on the emulated bus: see test_canopen_peer.py.
. tests/lib.sh
py=$(scripts/peer-venv.sh) || { echo "python-canopen is not installed: make test builds its venv (scripts/peer-venv.sh) before the tests; failing, not skipping"; exit 1; }
exec "$py" tests/hw/test_canopen_peer.py
