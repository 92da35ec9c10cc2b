#!/bin/sh
# Same numbers check (issue 25): run every deck of inputs/seed and
# inputs/demo with two beamid-batch executables, each in a fresh copy of the
# input folders, and compare every output file byte for byte.
#
#   tools/compare_outputs.sh BASE_BATCH NEW_BATCH [WORKDIR]
#
# BASE_BATCH: beamid-batch built from main (the reference), NEW_BATCH: the
# one under test (build/cp311/beamid-batch). Exit 0 when every deck gives the
# same exit code and byte-identical files, 1 otherwise (the differing files
# are listed). WORKDIR (default: a new temporary folder) keeps both runs.
set -u
base=$1
new=$2
root=$(cd "$(dirname "$0")/.." && pwd)
work=${3:-$(mktemp -d /tmp/beamid_compare.XXXXXX)}
status=0
for side in base new; do
    mkdir -p "$work/$side"
    cp -r "$root/inputs/seed" "$root/inputs/demo" "$work/$side/"
done
for deck in $(cd "$root/inputs" && ls seed/*.nml demo/*.nml); do
    (cd "$work/base/$(dirname "$deck")" && "$base" --quiet "$(basename "$deck")" \
        >/dev/null 2>"$(basename "$deck").err"; echo $? > "$(basename "$deck").rc")
    (cd "$work/new/$(dirname "$deck")" && "$new" --quiet "$(basename "$deck")" \
        >/dev/null 2>"$(basename "$deck").err"; echo $? > "$(basename "$deck").rc")
done
if diff -r "$work/base" "$work/new" > "$work/diff.txt"; then
    echo "same: every output of $(cd "$root/inputs" && ls seed/*.nml demo/*.nml | wc -l) decks is byte-identical ($work)"
else
    echo "DIFFERENT outputs (see $work/diff.txt):"
    grep -E '^(diff|Only|Binary)' "$work/diff.txt" | head -40
    status=1
fi
exit $status
