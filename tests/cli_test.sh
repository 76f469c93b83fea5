#!/usr/bin/env bash
# The CLI against the reference scenes and on bad input: exact output,
# clear messages, non-zero exits, no crash.
set -u
cli=$1
data=$2
fail=0
pass=0
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# shellcheck source=support/cli_checks.sh
. "$(dirname "$0")/support/cli_checks.sh"

# Every structure of `list` reproduces every reference scene exactly.
algos=$(replayed_structures)
[ -n "$algos" ] || { echo "FAIL: list printed nothing"; exit 1; }
for a in $algos; do
  for s in "$data"/scenes/*.scene; do
    exp=${s%.scene}.expected
    frames=$(wc -l <"$exp")
    "$cli" run --scene "$s" --algo "$a" --frames "$frames" >"$tmp/out" 2>"$tmp/err"
    check "$a on $(basename "$s")" cmp -s "$tmp/out" "$exp"
  done
done
# The lean path over arrays (run --arrays) reproduces them too.
for s in "$data"/scenes/*.scene; do
  exp=${s%.scene}.expected
  "$cli" run --scene "$s" --arrays --frames "$(wc -l <"$exp")" >"$tmp/out" 2>"$tmp/err"
  check "arrays on $(basename "$s")" cmp -s "$tmp/out" "$exp"
done

# Bad input: a message naming the file and line, a non-zero exit, no crash.
bad() {  # bad NAME PATTERN CONTENT
  printf '%b' "$3" >"$tmp/bad.scene"
  expect_error "$1" "$2" run --scene "$tmp/bad.scene" --algo naive --frames 1
}
bad "wrong header" "bad.scene:1:" "broadphase-scene 4\nworld 10\nobjects 0\n"
bad "missing field" "bad.scene:4:" "broadphase-scene 1\nworld 10\nobjects 1\n1 2 3 4 0 0\n"
bad "extra field" "bad.scene:4:" "broadphase-scene 1\nworld 10\nobjects 1\n1 2 3 4 0 0 0 9\n"
bad "not a number" "bad.scene:4:.*'abc'" "broadphase-scene 1\nworld 10\nobjects 1\n1 abc 3 4 0 0 0\n"
bad "nan" "bad.scene:4:" "broadphase-scene 1\nworld 10\nobjects 1\n1 nan 3 4 0 0 0\n"
bad "infinity" "bad.scene:4:" "broadphase-scene 1\nworld 10\nobjects 1\n1 2 inf 4 0 0 0\n"
bad "negative radius" "bad.scene:5:.*negative" "broadphase-scene 1\nworld 10\nobjects 2\n1 2 3 4 0 0 0\n1 2 3 -4 0 0 0\n"
bad "count too high" "declares 2 objects but has 1" "broadphase-scene 1\nworld 10\nobjects 2\n1 2 3 4 0 0 0\n"
bad "count too low" "bad.scene:5:.*more object lines" "broadphase-scene 1\nworld 10\nobjects 1\n1 2 3 4 0 0 0\n1 2 3 4 0 0 0\n"
bad "bad world" "bad.scene:2:" "broadphase-scene 1\nworld -1\nobjects 0\n"
bad "box in v1" "bad.scene:4:" "broadphase-scene 1\nworld 10\nobjects 1\nbox 1 2 3 1 1 1 0 0 0\n"
bad "negative half" "bad.scene:4:.*negative" "broadphase-scene 2\nworld 10\nobjects 1\nbox 1 2 3 1 -1 1 0 0 0\n"
bad "unknown kind" "bad.scene:4:.*'cone'" "broadphase-scene 2\nworld 10\nobjects 1\ncone 1 2 3 1 0 0 0\n"
expect_error "missing file" "cannot open" run --scene "$tmp/none.scene" --algo naive
expect_error "unknown algorithm" "valid: naive" run --scene "$data/scenes/single.scene" --algo nope
expect_error "unknown option" "unknown option" run --scene "$data/scenes/single.scene" --algo naive:foo=1
expect_error "option without a value" "not of the form key=value" run --scene "$data/scenes/single.scene" --algo grid-verlet:threads
expect_error "option given twice" "option 'threads' is given twice" run --scene "$data/scenes/single.scene" --algo grid-verlet:threads=2,threads=1
expect_error "bad frames" "frames" run --scene "$data/scenes/single.scene" --algo naive --frames 0
expect_error "bad dist" "dist" gen --dist lumpy --n 10 --out "$tmp/x.scene"

# A motion that overflows the doubles: the frames before it are printed,
# then an error naming the frame and the object.
printf 'broadphase-scene 1\nworld 1e300\nobjects 2\n0 0 0 1 0 0 0\n1.79e308 0 0 1 1e306 0 0\n' >"$tmp/overflow.scene"
"$cli" run --scene "$tmp/overflow.scene" --algo grid-verlet --frames 3 >"$tmp/out" 2>"$tmp/err"
rc=$?
check "overflowing motion: exit" test "$rc" -eq 1
check "overflowing motion: frame 0 printed" test "$(cat "$tmp/out")" = "0 0 0000000000000000"
check "overflowing motion: message" grep -q "frame 1: object 1 moves beyond the range of doubles" "$tmp/err"

# Comments and blank lines anywhere after line 1; r = 0 is valid.
printf 'broadphase-scene 1\n# c\n\nworld 10\n# c\nobjects 2\n\n1 1 1 0 0 0 0\n# c\n1 1 1 0 0 0 0\n' >"$tmp/ok.scene"
# splitmix64((0 << 32) | 1) is the hash of the single pair (0, 1).
check "comments and zero radius" test "$("$cli" run --scene "$tmp/ok.scene" --frames 1)" = "0 1 910a2dec89025cc1"

# gen writes a scene that reads back; the same seed gives the same file.
"$cli" gen --dist uneven --n 500 --seed 3 --out "$tmp/a.scene"
"$cli" gen --dist uneven --n 500 --seed 3 --out "$tmp/b.scene"
check "gen is deterministic" cmp -s "$tmp/a.scene" "$tmp/b.scene"
check "gen output replays" test "$("$cli" run --scene "$tmp/a.scene" --frames 3 | wc -l)" = 3
"$cli" run --scene "$tmp/a.scene" --frames 2 --json >"$tmp/j" 
check "json has the fields" python3 -c "import json,sys; j=json.load(open('$tmp/j')); sys.exit(0 if all(k in j for k in ['algo','n','frames','pairs_total','hash_total','tests_total','median_frame_ms','total_ms','memory_bytes']) and len(j['hash_total'])==16 else 1)"

# advise: times the structures named, checks their pairs against each other
# and recommends one of those that agree.
"$cli" advise --scene "$tmp/a.scene" --algos naive,grid-hashed,grid-verlet --frames 6 --seconds 3 \
  --json >"$tmp/adv" 2>/dev/null
check "advise recommends an agreeing structure" python3 -c "
import json, sys
j = json.load(open('$tmp/adv'))
s = {x['structure']: x for x in j['structures']}
ok = sorted(s) == ['grid-hashed', 'grid-verlet', 'naive'] and all(x['pairs_agree'] for x in s.values())
ok = ok and j['recommended'] in s and all(x['frames'] >= 1 and x['mean_frame_ms'] > 0 for x in s.values())
sys.exit(0 if ok else 1)"
check "advise times a query, an insert and a remove of every structure" python3 -c "
import json, sys
j = json.load(open('$tmp/adv'))
sys.exit(0 if all(x[k] > 0 for x in j['structures'] for k in ('query_us', 'insert_us', 'remove_us')) else 1)"
expect_error "advise: unknown algorithm" "nope" advise --scene "$tmp/a.scene" --algos naive,nope
expect_error "advise: missing scene" "cannot open" advise --scene "$tmp/none.scene"

echo "$pass passed, $fail failed"
[ $fail -eq 0 ]
