#!/bin/sh
# make demo: the robot application in simulation under the managers, in its own network
# namespace (see docs/robot-app.md; marie-demo --help for options).
set -eu
B=${B:-build}
exec scripts/netns-run "$B/bin/marie-demo" "$@"
