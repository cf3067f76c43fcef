#!/bin/sh
# test-light
# test_systemd: the marie-am unit is what systemd expects (systemd-analyze verify) and asks for
# the behaviour marie-am implements (Type=notify, WatchdogSec=, Restart=on-failure: the notify
# and watchdog protocol itself is tested against a real socket in test_am_notify), and make
# install puts it in place naming the installed binary.
. tests/lib.sh
U=deploy/systemd/marie-am.service
T=$(mktemp -d /tmp/marie-test-unit.XXXXXX)
trap 'rm -rf "$T"' EXIT
# verify against the built binary (the unit names the installed path)
sed "s|/usr/local/bin/marie-am|$PWD/$BIN/marie-am|" $U > "$T/marie-am.service"
# systemd parses the unit with the settings marie-am's notify and watchdog code relies on
verify() {
    out=$(systemd-analyze verify "$T/marie-am.service" 2>&1); rc=$?; echo "$out"
    [ $rc -eq 0 ] && [ -z "$out" ] || return 1
    grep -qx 'Type=notify' $U && grep -q '^WatchdogSec=[0-9]' $U && grep -qx 'Restart=on-failure' $U
}
if command -v systemd-analyze > /dev/null; then
    check "systemd-analyze verify accepts the notify/watchdog/restart unit" verify
else
    skip "systemd-analyze verify" "systemd-analyze not installed (scripts/install-deps.sh base)"
fi
# The real install into a scratch root: the unit lands there, naming the installed binary.
install_step() {
    make -s --no-print-directory install DESTDIR="$T/root" PREFIX=/usr > "$T/install.log" 2>&1 &&
        grep -q '^ExecStart=/usr/bin/marie-am ' "$T/root/usr/lib/systemd/system/marie-am.service" &&
        test -x "$T/root/usr/bin/marie-am"
}
check "make install installs the unit" install_step
finish
