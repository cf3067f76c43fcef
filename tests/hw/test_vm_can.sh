#!/bin/sh
# test_vm_can: the real PF_CAN path: boots Debian's kernel under qemu (scripts/vm/run-in-vm.sh)
# with vcan, and runs tests/hw/vm_can_inner.sh there. When qemu or busybox-static is not
# installed (scripts/install-deps.sh vm) it says so and counts nothing; a kernel that cannot
# be fetched, or anything failing inside, is a failure.
B=${B:-build}
if ! command -v qemu-system-x86_64 >/dev/null || ! [ -x /bin/busybox ]; then
    echo "test_vm_can: SKIPPED: qemu-system-x86 or busybox-static missing (scripts/install-deps.sh vm)"
    exit 0
fi
mkdir -p "$B/test-logs/vm-can"
exec scripts/vm/run-in-vm.sh -t ${VM_TIMEOUT:-240} -m vcan -m can-raw -m can-dev -w "$B/test-logs/vm-can" -- \
    env B="$B" VM_OUT="$(pwd)/$B/test-logs/vm-can" sh tests/hw/vm_can_inner.sh
