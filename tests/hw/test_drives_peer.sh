#!/bin/sh
# marie-drives against CiA 402 drives written from the standard on python-canopen's LocalNode
# (PyPI, in the venv scripts/peer-venv.sh makes), with upstream LCM for Python as the listener:
# see test_drives_peer.py.
. tests/lib.sh
py=$(scripts/peer-venv.sh) || { echo "python-canopen is not installed: make test builds its venv (scripts/peer-venv.sh) before the tests; failing, not skipping"; exit 1; }
exec "$py" tests/hw/test_drives_peer.py
