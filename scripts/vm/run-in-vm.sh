#!/bin/sh
# Runs one command inside a throw-away VM booted from Debian's kernel, for what this
# machine's kernel lacks (SocketCAN, gpio-sim, ...).
#
#   scripts/vm/run-in-vm.sh [-m MODULE]... [-q QEMU-ARG]... [-w DIR] [-t SECONDS] -- COMMAND [ARGS...]
#
#   -m MODULE   load this kernel module (and what it depends on) before the command,
#               e.g. -m vcan -m can-raw; a path to a .ko file loads a module built out of
#               tree (scripts/vm/build-gpio-sim.sh), after what its modinfo depends on;
#               repeatable
#               (emulated devices); repeatable
#   -w DIR      make host directory DIR writable inside the VM (same path), e.g. for logs;
#               everything else of the host is mounted read-only
#   -t SECONDS  give up after this long (default 120); exit status 124
#   -q ARGS     more qemu arguments (split at spaces), e.g. emulated devices:
#               -q "-object can-bus,id=cb -device kvaser_pci,canbus=cb"
#
# The VM (qemu-system-x86_64, TCG, 1 CPU, 512 MB, no network card) mounts the host's / with
# 9p read-only, mounts proc, sys, devtmpfs and a tmpfs /tmp, chroots into it and runs COMMAND
# in the current directory as root, so the build's binaries run as they are (keep them out of
# /tmp). Only `lo` exists inside; bring it up yourself (ip link set lo up). The command's
# output comes on stdout; the script exits with the command's exit status.
# The kernel comes from scripts/vm/fetch-kernel.sh (downloaded once into a cache); its
# uncompressed vmlinux is booted when there is one (the PVH entry: no decompression under TCG).
# env: MARIE_VM_MEM (default 512M), QEMU (default qemu-system-x86_64), MARIE_VM_CACHE,
# MARIE_VM_BOOT_LIMIT (seconds for init to start, default 60; then one more boot).
set -eu
here=$(cd "$(dirname "$0")" && pwd)
mods=""
qargs=""
wdir=""
limit=120
while [ $# -gt 0 ]; do
    case "$1" in
    -m) mods="$mods $2"; shift 2 ;;
    -q) qargs="$qargs $2"; shift 2 ;;
    -w) wdir=$(cd "$2" && pwd); shift 2 ;;
    -t) limit=$2; shift 2 ;;
    --) shift; break ;;
    -h|--help) sed -n '2,/^[^#]/p' "$0" | grep '^#' | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) break ;;
    esac
done
[ $# -gt 0 ] || { echo "run-in-vm: no command (see -h)" >&2; exit 2; }
qemu=${QEMU:-qemu-system-x86_64}
command -v "$qemu" >/dev/null || { echo "run-in-vm: $qemu not installed (scripts/install-deps.sh vm)" >&2; exit 2; }
bb=$(command -v busybox || true)
[ -n "$bb" ] && file -L "$bb" 2>/dev/null | grep -q static || bb=/bin/busybox
[ -x "$bb" ] || { echo "run-in-vm: busybox-static not installed (scripts/install-deps.sh vm)" >&2; exit 2; }

kdir=$("$here"/fetch-kernel.sh)
mdir=$kdir/modules
kernel=$kdir/vmlinuz
[ -f "$kdir/vmlinux" ] && kernel=$kdir/vmlinux

work=$(mktemp -d "${TMPDIR:-/tmp}/marie-vm.XXXXXX")
trap 'rm -rf "$work"' EXIT INT TERM
root=$work/initramfs
mkdir -p "$root/bin" "$root/lib/modules" "$root/proc" "$root/sys" "$root/dev" "$root/host"
cp "$bb" "$root/bin/busybox"

# Modules in dependency order: a module's .modinfo names what it needs ("depends=a,b");
# modules.order lists where each one lives.
loaded=""
norm() { echo "$1" | tr '-' '_'; }
modinfo_depends() {
    case "$1" in
    *.xz) xz -dc "$1" ;; *.zst) zstd -qdc "$1" ;; *.gz) gzip -dc "$1" ;; *) cat "$1" ;;
    esac | tr '\0' '\n' | sed -n 's/^depends=//p' | head -1 | tr ',' ' '
}
resolve() {
    case "$1" in */*.ko) resolve_file "$1"; return ;; esac
    want=$(norm "$1")
    case " $loaded " in *" $want "*) return 0 ;; esac
    path=$(awk -v w="$want" '{ n = $0; sub(/.*\//, "", n); sub(/\.ko.*/, "", n); gsub(/-/, "_", n);
                               if (n == w) { print; exit } }' "$mdir/modules.order")
    if [ -z "$path" ]; then
        if grep -q "/$1\.ko\|/$want\.ko" "$mdir/modules.builtin" 2>/dev/null; then return 0; fi
        echo "run-in-vm: module $1 not found in $kdir" >&2
        exit 2
    fi
    file=$(ls "$mdir/$path"* 2>/dev/null | head -1)
    [ -n "$file" ] || { echo "run-in-vm: $mdir/$path missing" >&2; exit 2; }
    for d in $(modinfo_depends "$file"); do
        resolve "$d"
    done
    # sh has no local variables: the recursion may have changed them
    want=$(norm "$1")
    file=$(ls "$mdir"/$(awk -v w="$want" '{ n = $0; sub(/.*\//, "", n); sub(/\.ko.*/, "", n); gsub(/-/, "_", n);
                                           if (n == w) { print; exit } }' "$mdir/modules.order")* | head -1)
    case " $loaded " in *" $want "*) return 0 ;; esac
    loaded="$loaded $want"
    out=$root/lib/modules/$(printf '%02d' "$(echo $loaded | wc -w)")-$want.ko
    case "$file" in
    *.xz) xz -dc "$file" > "$out" ;;
    *.zst) zstd -qdc "$file" > "$out" ;;
    *.gz) gzip -dc "$file" > "$out" ;;
    *) cp "$file" "$out" ;;
    esac
}
# A module built out of tree: what it depends on comes from the kernel's tree.
resolve_file() {
    [ -f "$1" ] || { echo "run-in-vm: $1 missing" >&2; exit 2; }
    for d in $(modinfo_depends "$1"); do
        resolve "$d"
    done
    want=$(basename "$1" .ko | tr '-' '_')
    loaded="$loaded $want"
    cp "$1" "$root/lib/modules/$(printf '%02d' "$(echo $loaded | wc -w)")-$want.ko"
}
for m in virtio_pci 9pnet_virtio 9p $mods; do
    resolve "$m"
done

# The command, quoted for sh, runs from the current directory inside the chroot.
cwd=$(pwd)
{
    printf 'cd %s || exit 125\n' "'$(pwd)'"
    printf 'exec'
    for a in "$@"; do printf " '%s'" "$(printf '%s' "$a" | sed "s/'/'\\\\''/g")"; done
    printf '\n'
} > "$root/cmd.sh"

cat > "$root/init" <<INIT
#!/bin/busybox sh
echo "MARIE-VM-UP"
/bin/busybox --install -s /bin
export PATH=/bin
mount -t proc proc /proc
mount -t sysfs sys /sys
mount -t devtmpfs dev /dev
for m in /lib/modules/*.ko; do insmod "\$m" || echo "run-in-vm: insmod \$m failed"; done
mount -t 9p -o trans=virtio,version=9p2000.L,ro host /host || { echo "MARIE-VM-EXIT 126"; poweroff -f; }
mount -t proc proc /host/proc
mount -t sysfs sys /host/sys
mount -t devtmpfs dev /host/dev
# The VM gets its own /tmp; a checkout under the host's /tmp (a CI clone) stays reachable.
mkdir -p /hosttmp
mount -o bind /host/tmp /hosttmp
mount -t tmpfs tmp /host/tmp
case "$cwd" in /tmp/*) mkdir -p "/host$cwd" && mount -o bind "/hosttmp${cwd#/tmp}" "/host$cwd" ;; esac
[ -n "$wdir" ] && mount -t 9p -o trans=virtio,version=9p2000.L out /host$wdir
cp /cmd.sh /host/tmp/.marie-vm-cmd.sh
chroot /host /bin/sh /tmp/.marie-vm-cmd.sh
echo "MARIE-VM-EXIT \$?"
sync
poweroff -f
INIT
chmod +x "$root/init"
[ -n "${MARIE_VM_DEBUG:-}" ] && ls "$root/lib/modules" >&2
(cd "$root" && find . | cpio -o -H newc 2>/dev/null | gzip -1) > "$work/initramfs.gz"

share_w=""
[ -n "$wdir" ] && share_w="-virtfs local,path=$wdir,mount_tag=out,security_model=none"
log=$work/console.log
# boot SECONDS: runs the VM for at most SECONDS, its console into $log. Under TCG on a busy
# machine a boot has (once in many runs) never reached init; a VM whose init has not spoken
# within MARIE_VM_BOOT_LIMIT seconds (default 60; a boot takes 3-4 s on an idle machine here)
# is stopped and booted once more, with what is left of the time limit.
boot() {
    # shellcheck disable=SC2086
    timeout -k 5 "$1" "$qemu" -accel tcg -m "${MARIE_VM_MEM:-512M}" -smp 1 -nographic -no-reboot \
        -nic none -kernel "$kernel" -initrd "$work/initramfs.gz" \
        -append "console=ttyS0 quiet loglevel=3 panic=-1" \
        -virtfs local,path=/,mount_tag=host,security_model=none,readonly=on,multidevs=remap $share_w $qargs \
        < /dev/null > "$log" 2>&1 &
    vm=$!
    waited=0
    while kill -0 "$vm" 2>/dev/null && ! grep -q 'MARIE-VM-UP' "$log"; do
        if [ "$waited" -ge "$((boot_limit * 5))" ]; then
            kill "$vm" 2>/dev/null
            wait "$vm"
            return 1
        fi
        sleep 0.2
        waited=$((waited + 1))
    done
    wait "$vm" || true
}
boot_limit=${MARIE_VM_BOOT_LIMIT:-60}
if ! boot "$limit"; then
    echo "run-in-vm: the VM's init did not start within ${boot_limit}s ($(wc -c < "$log") bytes on the console): booting again" >&2
    boot "$((limit > boot_limit * 2 ? limit - boot_limit : boot_limit))" ||
        echo "run-in-vm: the VM's init did not start within ${boot_limit}s again" >&2
fi
# Console lines end in CR LF; drop the CRs and the exit marker from what the caller sees.
# Firmware chatter and terminal escapes are not the command's output.
tr -d '\r' < "$log" | sed 's/\x1b\[[0-9;?]*[a-zA-Z]//g; s/\x1bc//g' |
    grep -v -e '^MARIE-VM-EXIT ' -e '^MARIE-VM-UP' -e '^SeaBIOS' -e '^Booting from ROM' -e 'reboot: Power down' -e '^$' || true
rc=$(tr -d '\r' < "$log" | sed -n 's/^MARIE-VM-EXIT \([0-9]*\).*/\1/p' | tail -1)
if [ -z "$rc" ]; then
    echo "run-in-vm: the VM did not finish (timeout ${limit}s or boot failure)" >&2
    exit 124
fi
exit "$rc"
