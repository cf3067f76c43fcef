#!/bin/sh
# test-group: vm-managers
# test_vm_can: the real PF_CAN path: boots Debian's kernel under qemu (scripts/vm/run-in-vm.sh)
# with vcan, and runs tests/hw/vm_can_inner.sh there. Without qemu or busybox-static
# (scripts/install-deps.sh vm) the VM cannot boot: the case is reported as SKIPPED with that
# reason, except in CI (CI or MARIE_REQUIRE_VM set), where the VM must run and a missing
# package is a failure. A kernel that cannot be fetched, or anything failing inside, is a failure.
B=${B:-build}
. tests/lib.sh
if ! command -v qemu-system-x86_64 >/dev/null || ! [ -x /bin/busybox ]; then
    why="qemu-system-x86 or busybox-static missing (scripts/install-deps.sh vm)"
    if [ -n "${CI:-}${MARIE_REQUIRE_VM:-}" ]; then
        check "VM can boot: $why" false
        finish
    fi
    skip "SocketCAN in the VM" "$why"
    exit 0
fi
mkdir -p "$B/test-logs/vm-can"
# The boot watchdog: a VM whose CPU never starts (qemu -S) is stopped at the boot limit, booted
# once more, then given up, long before the time limit.
start=$(date +%s)
MARIE_VM_BOOT_LIMIT=2 scripts/vm/run-in-vm.sh -t 60 -q -S -- true 2> "$B/test-logs/vm-can/stuck.err"
rc=$?
took=$(( $(date +%s) - start ))
check "a VM whose init never starts is booted once more after the boot limit, then given up (exit $rc, $took s)" \
    sh -c "[ $rc -eq 124 ] && [ $took -lt 20 ] && [ \$(grep -c 'did not start within 2s' $B/test-logs/vm-can/stuck.err) -eq 2 ]"
[ "$_bad" -eq 0 ] || finish
exec scripts/vm/run-in-vm.sh -t ${VM_TIMEOUT:-240} -m vcan -m can-raw -m can-dev -w "$B/test-logs/vm-can" -- \
    env B="$B" VM_OUT="$(pwd)/$B/test-logs/vm-can" sh tests/hw/vm_can_inner.sh
