#!/bin/sh
# Fetches and unpacks Debian's linux-image-amd64 kernel (vmlinuz + modules) for the VM test,
# once; later runs only print the directory. Nothing is installed on the host. The kernel is
# also kept uncompressed (vmlinux, scripts/vm/unpack-kernel.py) when it has a PVH entry point:
# qemu boots that directly, without decompressing it in the emulated CPU first.
#   scripts/vm/fetch-kernel.sh            prints the unpacked root, e.g. /var/cache/marie-vm/6.1.0-56-amd64
#   scripts/vm/fetch-kernel.sh --extras   also builds the out-of-tree modules the VM tests load
#                                         (scripts/vm/build-gpio-sim.sh, cached likewise)
# env: MARIE_VM_CACHE   cache directory (default /var/cache/marie-vm when writable, else build/vm)
#      MARIE_VM_KERNEL  a kernel package to use instead of what linux-image-amd64 depends on,
#                       e.g. linux-image-6.12.12+bpo-amd64 from bookworm-backports (needs that
#                       archive in apt's sources); Debian's 6.1 has vcan but no gpio-sim
set -eu
if [ "${1:-}" = --extras ]; then
    d=$("$0")
    "$(dirname "$0")"/build-gpio-sim.sh >/dev/null
    echo "$d"
    exit 0
fi
cache=${MARIE_VM_CACHE:-}
if [ -z "$cache" ]; then
    if mkdir -p /var/cache/marie-vm 2>/dev/null && [ -w /var/cache/marie-vm ]; then
        cache=/var/cache/marie-vm
    else
        cache=$(pwd)/${B:-build}/vm
    fi
fi
mkdir -p "$cache"
# elf DIR: DIR/vmlinux from DIR/vmlinuz, once; a kernel without a PVH entry is marked so, and
# booted compressed.
elf() {
    [ -f "$1/vmlinux" ] || [ -f "$1/vmlinux.none" ] ||
        python3 "$(dirname "$0")"/unpack-kernel.py "$1/vmlinuz" "$1/vmlinux" || : > "$1/vmlinux.none"
}
# A kernel already unpacked is used as is (no network needed).
want=${MARIE_VM_KERNEL:+${MARIE_VM_KERNEL#linux-image-}}
for d in "$cache"/${want:-*-amd64}; do
    if [ -f "$d/vmlinuz" ] && [ -d "$d/modules" ]; then elf "$d" 2>/dev/null; echo "$d"; exit 0; fi
done
pkg=${MARIE_VM_KERNEL:-}
[ -n "$pkg" ] || pkg=$(apt-cache depends linux-image-amd64 2>/dev/null | awk '/Depends: linux-image-[0-9]/{print $2; exit}')
if [ -z "$pkg" ] && [ -z "${MARIE_VM_KERNEL:-}" ]; then
    if [ "$(id -u)" = 0 ]; then apt-get update -q >/dev/null 2>&1 || true; fi
    pkg=$(apt-cache depends linux-image-amd64 2>/dev/null | awk '/Depends: linux-image-[0-9]/{print $2; exit}')
fi
[ -n "$pkg" ] || { echo "fetch-kernel: cannot resolve linux-image-amd64 (apt-get update?)" >&2; exit 1; }
ver=${pkg#linux-image-}
dl=$cache/deb
mkdir -p "$dl"
if ! ls "$dl"/"$pkg"_*.deb >/dev/null 2>&1; then
    echo "fetch-kernel: downloading $pkg" >&2
    (cd "$dl" && apt-get download "$pkg" >&2) || {
        echo "fetch-kernel: apt-get download $pkg failed" >&2; exit 1; }
fi
tmp=$cache/.unpack.$$
rm -rf "$tmp"; mkdir -p "$tmp"
dpkg-deb -x "$dl"/"$pkg"_*.deb "$tmp"
out=$cache/$ver
rm -rf "$out"; mkdir -p "$out"
cp "$tmp"/boot/vmlinuz-"$ver" "$out"/vmlinuz
mv "$tmp"/lib/modules/"$ver" "$out"/modules 2>/dev/null || mv "$tmp"/usr/lib/modules/"$ver" "$out"/modules
rm -rf "$tmp" "$dl"
elf "$out"
echo "$out"
