#!/bin/sh
# test-light
# test_install_deps: scripts/install-deps.sh installs every set it is asked for, and only what is
# missing (stand-in dpkg-query, apt-get and id on PATH record what would happen).
. tests/lib.sh
T=$(mktemp -d /tmp/marie-test-deps.XXXXXX)
trap 'rm -rf "$T"' EXIT
mkdir -p "$T/bin" "$T/scripts/vm"
cp scripts/install-deps.sh "$T/scripts/"
# fetch-kernel stand-in: records that the VM's kernel was fetched.
printf '#!/bin/sh\necho fetched >> "%s/kernel"\n' "$T" > "$T/scripts/vm/fetch-kernel.sh"
# dpkg-query stand-in: a package is installed when it is listed in $T/installed.
cat > "$T/bin/dpkg-query" <<EOS
#!/bin/sh
for p; do :; done
grep -qx "\$p" "$T/installed" 2>/dev/null && printf 'install ok installed' || exit 1
EOS
printf '#!/bin/sh\necho "$*" >> "%s/apt"\n' "$T" > "$T/bin/apt-get"
printf '#!/bin/sh\necho "${FAKE_UID:-0}"\n' > "$T/bin/id"
chmod +x "$T/bin/"* "$T/scripts/vm/fetch-kernel.sh"
export MARIE_APT_STAMP="$T/stamp"

deps() { : > "$T/apt"; rm -f "$T/kernel"; PATH="$T/bin:$PATH" sh "$T/scripts/install-deps.sh" "$@"; }
installs() { grep '^install' "$T/apt" | tr ' ' '\n' | grep -qx "$1"; }
base_pkgs=$(sed -n '/^base="/,/"$/p' scripts/install-deps.sh | tr -d '"' | sed 's/^base=//')

every_set_asked_for_is_installed() {
    : > "$T/installed"
    deps vm browser || return 1
    for p in qemu-system-x86 busybox-static cpio chromium; do installs "$p" || { echo "missing $p"; return 1; }; done
    ! installs libode-dev && [ -s "$T/kernel" ]
}
default_is_base_only() {
    : > "$T/installed"
    deps || return 1
    for p in $base_pkgs; do installs "$p" || { echo "missing $p"; return 1; }; done
    ! installs chromium && ! installs qemu-system-x86 && [ ! -e "$T/kernel" ]
}
installed_packages_are_left_alone() {
    printf '%s\n' $base_pkgs chromium > "$T/installed"
    deps base browser || return 1
    [ ! -s "$T/apt" ]
}
only_missing_packages_are_installed() {
    printf '%s\n' $base_pkgs > "$T/installed"
    deps base browser || return 1
    installs chromium && [ "$(grep '^install' "$T/apt" | wc -w)" -eq "$(echo 'install -y -q --no-install-recommends chromium' | wc -w)" ]
}
unknown_set_is_a_usage_error() {
    : > "$T/installed"
    deps base nonsense 2> "$T/err"; rc=$?
    [ "$rc" -eq 2 ] && grep -q "unknown set 'nonsense'" "$T/err" && [ ! -s "$T/apt" ]
}
non_root_is_told_what_to_install() {
    : > "$T/installed"
    FAKE_UID=1000 deps browser 2> "$T/err"; rc=$?
    [ "$rc" -eq 1 ] && grep -q 'chromium' "$T/err" && [ ! -s "$T/apt" ]
}

check every_set_asked_for_is_installed every_set_asked_for_is_installed
check default_is_base_only default_is_base_only
check installed_packages_are_left_alone installed_packages_are_left_alone
check only_missing_packages_are_installed only_missing_packages_are_installed
check unknown_set_is_a_usage_error unknown_set_is_a_usage_error
check non_root_is_told_what_to_install non_root_is_told_what_to_install
finish
