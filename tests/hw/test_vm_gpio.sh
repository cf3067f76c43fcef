#!/bin/sh
# test-group: vm-managers
# test_vm_gpio: marie-gpio on a real GPIO line: boots Debian's kernel under qemu with the
# gpio-sim module built out of tree for it (scripts/vm/build-gpio-sim.sh, cached), and runs
# tests/hw/vm_gpio_inner.sh there. Without qemu or busybox-static it says SKIPPED and counts
# nothing; a module that cannot be built, or anything failing inside, is a failure.
B=${B:-build}
if ! command -v qemu-system-x86_64 >/dev/null || ! [ -x /bin/busybox ]; then
    echo "[  SKIPPED ] test_vm_gpio: qemu-system-x86 or busybox-static missing (scripts/install-deps.sh vm)"
    exit 0
fi
ko=$(scripts/vm/build-gpio-sim.sh) || { echo "[  FAILED  ] building gpio-sim for the VM's kernel"; exit 1; }
mkdir -p "$B/test-logs/vm-gpio"
exec scripts/vm/run-in-vm.sh -t ${VM_TIMEOUT:-280} -m "$ko" -m vcan -m can-raw -m can-dev \
    -w "$B/test-logs/vm-gpio" -- env B="$B" VM_OUT="$(pwd)/$B/test-logs/vm-gpio" sh tests/hw/vm_gpio_inner.sh
