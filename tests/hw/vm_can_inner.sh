#!/bin/sh
# Runs inside the VM (see tests/hw/test_vm_can.sh): marie-drives and marie-gyro against the
# virtual devices on real SocketCAN, with candump as the independent witness: on vcan0, or
# (VM_CAN=controllers, tests/hw/test_vm_canctl.sh) with the drivers on can0 and the devices on
# can1, two emulated SJA1000 boards (kvaser_pci) on one emulated bus, set up as on the robot.
B=${B:-build}
. tests/lib.sh
BIN=$B/bin
out=${VM_OUT:-/tmp}
ip link set lo up
ip link set lo multicast on
ip route add 224.0.0.0/4 dev lo
echo 8388608 > /proc/sys/net/core/rmem_max     # LCM asks for an 8 MB receive buffer
if [ "${VM_CAN:-vcan}" = controllers ]; then
    IF=can0; DEV_IF=can1
    check "two CAN controllers probed (kvaser_pci, sja1000)" [ -e /sys/class/net/can0 -a -e /sys/class/net/can1 ]
    ip link set can0 type can bitrate 500000 restart-ms 100
    ip link set can1 type can bitrate 500000 restart-ms 100
    ip link set can0 up
    ip link set can1 up
    ip -details link show can0 | sed -n 's/^ *\(can state [A-Z-]*\).*/\1/p'
    check "can0 comes up error-active at 500 kbit/s" sh -c 'ip -details link show can0 | grep -q "state ERROR-ACTIVE" && ip -details link show can0 | grep -q "bitrate 500000"'
else
    IF=vcan0; DEV_IF=vcan0
    ip link add dev vcan0 type vcan
    ip link set vcan0 mtu 72        # CAN FD capable
    ip link set up vcan0
    # The CAN layer itself on PF_CAN (cmocka cases, counted by the runner).
    $B/tests/vm/vm_socketcan
fi
export MARIE_LOG=${MARIE_LOG:-warn}

candump -L $IF > /tmp/candump.log 2>&1 &
dump=$!
$BIN/marie-vcan-devices --can can:$DEV_IF --gyro-noise 0.0005 > $out/vcan-devices.log 2>&1 &
devs=$!
# An emulated CPU (TCG) on a shared host stalls for tenths of a second: the drives' watch on
# marie-drives (0.1 s on the robot), the driver's watch on the drives (0.35 s) and its SDO
# timeout (0.2 s; 4 s of configuration steps timed out one after the other at a load of 9) get the
# margin of a slow machine here.
$BIN/marie-drives --param can=can:$IF --param master_timeout=1 --param rpdo_timeout=1 --param heartbeat_timeout=1 \
    --param sdo_timeout=1 > $out/drives.log 2>&1 &
drv=$!
$BIN/marie-gyro --param can=can:$IF > $out/gyro.log 2>&1 &
gyr=$!

$B/tests/vm/hw_vm_check 3 > /tmp/check.txt 2>&1
check_rc=$?
# A drive fault on the wire: EMCY from the left drive, then the driver's fault reset.
kill -USR1 $devs
i=0
while [ $i -lt 80 ] && ! grep -q " $IF 201#8000" /tmp/candump.log; do sleep 0.1; i=$((i + 1)); done
sleep 0.5
if [ "$IF" = can0 ]; then
    # The drivers' controller goes down and up (a cable pulled, ip link set down): sends fail,
    # reads end, the link reopens; the drives come back under control.
    ip link set can0 down
    sleep 1
    ip link set can0 up
    $B/tests/vm/hw_vm_check 3 > /tmp/check2.txt 2>&1
    check "after can0 down and up the drivers report the commanded velocities again" [ $? -eq 0 ]
    check "the link loss is counted (tx_error or disconnected)" grep -q "tx_error\|disconnected" $out/drives.log
    ip -statistics link show can0 | sed -n '3,6p'
fi
kill $dump 2>/dev/null    # candump ends by itself when can0 goes down
kill $drv $gyr
sleep 0.3
kill $devs
wait 2>/dev/null
cat /tmp/check.txt
cp /tmp/candump.log $out/candump.log 2>/dev/null
val() { sed -n "s/^$1=//p" /tmp/check.txt; }
# little-endian hex bytes (8 hex digits) to a signed 32-bit number
le32() { b=$1; v=$(printf '%d' "0x$(echo "$b" | sed 's/\(..\)\(..\)\(..\)\(..\)/\4\3\2\1/')"); [ "$v" -ge 2147483648 ] && v=$((v - 4294967296)); echo "$v"; }
# the frames on the wire before the driver published what it reported (candump buffers its
# output, so time stamps, not file position, tell what came before)
last() { m=$(val ${3:-enc}_time); awk -v m="$m" '{ t = substr($1, 2, length($1) - 2) } t + 0 <= m + 0' /tmp/candump.log | grep " $IF $1#" | tail -${2:-1} | head -1 | sed 's/.*#//'; }
count() { grep -c " $IF $1#" /tmp/candump.log; }

check "drivers report the commanded wheel velocities over LCM" [ "$check_rc" -eq 0 ]
check "candump sees SYNC from marie-drives" [ "$(count 080)" -gt 20 ]
check "candump sees RPDO1 to both drives" [ "$(count 201)" -gt 20 -a "$(count 202)" -gt 20 ]
check "candump sees TPDO1/TPDO2 of both drives" [ "$(count 181)" -gt 20 -a "$(count 282)" -gt 20 ]
check "candump sees the gyro TPDO" [ "$(count 1A0)" -gt 50 ]
check "candump sees the SDO configuration and NMT start" [ "$(count 601)" -gt 10 -a "$(count 000)" -ge 2 ]
# RPDO1: controlword 0x000F (enable operation) and target 4 rad/s = 2608 increments/s
r=$(last 201)
echo "last RPDO1 left: $r"
check "RPDO1 carries enable-operation and the kinematic target" [ "$r" = "0F00300A0000" ]
# the left drive's TPDO2 (actual velocity) a little before the end, against the driver's report
t=$(last 281 2)
cnt=$(le32 "$t")
echo "TPDO2 left velocity: $cnt increments/s; driver reported $(val left_velocity) rad/s"
check "driver's wheel velocity matches the drive's TPDO on the wire" \
    awk -v c="$cnt" -v r="$(val left_velocity)" 'BEGIN { d = c * 6.283185307 / 4096 - r; exit !(d < 0.01 && d > -0.01) }'
check "candump sees the left drive's EMCY 0x2310 (over-current)" grep -q " $IF 081#1023" /tmp/candump.log
check "the driver answers the fault with a fault reset (controlword 0x0080)" grep -q " $IF 201#8000" /tmp/candump.log
check "and enables operation again after it" sh -c "sed -n '/ $IF 201#8000/,\$p' /tmp/candump.log | grep -q ' $IF 201#0F00'"
g=$(last 1A0 1 gyro)
graw=$(le32 "$(echo "$g" | cut -c1-8)")
echo "gyro TPDO raw $graw urad/s; driver yaw_rate $(val yaw_rate) + bias $(val bias)"
check "gyro driver's rate plus bias matches the raw TPDO" \
    awk -v g="$graw" -v y="$(val yaw_rate)" -v b="$(val bias)" 'BEGIN { d = g * 1e-6 - (y + b); exit !(d < 0.02 && d > -0.02) }'
finish
