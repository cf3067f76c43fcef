#!/bin/sh
# Runs inside the VM (see tests/hw/test_vm_can_ctrl.sh): two emulated Kvaser PCI boards
# (SJA1000, driven by Debian's sja1000 + kvaser_pci) on one emulated bus; marie-drives and
# marie-gyro on can0, the virtual devices on can1, candump on can1 as the independent witness.
B=${B:-build}
. tests/lib.sh
out=${VM_OUT:-/tmp}
boot=$(cut -d" " -f1 /proc/uptime)
ip link set lo up
ip link set lo multicast on
ip route add 224.0.0.0/4 dev lo
echo 8388608 > /proc/sys/net/core/rmem_max     # LCM asks for an 8 MB receive buffer
export MARIE_LOG=${MARIE_LOG:-warn}

# As on the robot.
ip link set can0 type can bitrate 500000 restart-ms 100
ip link set can1 type can bitrate 500000 restart-ms 100
ip link set can0 up
ip link set can1 up
ip -details link show can0 > /tmp/can0.txt
cat /tmp/can0.txt
check "can0 is an SJA1000 at 500 kbit/s, error-active, restart-ms 100" \
    sh -c 'grep -q "sja1000:" /tmp/can0.txt && grep -q "bitrate 500000" /tmp/can0.txt &&
           grep -q "state ERROR-ACTIVE" /tmp/can0.txt && grep -q "restart-ms 100" /tmp/can0.txt'
# The emulated bus on its own, can-utils on both ends.
candump -L -n 2 can1 > /tmp/peer.log 2>&1 &
peer=$!
sleep 0.3
cansend can0 123#DEADBEEF
cansend can0 7FF#R
wait $peer
check "cansend on can0 reaches candump on can1 through the controllers" \
    sh -c 'grep -q " can1 123#DEADBEEF" /tmp/peer.log && grep -q " can1 7FF#R" /tmp/peer.log'

# line-buffered: the checks below read the log while candump runs
stdbuf -oL candump -L can1 > /tmp/candump.log 2>&1 &
dump=$!
$BIN/marie-vcan-devices --can can:can1 --gyro-noise 0.0005 > $out/devices.log 2>&1 &
devs=$!
$BIN/marie-drives --param can=can:can0 > $out/drives.log 2>&1 &
drv=$!
$BIN/marie-gyro --param can=can:can0 > $out/gyro.log 2>&1 &
gyr=$!
$B/tests/vm/hw_vm_check 3 > /tmp/check.txt 2>&1
check_rc=$?
cat /tmp/check.txt
count() { grep -c " can1 $1#" /tmp/candump.log; }
check "start-up and motion over real controllers: the drivers report the commanded velocities" [ "$check_rc" -eq 0 ]
check "candump sees the SDO configuration and NMT start" [ "$(count 601)" -gt 10 -a "$(count 000)" -ge 2 ]
check "candump sees SYNC, RPDO1 to both drives and their TPDOs" \
    [ "$(count 080)" -gt 20 -a "$(count 201)" -gt 20 -a "$(count 202)" -gt 20 -a "$(count 281)" -gt 20 ]
check "candump sees the gyro TPDO" [ "$(count 1A0)" -gt 20 ]
check "RPDO1 carries enable-operation and the kinematic target" grep -q " can1 201#0F00300A0000" /tmp/candump.log

# --- can0 goes down under the driver while it commands motion, then up again.
$B/tests/vm/hw_vm_check 600 > /tmp/check2.txt 2>&1 &
cmd=$!
vel() { printf '%d' "0x$(echo "$1" | sed 's/\(..\)\(..\)\(..\)\(..\).*/\4\3\2\1/')"; }
moving_since() {
    awk -v t0="$1" '{ t = substr($1, 2, length($1) - 2) } t + 0 > t0 + 0 && / can1 281#/' /tmp/candump.log |
        tail -1 | sed 's/.*#//' > /tmp/last281
    f=$(cat /tmp/last281); [ -n "$f" ] && [ "$(vel "$f")" -gt 2000 ]
}
check "the left drive turns" wait_for 30 moving_since 0
tx_before=$(ip -s link show can0 | awk '/TX:/ { getline; print $2; exit }')
ip link set can0 down
t_down=$(date +%s.%N)
sleep 1
t_up=$(date +%s.%N)
ip link set can0 up
check "marie-drives reports the link loss with the reason" grep -q "can:can0: Network is down" $out/drives.log
check "after can0 is down for 1 s and up again, the drive turns again" wait_for 30 moving_since "$t_up"
t_ok=$(awk -v t0="$t_up" '{ t = substr($1, 2, length($1) - 2) } t + 0 > t0 + 0 && / can1 201#0F00/ { print t; exit }' /tmp/candump.log)
echo "can0 down at $t_down, up at $t_up, enable-operation RPDO again at ${t_ok:-never}"
frames_down=$(awk -v a="$t_down" -v b="$t_up" '{ t = substr($1, 2, length($1) - 2) } t + 0 > a + 0 && t + 0 < b + 0 && / can1 (080|201|202)#/' /tmp/candump.log | wc -l)
check "no master frame reaches the bus while can0 is down" [ "$frames_down" -eq 0 ]
f=$(awk -v b="$t_up" '{ t = substr($1, 2, length($1) - 2) } t + 0 < b + 0 && / can1 281#/' /tmp/candump.log | tail -1 | sed 's/.*#//')
echo "left drive's actual velocity at the end of the outage: $(vel "${f:-00000000}") increments/s"
grep -c "disconnected: can:can0" $out/drives.log | sed 's/^/disconnected events: /'

# --- a flood: cangen sends 1000 frames back to back on can0 beside marie-drives. The
# emulated SJA1000 completes every transmission at once, so no TX queue fills (no ENOBUFS)
# and no error frame comes; the drivers must come through the load.
cangen can0 -g 0 -n 1000 -I 7F0 -L 8 > /tmp/cangen.txt 2>&1
cangen_rc=$?
cat /tmp/cangen.txt | head -3
ip -s -details link show can0 | sed -n '/RX:/,$p'
echo "cangen rc=$cangen_rc"
check "the drive turns again after the flood" wait_for 60 moving_since "$(date +%s.%N)"

kill $cmd $drv $gyr 2>/dev/null
sleep 0.3
kill $devs $dump 2>/dev/null
wait 2>/dev/null
cp /tmp/candump.log $out/candump.log
echo "VM up $boot s when the test started"
finish
