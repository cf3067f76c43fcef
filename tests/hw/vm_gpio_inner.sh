#!/bin/sh
# Runs inside the VM (see tests/hw/test_vm_gpio.sh): marie-gpio on a gpio-sim chip through
# libgpiod (e-stop with bounce, the LED, a missing and a busy line), then the chain e-stop
# line -> ESTOP -> marie-drives -> the virtual drive on vcan0 stops, with candump as witness.
B=${B:-build}
. tests/lib.sh
out=${VM_OUT:-/tmp}
boot=$(cut -d" " -f1 /proc/uptime)
ip link set lo up
ip link set lo multicast on
ip route add 224.0.0.0/4 dev lo
echo 8388608 > /proc/sys/net/core/rmem_max     # LCM asks for an 8 MB receive buffer
export MARIE_LOG=${MARIE_LOG:-warn}

# A chip labelled marie-sim with 8 lines: 0 the e-stop contact, 1 the status LED.
mount -t configfs none /sys/kernel/config
cfg=/sys/kernel/config/gpio-sim/marie
mkdir $cfg $cfg/bank0
echo 8 > $cfg/bank0/num_lines
echo marie-sim > $cfg/bank0/label
mkdir $cfg/bank0/line0 $cfg/bank0/line1
echo estop > $cfg/bank0/line0/name
echo status-led > $cfg/bank0/line1/name
echo 1 > $cfg/live
sim=/sys/devices/platform/$(cat $cfg/dev_name)/$(cat $cfg/bank0/chip_name)
check "gpio-sim chip marie-sim is live" [ -e $sim/sim_gpio0/pull ]
line_value() { cat $sim/sim_gpio$1/value; }

# --- marie-gpio on the real line; release_ms raised so scheduling noise cannot pass for a
# release between two bounces of 10 ms. Latency bounds are generous: under TCG on a loaded
# machine the VM's one CPU can stall for a second; the figures are printed.
$BIN/marie-gpio --name estop --param chip=marie-sim --param estop_line=0 --param led_line=1 \
    --param release_ms=500 > $out/gpio.log 2>&1 &
gp=$!
$B/tests/vm/vm_gpio_check $sim/sim_gpio0/pull $sim/sim_gpio1/value > /tmp/gpio.txt 2>&1
cat /tmp/gpio.txt
val() { sed -n "s/^$1=//p" /tmp/gpio.txt; }
within() { awk -v x="$1" -v lo="$2" -v hi="$3" 'BEGIN { exit !(x + 0 >= lo && x + 0 <= hi) }'; }
check "marie-gpio runs and publishes ESTOP" [ "$(val running)" = 1 ]
check "e-stop contact closed (pull-down) is published as released" [ "$(val released_initially)" = 1 ]
check "a bouncing press is published as pressed" [ "$(val press_seen)" = 1 ]
check "within 3 s of the first edge" within "$(val press_latency_ms)" 0 3000
check "once for the whole bounce" [ "$(val presses_during_press_bounce)" = 1 ]
check "a bouncing release is published as released once" [ "$(val release_seen)" = 1 -a "$(val releases_during_release_bounce)" = 1 ]
check "only after release_ms (500) of quiet contact" within "$(val release_after_last_bounce_ms)" 495 3500
check "one press in all" [ "$(val presses_total)" = 1 ]
check "the kernel delivered the bounces as edge events" within "$(val edges)" 12 1000
# heartbeat pattern: 100 ms on every second; pressed: 5 Hz, half on. The LED is sampled from
# inside a VM whose one emulated CPU stalls under load, so toggles can be missed: "fast" is
# above the heartbeat's 1 Hz with about half the time on, told apart from it by both.
check "LED blinks the heartbeat while running (1 Hz, ~10% on)" \
    sh -c "$(printf 'awk -v h=%s -v p=%s "BEGIN { exit !(h >= 0.4 && h <= 1.5 && p >= 3 && p <= 30) }"' "$(val led_released_hz)" "$(val led_released_on_pct)")"
check "LED blinks fast while the e-stop is pressed (5 Hz, ~50% on)" \
    sh -c "$(printf 'awk -v h=%s -v p=%s "BEGIN { exit !(h > 1.5 && h <= 6 && p >= 30 && p <= 70) }"' "$(val led_pressed_hz)" "$(val led_pressed_on_pct)")"
gpioinfo marie-sim > /tmp/gpioinfo.txt 2>&1
check "gpioinfo shows marie's consumers on both lines" \
    sh -c 'grep -q "\"marie-estop\"" /tmp/gpioinfo.txt && grep -q "\"marie-status\"" /tmp/gpioinfo.txt'

# --- a busy line (held by marie-gpio above) and a missing line: init fails with the reason,
# the process stays up.
$BIN/marie-gpio --name estop2 --param chip=marie-sim --param estop_line=0 > $out/gpio-busy.log 2>&1 &
busy=$!
$BIN/marie-gpio --name estop3 --param chip=marie-sim --param estop_line=40 > $out/gpio-missing.log 2>&1 &
miss=$!
check "a busy e-stop line is reported as busy" \
    wait_for 15 grep -q "cannot request e-stop line 0 on marie-sim: Device or resource busy" $out/gpio-busy.log
check "a missing e-stop line is reported" wait_for 15 grep -q "cannot request e-stop line 40 on marie-sim" $out/gpio-missing.log
check "both stay up (failed, for their manager to decide)" kill -0 $busy $miss
kill $busy $miss
cat $out/gpio-busy.log $out/gpio-missing.log | grep -i "cannot" | head -2

# --- the chain: e-stop line -> ESTOP -> marie-drives -> the virtual drive stops.
ip link add dev vcan0 type vcan
ip link set up vcan0
# line-buffered: the checks below read the log while candump runs
stdbuf -oL candump -L vcan0 > /tmp/candump.log 2>&1 &
dump=$!
$BIN/marie-vcan-devices --can can:vcan0 > $out/vcan-devices.log 2>&1 &
devs=$!
# the watches get the margin of an emulated CPU (see vm_can_inner.sh)
$BIN/marie-drives --param can=can:vcan0 --param master_timeout=1 --param rpdo_timeout=1 --param heartbeat_timeout=1 > $out/drives.log 2>&1 &
drv=$!
$B/tests/vm/hw_vm_check 120 > /tmp/check.txt 2>&1 &
cmd=$!
# little-endian hex of the left drive's TPDO2 (actual velocity, increments/s) to a number
vel() { printf '%d' "0x$(echo "$1" | sed 's/\(..\)\(..\)\(..\)\(..\).*/\4\3\2\1/')"; }
left_moving() { f=$(grep " vcan0 281#" /tmp/candump.log | tail -1 | sed 's/.*#//'); [ -n "$f" ] && [ "$(vel "$f")" -gt 2000 ]; }
# A drive that drops out on its own (a starved VM can miss heartbeats) stops without the
# e-stop: a press only counts when the drive was turning just before it; up to 3 tries.
t0=0; ts=""
stopped_at() {
    awk -v t0="$t0" '{ t = substr($1, 2, length($1) - 2) } t + 0 > t0 + 0 && / vcan0 281#00000000/ { print t; exit }' /tmp/candump.log
}
stopped() { [ -n "$(stopped_at)" ]; }
quick_stop() { awk -v t0="$t0" '{ t = substr($1, 2, length($1) - 2) } t + 0 > t0 + 0' /tmp/candump.log | grep -q ' vcan0 201#0200'; }
try=0
while [ $try -lt 3 ] && [ -z "$ts" ]; do
    try=$((try + 1))
    wait_for 60 left_moving || continue
    t0=$(date +%s.%N)
    echo pull-up > $sim/sim_gpio0/pull
    if wait_for 10 stopped && quick_stop; then
        ts=$(stopped_at)
    else
        echo "try $try: the drive did not quick-stop after the press (dropped out?)"
        echo pull-down > $sim/sim_gpio0/pull
    fi
done
echo "e-stop line pressed at $t0, left drive at 0 on the wire at ${ts:-never} (try $try)"
check "pressing the e-stop line quick-stops the turning virtual drive (controlword 0x0002)" [ -n "$ts" ]
check "to 0 on the wire within 3 s of the line going active" \
    awk -v a="$t0" -v b="${ts:-0}" 'BEGIN { d = b - a; printf "stop latency %.0f ms\n", d * 1000; exit !(d > 0 && d < 3.0) }'
echo pull-down > $sim/sim_gpio0/pull
check "releasing the e-stop lets it turn again" wait_for 30 left_moving
kill $cmd $drv $devs $dump 2>/dev/null

# --- quitting switches the LED off and frees both lines.
kill $gp
wait $gp
check "on quit the LED line is left off" [ "$(line_value 1)" = 0 ]
gpioinfo marie-sim > /tmp/gpioinfo.txt 2>&1
check "and both lines are free again" sh -c '! grep -q "marie-" /tmp/gpioinfo.txt'
wait 2>/dev/null
cp /tmp/candump.log $out/candump.log 2>/dev/null
echo "VM up $boot s when the test started"
finish
