#!/usr/bin/env bash
# The FCL example on our manager prints what it prints on FCL's dynamic
# AABB tree: the same contacts every step and the same nearest distance.
set -u
here=$(cd "$(dirname "$0")" && pwd)
cli=$1
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
pass=0 fail=0
source "$here/../support/cli_checks.sh"
"$cli" >"$tmp/ours"
"$cli" fcl >"$tmp/theirs"
cat "$tmp/ours"
check "same output as on FCL's tree" cmp -s "$tmp/ours" "$tmp/theirs"
check "five steps with contacts" test "$(grep -c '^step [0-9]: [1-9][0-9]* contacts$' "$tmp/ours")" = 5
check "a nearest distance" grep -q '^probe: nearest object at [0-9.]*$' "$tmp/ours"
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
