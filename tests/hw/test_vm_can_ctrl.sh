#!/bin/sh
# test_vm_can_ctrl: marie's CAN drivers on a real CAN controller driver: boots Debian's kernel
# under qemu with two emulated Kvaser PCI boards (SJA1000) on one emulated CAN bus, and runs
# tests/hw/vm_can_ctrl_inner.sh there. Without qemu or busybox-static it says SKIPPED and
# counts nothing; anything failing inside is a failure.
B=${B:-build}
if ! command -v qemu-system-x86_64 >/dev/null || ! [ -x /bin/busybox ]; then
    echo "[  SKIPPED ] test_vm_can_ctrl: qemu-system-x86 or busybox-static missing (scripts/install-deps.sh vm)"
    exit 0
fi
mkdir -p "$B/test-logs/vm-can-ctrl"
exec scripts/vm/run-in-vm.sh -t ${VM_TIMEOUT:-280} -m kvaser_pci -m can-raw -m can-dev \
    -q -object -q can-bus,id=canbus0 \
    -q -device -q kvaser_pci,canbus=canbus0 -q -device -q kvaser_pci,canbus=canbus0 \
    -w "$B/test-logs/vm-can-ctrl" -- \
    env B="$B" VM_OUT="$(pwd)/$B/test-logs/vm-can-ctrl" sh tests/hw/vm_can_ctrl_inner.sh
