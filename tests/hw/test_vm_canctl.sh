#!/bin/sh
# test-group: vm-managers
# test_vm_canctl: the drivers on a real CAN controller driver, not only vcan: qemu emulates two
# Kvaser PCICANx boards (SJA1000, Linux's kvaser_pci + sja1000 drivers) on one emulated bus;
# the drivers use can0 and the virtual devices can1, both set to 500 kbit/s with restart-ms
# as on the robot, and tests/hw/vm_can_inner.sh runs the full CANopen start-up and motion
# checks there, candump on can0 as the witness. Skipped with a message, like test_vm_can,
# only when qemu or busybox-static is not installed.
B=${B:-build}
if ! command -v qemu-system-x86_64 >/dev/null || ! [ -x /bin/busybox ]; then
    echo "test_vm_canctl: SKIPPED: qemu-system-x86 or busybox-static missing (scripts/install-deps.sh vm)"
    exit 0
fi
mkdir -p "$B/test-logs/vm-canctl"
exec scripts/vm/run-in-vm.sh -t ${VM_TIMEOUT:-240} -m can-raw -m can-dev -m sja1000 -m kvaser_pci \
    -q "-object can-bus,id=canbus0 -device kvaser_pci,canbus=canbus0 -device kvaser_pci,canbus=canbus0" \
    -w "$B/test-logs/vm-canctl" -- \
    env B="$B" VM_OUT="$(pwd)/$B/test-logs/vm-canctl" VM_CAN=controllers sh tests/hw/vm_can_inner.sh
