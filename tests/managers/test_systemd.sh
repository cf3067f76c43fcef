#!/bin/sh
# test_systemd: the marie-am unit is what systemd expects (systemd-analyze verify) and says
# Type=notify, WatchdogSec= and Restart=on-failure.
. tests/lib.sh
U=deploy/systemd/marie-am.service
T=$(mktemp -d /tmp/marie-test-unit.XXXXXX)
trap 'rm -rf "$T"' EXIT
check "Type=notify" grep -qx 'Type=notify' $U
check "WatchdogSec set" grep -q '^WatchdogSec=[0-9]' $U
check "Restart=on-failure" grep -qx 'Restart=on-failure' $U
# verify against the built binary (the unit names the installed path)
sed "s|/usr/local/bin/marie-am|$PWD/$BIN/marie-am|" $U > "$T/marie-am.service"
verify() { out=$(systemd-analyze verify "$T/marie-am.service" 2>&1); rc=$?; echo "$out"; [ $rc -eq 0 ] && [ -z "$out" ]; }
if command -v systemd-analyze > /dev/null; then
    check "systemd-analyze verify accepts the unit" verify
else
    echo "systemd-analyze not installed: verify skipped"
fi
# The real install into a scratch root: the unit lands there, naming the installed binary.
install_step() {
    make -s --no-print-directory install DESTDIR="$T/root" PREFIX=/usr > "$T/install.log" 2>&1 &&
        grep -q '^ExecStart=/usr/bin/marie-am ' "$T/root/usr/lib/systemd/system/marie-am.service" &&
        test -x "$T/root/usr/bin/marie-am"
}
check "make install installs the unit" install_step
finish
