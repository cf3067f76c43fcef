#!/bin/sh
# Installs the Debian packages marie needs that are missing; quick when nothing is.
# Usage: scripts/install-deps.sh [base|vm|san|all]   (default: base)
set -eu

base="liblcm-dev liblcm-bin liblcm-java default-jdk-headless libglib2.0-dev pkg-config
      libeigen3-dev libode-dev libompl-dev libboost-serialization-dev
      libboost-filesystem-dev libboost-system-dev libopencv-dev libapriltag-dev
      libgpiod-dev gpiod can-utils libfyaml-dev libexpat1-dev libsodium-dev libsystemd-dev
      systemd libcmocka-dev iproute2 python3 util-linux procps libcivetweb-dev libjpeg-dev
      libjchart2d-java xvfb x11-apps"
# The VM test boots Debian's kernel under qemu to reach real SocketCAN.
vm="qemu-system-x86 busybox-static cpio"
# libFuzzer and clang's sanitizer runtimes.
san="clang libclang-rt-14-dev"
# The log viewer's browser tests drive Debian's Chromium headless.
browser="chromium"

want=""
for set in ${1:-base}; do
    case "$set" in
    base) want="$want $base" ;;
    vm)   want="$want $vm" ;;
    san)  want="$want $san" ;;
    browser) want="$want $browser" ;;
    all)  want="$want $base $vm $san $browser" ;;
    *) echo "install-deps: unknown set '$set' (base, vm, san, browser, all)" >&2; exit 2 ;;
    esac
done

# The VM test also needs Debian's kernel, unpacked in a cache (no install on the host).
case " $* " in *" vm "*|*" all "*) fetch_kernel=1 ;; *) fetch_kernel=0 ;; esac

missing=""
for p in $want; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' ||
        missing="$missing $p"
done
if [ -z "$missing" ]; then
    [ "$fetch_kernel" = 1 ] && { "$(dirname "$0")/vm/fetch-kernel.sh" >/dev/null || exit 1; }
    exit 0
fi

if [ "$(id -u)" != 0 ]; then
    echo "install-deps: missing Debian packages:$missing" >&2
    echo "install-deps: run as root (or: sudo apt-get install$missing)" >&2
    exit 1
fi
echo "install-deps: installing$missing"
export DEBIAN_FRONTEND=noninteractive
stamp=/var/lib/apt/periodic/marie-update-stamp
if [ ! -e "$stamp" ] || [ -n "$(find "$stamp" -mmin +360 2>/dev/null)" ]; then
    apt-get update -q >/dev/null
    mkdir -p "$(dirname "$stamp")" && touch "$stamp"
fi
# shellcheck disable=SC2086
apt-get install -y -q --no-install-recommends $missing >/dev/null
[ "$fetch_kernel" = 1 ] && "$(dirname "$0")/vm/fetch-kernel.sh" >/dev/null
exit 0
