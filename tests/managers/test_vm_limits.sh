#!/bin/sh
# test_vm_limits: components' limits held by cgroup v2, as on a robot's Debian: boots Debian's
# kernel under qemu (scripts/vm/run-in-vm.sh), where cgroup v2 has the memory and cpu controllers
# (this machine's kernel keeps them on cgroup v1), and runs tests/managers/vm_limits_inner.sh
# there: the kernel kills a leak at its memory.max and holds a hog to its cpu.max, and marie-am
# reports each breach and applies the policy. Without qemu or busybox-static (scripts/install-deps.sh
# vm) the VM cannot boot: the case is reported as SKIPPED with that reason, except in CI (CI or
# MARIE_REQUIRE_VM set), where a missing package is a failure.
B=${B:-build}
. tests/lib.sh
if ! command -v qemu-system-x86_64 >/dev/null || ! [ -x /bin/busybox ]; then
    why="qemu-system-x86 or busybox-static missing (scripts/install-deps.sh vm)"
    if [ -n "${CI:-}${MARIE_REQUIRE_VM:-}" ]; then
        check "VM can boot: $why" false
        finish
    fi
    skip "cgroup v2 limits in the VM" "$why"
    exit 0
fi
mkdir -p "$B/test-logs/vm-limits"
exec scripts/vm/run-in-vm.sh -t ${VM_TIMEOUT:-240} -w "$B/test-logs/vm-limits" -- \
    env B="$B" VM_OUT="$(pwd)/$B/test-logs/vm-limits" sh tests/managers/vm_limits_inner.sh
