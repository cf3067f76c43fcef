#!/bin/sh
# gen-man-completion.sh: a man page and a bash completion for each program, made from its own
# --help (run with a time limit, 30 s for a loaded machine; a program whose --help fails gets
# neither, and is named on stderr).
#   scripts/gen-man-completion.sh OUTDIR PROGRAM...   writes OUTDIR/man1/NAME.1, OUTDIR/completions/NAME
set -u
out=$1; shift
mkdir -p "$out/man1" "$out/completions"
version=$(sed -n 's/^#define MARIE_VERSION "\(.*\)"/\1/p' "$(dirname "$0")/../core/version.h")
roff() { sed -e 's/\\/\\\\/g' -e 's/^\./\\\&./' -e "s/^'/\\\\\&'/" -e 's/^-/\\-/'; }
for prog in "$@"; do
    name=$(basename "$prog")
    help=$(timeout 30 "$prog" --help < /dev/null 2>&1) || { echo "$name: --help failed: no man page" >&2; continue; }
    [ -n "$help" ] || continue
    {
        printf '.TH %s 1 "" "marie %s" "marie"\n.SH NAME\n%s \\- a program of marie, the robotics integration stack\n' \
            "$(echo "$name" | tr a-z A-Z)" "$version" "$name"
        printf '.SH SYNOPSIS AND OPTIONS\n.nf\n'
        echo "$help" | roff
        printf '.fi\n.SH SEE ALSO\nmarie(1); the docs/ folder of marie, docs/cli.md and docs/python.md\n'
    } > "$out/man1/$name.1"
    opts=$(echo "$help" | grep -o -- '--[a-z][a-z0-9-]*' | sort -u | tr '\n' ' ')
    if [ "$name" = marie ]; then
        # marie's own commands, and the marie-X programs `marie X` runs
        cmds=$(echo "$help" | sed -n 's/^  \([a-z][a-z|]*\) .*/\1/p' | tr '|' ' ' | tr '\n' ' ')
        for p in "$@"; do b=$(basename "$p"); case $b in marie-*) cmds="$cmds ${b#marie-}" ;; esac; done
        cmds=$(printf '%s\n' $cmds | sort -u | tr '\n' ' ')
        cat > "$out/completions/$name" <<C
# bash completion for marie (generated from marie --help by scripts/gen-man-completion.sh)
_marie() {
    local cur=\${COMP_WORDS[COMP_CWORD]}
    if [ "\$COMP_CWORD" -eq 1 ]; then
        COMPREPLY=(\$(compgen -W "$cmds $opts" -- "\$cur"))
    else
        COMPREPLY=(\$(compgen -f -W "$opts" -- "\$cur"))
    fi
}
complete -F _marie marie
C
    else
        printf '# bash completion for %s (generated from its --help)\ncomplete -f -W "%s" %s\n' "$name" "$opts" "$name" \
            > "$out/completions/$name"
    fi
done
