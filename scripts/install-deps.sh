#!/bin/sh
# Installs the Debian packages marie needs that are missing; quick when nothing is.
# Usage: scripts/install-deps.sh [SET...]   SET: base, vm, san, browser, fresh, bench, all (default: base)
set -eu

base="gcc g++ make liblcm-dev liblcm-bin liblcm-java default-jdk-headless libglib2.0-dev pkg-config
      libeigen3-dev libode-dev libompl-dev libboost-serialization-dev
      libboost-filesystem-dev libboost-system-dev libopencv-dev libapriltag-dev
      libgpiod-dev gpiod can-utils libfyaml-dev libexpat1-dev libsodium-dev
      systemd libcmocka-dev iproute2 python3 python3-yaml util-linux procps libcivetweb-dev nettle-dev libjpeg-dev
      libjchart2d-java tmux python3-venv xvfb x11-apps default-jre fonts-dejavu-core fontconfig
      libfftw3-dev libasound2-dev libpocketsphinx-dev pocketsphinx-en-us festival festvox-kallpc16k espeak-ng
      libceres-dev cyclonedds-dev cyclonedds-tools zlib1g-dev"
# (audio: FFTW for SRP-PHAT, ALSA for the array driver, PocketSphinx and its US English model
# for marie-asr, Festival and its US English voice for marie-tts and the simulator's phrases
# (festvox-kallpc16k: recommends are not installed), espeak-ng a second voice.)
# (nettle-dev: SHA-1 for the web pages' WebSocket handshake, tools/webcommon; libcivetweb-dev:
# the WebSocket client of bench_viewer and bench_face.)
# (libceres-dev: the mapper's pose graph optimizer, adapters/mapper; zlib1g-dev: marie log import
# reads gzipped CARMEN logs.)
# (cyclonedds-dev: marie-ros2 speaks ROS 2 on Cyclone DDS; cyclonedds-tools has idlc, which
# makes the C types of the ROS 2 messages at build time, adapters/ros2.)
# (python3-venv: the PyPI witnesses, python-canopen among them, live in a venv under build/,
# made by scripts/peer-venv.sh; xvfb and x11-apps: the real lcm-spy is started on a virtual
# screen and photographed, which takes a Java with its X11 half (default-jre) and a font.)
# The VM tests boot Debian's kernel under qemu to reach real SocketCAN and GPIO; gpio-sim is
# built out of tree for that kernel (gcc-12 and the unpacked linux-kbuild tools need these).
vm="qemu-system-x86 busybox-static cpio gcc-12 make xz-utils libelf1 libssl3"
# libFuzzer and clang's sanitizer runtimes.
san="clang libclang-rt-14-dev"
# The log viewer's browser tests drive Debian's Chromium headless.
browser="chromium"
# make bench measures round trips against Cyclone DDS's ddsperf (ROS 2's middleware then).
bench="cyclonedds-tools"
# make test-fresh builds a Debian 12 root filesystem to prove the README's two commands.
fresh="debootstrap"

want=""
[ $# -gt 0 ] || set -- base
for set in "$@"; do
    case "$set" in
    base) want="$want $base" ;;
    vm)   want="$want $vm" ;;
    san)  want="$want $san" ;;
    browser) want="$want $browser" ;;
    fresh) want="$want $fresh" ;;
    bench) want="$want $bench" ;;
    all)  want="$want $base $vm $san $browser $fresh $bench" ;;
    *) echo "install-deps: unknown set '$set' (base, vm, san, browser, fresh, bench, all)" >&2; exit 2 ;;
    esac
done

# The VM tests also need Debian's kernel, unpacked in a cache (no install on the host), and
# the gpio-sim module built for it (--extras; cached too).
case " $* " in *" vm "*|*" all "*) fetch_kernel=1 ;; *) fetch_kernel=0 ;; esac

missing=""
for p in $want; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' ||
        missing="$missing $p"
done
if [ -z "$missing" ]; then
    [ "$fetch_kernel" = 1 ] && { "$(dirname "$0")/vm/fetch-kernel.sh" --extras >/dev/null || exit 1; }
    exit 0
fi

if [ "$(id -u)" != 0 ]; then
    echo "install-deps: missing Debian packages:$missing" >&2
    echo "install-deps: run as root (or: sudo apt-get install$missing)" >&2
    exit 1
fi
echo "install-deps: installing$missing"
export DEBIAN_FRONTEND=noninteractive
stamp=${MARIE_APT_STAMP:-/var/lib/apt/periodic/marie-update-stamp}
if [ ! -e "$stamp" ] || [ -n "$(find "$stamp" -mmin +360 2>/dev/null)" ]; then
    apt-get update -q >/dev/null
    mkdir -p "$(dirname "$stamp")" && touch "$stamp"
fi
# shellcheck disable=SC2086
apt-get install -y -q --no-install-recommends $missing >/dev/null
[ "$fetch_kernel" = 1 ] && "$(dirname "$0")/vm/fetch-kernel.sh" --extras >/dev/null
exit 0
