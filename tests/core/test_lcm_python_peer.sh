#!/bin/sh
# Upstream LCM for Python (PyPI, in the venv scripts/peer-venv.sh makes) reads what
# marie_bus_publish sends: see test_lcm_python_peer.py.
# test-light
. tests/lib.sh
py=$(scripts/peer-venv.sh) || { echo "LCM for Python is not installed: make test builds its venv (scripts/peer-venv.sh) before the tests; failing, not skipping"; exit 1; }
exec "$py" tests/core/test_lcm_python_peer.py
