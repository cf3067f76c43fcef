#!/bin/sh
# make demo: runs the robot application in simulation when it is built; until then the
# example producer/consumer pair, saying so.
set -eu
B=${B:-build}
if [ -x "$B/bin/marie-demo" ] && [ -f config/spartacus.yaml ]; then
    exec scripts/netns-run "$B/bin/marie-demo" "$@"
fi
echo "demo: the robot application is not built yet; this shows the example component pair"
echo "demo: (a producer publishing counter_t at 20 Hz, a consumer counting them) for 3 s"
exec scripts/netns-run sh -c '
    B='"$B"'
    $B/bin/marie-example-consumer --name consumer & c=$!
    $B/bin/marie-example-producer --name producer --param rate_hz=20 & p=$!
    lcm-logger -q $B/demo-example.lcm & l=$!
    sleep 3
    kill -TERM $p $c $l; wait $p; wait $c; wait $l || true
    n=$(lcm-logplayer --help >/dev/null 2>&1; python3 -c "import sys,struct
d=open(\"$B/demo-example.lcm\",\"rb\").read(); i=0; n=0
while i+28<=len(d):
    cl,dl=struct.unpack(\">II\",d[i+20:i+28]); ch=d[i+28:i+28+cl]; n+=ch==b\"EXAMPLE\"; i+=28+cl+dl
print(n)")
    echo "demo: example pair ran 3 s; $n EXAMPLE messages recorded in $B/demo-example.lcm"
'
