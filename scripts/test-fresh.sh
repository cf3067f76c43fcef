#!/bin/sh
# test-fresh: proves the README on a brand-new Debian 12 root filesystem. A minimal bookworm
# root is built once with debootstrap (cached); every run starts from a new copy of it, puts the
# committed tree there (what a clean clone has) and runs the README's commands as root in its
# own mount namespace. pivot_root rather than chroot: the tests' user and network namespaces
# refuse a chrooted caller.
#   scripts/test-fresh.sh [COMMAND]    default: "make demo && make test"
#   env: MARIE_FRESH_CACHE (default /var/cache/marie-fresh), MARIE_FRESH_MIRROR,
#        MARIE_FRESH_KEEP=1 keeps the run's root for a look afterwards
set -eu
top=$(cd "$(dirname "$0")/.." && pwd)
cache=${MARIE_FRESH_CACHE:-/var/cache/marie-fresh}
mirror=${MARIE_FRESH_MIRROR:-http://deb.debian.org/debian}
cmd=${1:-make demo && make test}
base=$cache/bookworm

[ "$(id -u)" = 0 ] || { echo "test-fresh: run as root (it builds a root filesystem)" >&2; exit 1; }
if [ ! -e "$base/.complete" ]; then
    echo "test-fresh: building a minimal Debian 12 root in $base (once)"
    rm -rf "$base"
    mkdir -p "$cache"
    # make is the one tool the README assumes; install-deps brings everything else.
    debootstrap --variant=minbase --include=make bookworm "$base" "$mirror" > "$cache/debootstrap.log" 2>&1 ||
        { tail -20 "$cache/debootstrap.log" >&2; exit 1; }
    sec=$(echo "$mirror" | sed 's|/debian/*$|/debian-security|')
    printf 'deb %s bookworm main\ndeb %s bookworm-updates main\ndeb %s bookworm-security main\n' \
        "$mirror" "$mirror" "$sec" > "$base/etc/apt/sources.list"
    apt-get -o Dir="$base" clean 2>/dev/null || true
    touch "$base/.complete"
fi

run=$(mktemp -d "$cache/run.XXXXXX")
root=$run/root
cleanup() {
    # The run's test logs outlive it, so a failure in the fresh root can be read afterwards.
    if [ -d "$root/src/marie/build/test-logs" ]; then
        rm -rf "$cache/last-test-logs"
        cp -a "$root/src/marie/build/test-logs" "$cache/last-test-logs" && echo "test-fresh: logs in $cache/last-test-logs"
    fi
    [ "${MARIE_FRESH_KEEP:-0}" = 1 ] && { echo "test-fresh: kept $root"; return; }
    rm -rf "$run"
}
trap cleanup EXIT
cp -a "$base" "$root"
# The network's settings are the machine's, not the project's: name resolution, and the TLS
# trust a proxy on the way to PyPI may need (its CA in the bundle, pip told to use the bundle).
cp /etc/resolv.conf "$root/etc/resolv.conf"
if [ -f /etc/ssl/certs/ca-certificates.crt ]; then
    mkdir -p "$root/etc/ssl/certs" "$root/usr/local/share/ca-certificates"
    cp /etc/ssl/certs/ca-certificates.crt "$root/etc/ssl/certs/"
    # Local CAs too, or the bundle loses them when a package install runs update-ca-certificates.
    cp /usr/local/share/ca-certificates/*.crt "$root/usr/local/share/ca-certificates/" 2>/dev/null || true
fi
[ -f /etc/pip.conf ] && cp /etc/pip.conf "$root/etc/pip.conf"
mkdir -p "$root/src/marie" "$cache/archives/partial" "$root/var/cache/apt/archives"
git -C "$top" archive HEAD | tar -x -C "$root/src/marie"
# CI checks a clone with shared/ beside it; so does this.
[ -d "$top/../shared" ] && cp -a "$top/../shared" "$root/src/shared"
echo "test-fresh: $(git -C "$top" rev-parse --short HEAD) in a fresh Debian 12 root: $cmd"

# Downloaded packages are kept between runs (they are installed anew every time).
unshare --mount --propagation private sh -eu -c '
    root=$1; archives=$2; cmd=$3
    mount --bind "$root" "$root"
    mount --bind "$archives" "$root/var/cache/apt/archives"
    mount -t proc proc "$root/proc"
    mount --rbind /sys "$root/sys"
    mount --rbind /dev "$root/dev"
    mount -t tmpfs -o mode=1777 tmpfs "$root/dev/shm"
    mount -t tmpfs -o mode=1777 tmpfs "$root/tmp"
    cd "$root"
    mkdir -p .old
    pivot_root . .old
    exec chroot . /bin/sh -c "umount -l /.old && rmdir /.old && cd /src/marie &&
        exec env -i PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin HOME=/root LANG=C.UTF-8 sh -c \"$cmd\""
' sh "$root" "$cache/archives" "$cmd"
