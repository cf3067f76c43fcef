#!/bin/sh
# Builds the gpio-sim kernel module out of tree for the VM's kernel, once; later runs only
# print the path of the module. Debian's kernels are built without CONFIG_GPIO_SIM (and
# without CONFIG_IRQ_SIM, which it needs), so both come from the matching linux-source
# package and are linked into one module, built against the matching linux-headers.
#   scripts/vm/build-gpio-sim.sh       prints e.g. /var/cache/marie-vm/6.1.0-56-amd64/extra/gpio-sim.ko
# Needs the network the first time (apt-get download, ~155 MB, not installed on the host),
# gcc-12, make, xz-utils, libelf1 (scripts/install-deps.sh vm). env: as fetch-kernel.sh.
set -eu
here=$(cd "$(dirname "$0")" && pwd)
kdir=$("$here"/fetch-kernel.sh)
ver=$(basename "$kdir")
ko=$kdir/extra/gpio-sim.ko
if [ -f "$ko" ]; then echo "$ko"; exit 0; fi

pkgver=$(apt-cache show "linux-headers-$ver" 2>/dev/null | sed -n 's/^Version: //p' | head -1)
[ -n "$pkgver" ] || { echo "build-gpio-sim: no linux-headers-$ver in apt (apt-get update?)" >&2; exit 1; }
series=$(echo "$ver" | cut -d. -f1-2)          # 6.1
flavour=${ver##*-}                               # amd64
common=linux-headers-${ver%-"$flavour"}-common
# same PKG: the version of PKG to fetch: the headers' own where apt has it, else the newest of
# the same kernel release (the security archive publishes a new Debian revision of
# linux-kbuild and linux-source before, or without, new headers: 6.1.192-3 beside headers
# 6.1.192-2 once, and the -2 of those was gone).
same() {
    vs=$(apt-cache show "$1" 2>/dev/null | sed -n 's/^Version: //p')
    if echo "$vs" | grep -qxF "$pkgver"; then echo "$pkgver"; return; fi
    echo "$vs" | awk -v u="${pkgver%-*}-" 'index($0, u) == 1' | sort -V | tail -1
}
pkgs="linux-headers-$ver=$pkgver"
for p in "$common" "linux-kbuild-$series" "linux-source-$series"; do
    v=$(same "$p")
    [ -n "$v" ] || { echo "build-gpio-sim: no $p of kernel ${pkgver%-*} in apt (apt-get update?)" >&2; exit 1; }
    pkgs="$pkgs $p=$v"
done
tmp=$kdir/.gpio-sim.$$
rm -rf "$tmp"; mkdir -p "$tmp/deb" "$tmp/root" "$tmp/mod"
trap 'rm -rf "$tmp"' EXIT INT TERM
echo "build-gpio-sim: downloading headers and source of $ver: $pkgs" >&2
# shellcheck disable=SC2086
(cd "$tmp/deb" && apt-get download $pkgs >&2 2>/dev/null) || {
    echo "build-gpio-sim: apt-get download $pkgs failed (network? scripts/install-deps.sh vm)" >&2; exit 1; }
for d in "$tmp"/deb/*.deb; do dpkg-deb -x "$d" "$tmp/root"; done
rm -rf "$tmp/deb"
hdr=$tmp/root/usr/src/linux-headers-$ver
# The flavour's Makefile includes the common tree by its installed path; the package is
# only unpacked here (its relative scripts -> ../../lib/linux-kbuild-* links hold as is).
echo "include $tmp/root/usr/src/$common/Makefile" > "$hdr/Makefile"
src=linux-source-$series
tar -xJf "$tmp/root/usr/src/$src.tar.xz" -C "$tmp" \
    "$src/drivers/gpio/gpio-sim.c" "$src/drivers/gpio/gpiolib.h" "$src/kernel/irq/irq_sim.c"
cp "$tmp/$src/drivers/gpio/gpiolib.h" "$tmp/mod/"
cp "$tmp/$src/drivers/gpio/gpio-sim.c" "$tmp/mod/gpio-sim-main.c"
# irq_to_desc() is not exported to modules; generic_handle_irq() reaches the same
# handle_simple_irq() that irq_sim installs on each of its interrupts.
sed 's/handle_simple_irq(irq_to_desc(irqnum));/generic_handle_irq(irqnum);/' \
    "$tmp/$src/kernel/irq/irq_sim.c" > "$tmp/mod/irq_sim.c"
grep -q 'generic_handle_irq(irqnum)' "$tmp/mod/irq_sim.c" || {
    echo "build-gpio-sim: irq_sim.c of $src changed, cannot adapt it" >&2; exit 1; }
printf 'obj-m := gpio-sim.o\ngpio-sim-y := gpio-sim-main.o irq_sim.o\n' > "$tmp/mod/Kbuild"
make -s -C "$hdr" M="$tmp/mod" modules >"$tmp/build.log" 2>&1 || {
    cat "$tmp/build.log" >&2; echo "build-gpio-sim: module build failed" >&2; exit 1; }
mkdir -p "$kdir/extra"
cp "$tmp/mod/gpio-sim.ko" "$ko.part" && mv "$ko.part" "$ko"
echo "$ko"
