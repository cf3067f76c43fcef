#!/bin/sh
# test_commit_messages: every commit since the rule was set has a subject of at most 72
# characters, then a blank line before any body (.gitmessage is the template).
# test-light
. tests/lib.sh

# The first commit written under the rule; older subjects are history.
FIRST=5d1a29e

# long_subjects RANGE: "hash subject" of each commit in RANGE whose subject is over 72.
long_subjects() {
    git log --no-merges --format='%h %s' "$1" | awk '{ h = $1; sub(/^[^ ]+ /, ""); if (length($0) > 72) print h " " $0 }'
}
# glued_bodies RANGE: commits whose second line is not blank (a subject wrapped onto the body).
glued_bodies() {
    for h in $(git log --no-merges --format=%h "$1"); do
        git log -1 --format=%B "$h" | sed -n 2p | grep -q . && echo "$h"
    done
}

subjects_fit() {
    v=$(long_subjects "$FIRST^..HEAD")
    [ -z "$v" ] || { echo "subjects over 72 characters:"; echo "$v"; return 1; }
}
bodies_follow_a_blank_line() {
    v=$(glued_bodies "$FIRST^..HEAD")
    [ -z "$v" ] || { echo "no blank line after the subject: $v"; return 1; }
}
# The check is live: the history before the rule has long subjects, and they are caught.
a_long_subject_is_caught() {
    [ -n "$(long_subjects "$FIRST~20..$FIRST~1")" ]
}

if ! git rev-parse --verify -q "$FIRST^{commit}" >/dev/null 2>&1; then
    # A tree without its history (git archive, a shallow clone) has no commits to read.
    skip "commit subjects fit 72 characters" "no git history here"
    finish
fi
check "commit subjects fit 72 characters" subjects_fit
check "a blank line follows each subject" bodies_follow_a_blank_line
check "a long subject is caught" a_long_subject_is_caught
finish
