#!/usr/bin/env bash
# Scene format version 3 on the command line (filters, rays, periodic worlds).
#   cli_v3_test.sh CLI DATA input    bad input (a message naming the line, a
#                                    non-zero exit, nothing printed), `run
#                                    --oracle` on the reference scenes, sim
#                                    refusing what it cannot do, `gen`'s
#                                    filters, rays and periodic worlds,
#                                    --arrays against --oracle on them
#   cli_v3_test.sh CLI DATA rays     every structure of `list` and the lean
#                                    path on the reference scenes with rays
#                                    and no filters
#   cli_v3_test.sh CLI DATA filters  every structure of `list` and the lean
#                                    path on the reference scenes with filters
#   cli_v3_test.sh CLI DATA periodic every structure of `list` and the lean
#                                    path on the periodic reference scenes and
#                                    on ones `gen` makes
set -u
cli=$1
data=$2
mode=$3
fail=0
pass=0
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# shellcheck source=support/cli_checks.sh
. "$(dirname "$0")/support/cli_checks.sh"

has_filters() { grep -q '^\(sphere\|box\) .* filter ' "$1"; }
is_periodic() { grep -q '^world .* periodic ' "$1"; }

# Every structure of `list` prints the expected lines of the reference
# scenes of one kind (periodic: periodic worlds; rays: other scenes without
# object filters; filters: with).
replay_all() {  # replay_all rays|filters|periodic
  local algos
  algos=$(replayed_structures)
  [ -n "$algos" ] || { echo "FAIL: list printed nothing"; fail=$((fail + 1)); return; }
  for s in "$data"/scenes/v3/*.scene; do
    if is_periodic "$s"; then
      [ "$1" = periodic ] || continue
    elif has_filters "$s"; then [ "$1" = filters ] || continue; else [ "$1" = rays ] || continue; fi
    exp=${s%.scene}.expected
    frames=$(wc -l <"$exp")
    for a in $algos; do
      "$cli" run --scene "$s" --algo "$a" --frames "$frames" >"$tmp/out" 2>"$tmp/err"
      check "$a on v3/$(basename "$s")" cmp -s "$tmp/out" "$exp"
    done
    # The lean path too, with its filter columns and its rays (wrapping in
    # a periodic world).
    "$cli" run --scene "$s" --arrays --frames "$frames" >"$tmp/out" 2>"$tmp/err"
    check "arrays on v3/$(basename "$s")" cmp -s "$tmp/out" "$exp"
  done
}

bad() {  # bad NAME PATTERN CONTENT: refused by run (a structure and the oracle)
  printf '%b' "$3" >"$tmp/bad.scene"
  expect_error "$1" "$2" run --scene "$tmp/bad.scene" --algo grid-verlet --frames 1
  expect_error "$1 (oracle)" "$2" run --scene "$tmp/bad.scene" --oracle --frames 1
}

input_checks() {
  local h="broadphase-scene 3\nworld 100\nobjects 1\n" o="sphere 1 2 3 4 0 0 0\n"
  bad "version 4" "bad.scene:1:" "broadphase-scene 4\nworld 10\nobjects 0\n"
  bad "filter with one value" "bad.scene:4:.*two values" "${h}sphere 1 2 3 4 0 0 0 filter 1\n"
  bad "negative group" "bad.scene:4:.*'-1'" "${h}sphere 1 2 3 4 0 0 0 filter -1 1\n"
  bad "signed mask" "bad.scene:4:" "${h}sphere 1 2 3 4 0 0 0 filter 1 +1\n"
  bad "mask of 2^32" "bad.scene:4:.*2^32" "${h}sphere 1 2 3 4 0 0 0 filter 1 4294967296\n"
  bad "hex mask of 2^32" "bad.scene:4:.*2^32" "${h}box 1 2 3 1 1 1 0 0 0 filter 1 0x100000000\n"
  bad "malformed mask" "bad.scene:4:.*'0xz'" "${h}sphere 1 2 3 4 0 0 0 filter 1 0xz\n"
  bad "filter in version 2" "bad.scene:4:.*broadphase-scene 3" \
    "broadphase-scene 2\nworld 100\nobjects 1\n${o%\\n} filter 1 1\n"
  bad "rays in version 2" "bad.scene:5:.*broadphase-scene 3" \
    "broadphase-scene 2\nworld 100\nobjects 1\n${o}rays 0\n"
  bad "NaN origin" "bad.scene:6:.*'nan'" "${h}${o}rays 1\nray nan 0 0 1 0 0 1\n"
  bad "infinite origin" "bad.scene:6:" "${h}${o}rays 1\nray 0 0 inf 1 0 0 1\n"
  bad "infinite direction" "bad.scene:6:" "${h}${o}rays 1\nray 0 0 0 1 -inf 0 1\n"
  bad "NaN direction" "bad.scene:6:" "${h}${o}rays 1\nray 0 0 0 1 nan 0 1\n"
  bad "direction overflows" "bad.scene:6:.*overflows" "${h}${o}rays 1\nray 0 0 0 1e200 0 0 1\n"
  bad "direction underflows" "bad.scene:6:.*smallest normal" "${h}${o}rays 1\nray 0 0 0 0 1e-170 0 1\n"
  bad "negative tmax" "bad.scene:6:.*negative" "${h}${o}rays 1\nray 0 0 0 1 0 0 -2\n"
  bad "NaN tmax" "bad.scene:6:.*tmax" "${h}${o}rays 1\nray 0 0 0 1 0 0 nan\n"
  bad "missing tmax" "bad.scene:6:" "${h}${o}rays 1\nray 0 0 0 1 0 0\n"
  bad "malformed ray mask" "bad.scene:6:.*ray mask" "${h}${o}rays 1\nray 0 0 0 1 0 0 1 filter 1.5\n"
  bad "fewer rays" "declares 2 rays but has 1" "${h}${o}rays 2\nray 0 0 0 1 0 0 1\n"
  bad "more rays" "bad.scene:7:.*more ray lines" "${h}${o}rays 1\nray 0 0 0 1 0 0 1\nray 0 0 0 1 0 0 1\n"
  bad "ray without block" "bad.scene:5:" "${h}${o}ray 0 0 0 1 0 0 1\n"
  # Periodic worlds: the axes, and the limits on periodic axes.
  local p="broadphase-scene 3\nworld 100 periodic xz\nobjects 1\n"
  bad "periodic without axes" "bad.scene:2:.*needs its axes" "broadphase-scene 3\nworld 100 periodic\nobjects 0\n"
  bad "periodic axis twice" "bad.scene:2:.*twice" "broadphase-scene 3\nworld 100 periodic xyx\nobjects 0\n"
  bad "periodic unknown axis" "bad.scene:2:.*not an axis" "broadphase-scene 3\nworld 100 periodic xw\nobjects 0\n"
  bad "periodic in version 2" "bad.scene:2:.*broadphase-scene 3" "broadphase-scene 2\nworld 100 periodic x\nobjects 0\n"
  bad "periodic centre outside" "bad.scene:4:.*outside \\[0, L\\] on the periodic axis z" "${p}sphere 1 2 101 4 0 0 0\n"
  bad "periodic radius L/2" "bad.scene:4:.*radius '50' is not below L/2" "${p}sphere 1 2 3 50 0 0 0\n"
  bad "periodic half-extent" "bad.scene:4:.*hx '51'" "${p}box 1 2 3 51 1 1 0 0 0\n"
  bad "periodic velocity L" "bad.scene:4:.*vx '-100'" "${p}sphere 1 2 3 4 -100 0 0\n"

  # The oracle prints every reference scene's lines, rays and filters alike.
  for s in "$data"/scenes/v3/*.scene; do
    exp=${s%.scene}.expected
    "$cli" run --scene "$s" --oracle --frames "$(wc -l <"$exp")" >"$tmp/out" 2>"$tmp/err"
    check "oracle on v3/$(basename "$s")" cmp -s "$tmp/out" "$exp"
  done
  # And the version 1 and 2 scenes' lines, unchanged.
  for s in "$data"/scenes/*.scene; do
    exp=${s%.scene}.expected
    "$cli" run --scene "$s" --oracle --frames "$(wc -l <"$exp")" >"$tmp/out" 2>"$tmp/err"
    check "oracle on $(basename "$s")" cmp -s "$tmp/out" "$exp"
  done
  expect_error "--oracle with --arrays" "excludes" run --scene "$data/scenes/single.scene" --oracle --arrays

  # sim refuses periodic worlds rather than replay them with walls.
  expect_error "sim: periodic" "sim does not take periodic worlds yet" \
    sim --scene "$data/scenes/v3/periodic-xyz-300.scene" --frames 1

  # sim knows no filters yet and says so; rays play no part in it.
  expect_error "sim: filters" "sim does not take filters yet" \
    sim --scene "$data/scenes/v3/filter-layers-400.scene" --frames 1
  "$cli" sim --scene "$data/scenes/v3/rays-mixed-300.scene" --frames 2 >"$tmp/out" 2>"$tmp/err"
  check "sim: rays ignored" test $? -eq 0

  # gen: filters and rays written as version 3, deterministic, replayable;
  # the objects are those of the same seed without them.
  "$cli" gen --dist uneven --n 300 --seed 4 --out "$tmp/plain.scene"
  "$cli" gen --dist uneven --n 300 --seed 4 --layers 8 --rays 50 --out "$tmp/a.scene"
  "$cli" gen --dist uneven --n 300 --seed 4 --layers 8 --rays 50 --out "$tmp/b.scene"
  check "gen v3 is deterministic" cmp -s "$tmp/a.scene" "$tmp/b.scene"
  check "gen v3 header" test "$(head -1 "$tmp/a.scene")" = "broadphase-scene 3"
  "$cli" gen --dist uneven --n 300 --seed 4 --rays 50 --out "$tmp/c.scene"
  check "gen v3 keeps the objects" test \
    "$(grep '^sphere\|^box' "$tmp/a.scene" | sed 's/ filter.*//')" = "$(grep '^sphere\|^box' "$tmp/c.scene")"
  "$cli" run --scene "$tmp/plain.scene" --oracle --frames 3 >"$tmp/p"
  "$cli" run --scene "$tmp/c.scene" --oracle --frames 3 | cut -d' ' -f1-3 >"$tmp/q"
  check "gen v3 keeps the pairs" cmp -s "$tmp/p" "$tmp/q"
  "$cli" run --scene "$tmp/a.scene" --oracle --frames 3 >"$tmp/o" 2>"$tmp/err"
  check "gen v3 replays with six fields" test "$(awk '{print NF}' "$tmp/o" | sort -u)" = 6
  "$cli" gen --dist even --n 100 --filters random --out "$tmp/r.scene"
  check "gen --filters random" grep -q ' filter ' "$tmp/r.scene"
  "$cli" run --scene "$tmp/r.scene" --oracle --frames 1 >"$tmp/o"
  check "filters alone print three fields" test "$(awk '{print NF}' "$tmp/o")" = 3
  for k in mixed random lidar axis inside zero; do
    "$cli" gen --dist boxes --n 50 --rays 20 --ray-kind $k --out "$tmp/k.scene" 2>"$tmp/err"
    check "gen --ray-kind $k" test "$(grep -c '^ray ' "$tmp/k.scene")" = 20
    # The lean path's rays print the oracle's lines on every kind of ray.
    "$cli" run --scene "$tmp/k.scene" --oracle --frames 3 >"$tmp/ko" 2>"$tmp/err"
    "$cli" run --scene "$tmp/k.scene" --arrays --frames 3 >"$tmp/ka" 2>"$tmp/err"
    check "arrays = oracle on --ray-kind $k" cmp -s "$tmp/ka" "$tmp/ko"
  done
  "$cli" run --scene "$tmp/a.scene" --algo naive --frames 2 --json >"$tmp/j"
  "$cli" run --scene "$tmp/a.scene" --arrays --frames 2 --json >"$tmp/ja"
  check "arrays json has the oracle's hit totals" python3 -c "import json,sys; a=json.load(open('$tmp/ja')); b=json.load(open('$tmp/j')); sys.exit(0 if all(a[k]==b[k] for k in ['hits_total','hits_hash_total','closest_hash_total','rays']) else 1)"
  check "json has the hit totals" python3 -c "import json,sys; j=json.load(open('$tmp/j')); sys.exit(0 if all(k in j for k in ['hits_total','hits_hash_total','closest_hash_total','rays']) else 1)"
  expect_error "gen: bad ray kind" "ray-kind" gen --dist even --n 10 --rays 3 --ray-kind laser --out "$tmp/x.scene"
  expect_error "gen: bad filters" "filters" gen --dist even --n 10 --filters all --out "$tmp/x.scene"
  expect_error "gen: layers out of range" "layers" gen --dist even --n 10 --layers 33 --out "$tmp/x.scene"
  expect_error "gen: layers with random" "layers" gen --dist even --n 10 --layers 3 --filters random --out "$tmp/x.scene"
  check "gen: nothing written on a bad option" test ! -e "$tmp/x.scene"

  # gen --periodic: the world line in x, y, z order, centres in [0, L] on
  # the periodic axes, sizes below L/2, deterministic.
  "$cli" gen --dist decades --n 300 --seed 3 --periodic zx --out "$tmp/p.scene"
  "$cli" gen --dist decades --n 300 --seed 3 --periodic xz --out "$tmp/q.scene"
  check "gen --periodic is deterministic, axes in order" cmp -s "$tmp/p.scene" "$tmp/q.scene"
  check "gen --periodic world line" test "$(sed -n 2p "$tmp/p.scene")" = "world 1000 periodic xz"
  check "gen --periodic header" test "$(head -1 "$tmp/p.scene")" = "broadphase-scene 3"
  "$cli" gen --dist outside --n 300 --seed 3 --periodic xyz --out "$tmp/o.scene"
  check "gen --periodic wraps the outside kind" awk '/^sphere/ { for (a = 2; a <= 4; ++a) if ($a < 0 || $a > 1000) exit 1; if ($5 >= 500) exit 1 }' "$tmp/o.scene"
  expect_error "gen: periodic without axes" "--periodic" gen --dist even --n 10 --periodic "" --out "$tmp/x.scene"
  expect_error "gen: periodic axis twice" "--periodic.*twice" gen --dist even --n 10 --periodic xx --out "$tmp/x.scene"
  expect_error "gen: periodic bad axis" "--periodic.*not an axis" gen --dist even --n 10 --periodic w --out "$tmp/x.scene"
  check "gen: nothing written on a bad --periodic" test ! -e "$tmp/x.scene"
}

# Every structure on scenes `gen --periodic` makes (slab, tube, bulk, with
# filters and rays), against the oracle's lines.
periodic_gen() {
  local algos
  algos=$(replayed_structures)
  "$cli" gen --dist half-boxes --n 400 --seed 6 --periodic xy --out "$tmp/slab.scene"
  "$cli" gen --dist decades --n 300 --seed 6 --periodic x --layers 4 --out "$tmp/tube.scene"
  "$cli" gen --dist box-decades --n 300 --seed 6 --periodic xyz --filters random --rays 30 \
    --out "$tmp/bulk.scene"
  for s in "$tmp"/slab.scene "$tmp"/tube.scene "$tmp"/bulk.scene; do
    "$cli" run --scene "$s" --oracle --frames 4 >"$tmp/want"
    for a in $algos; do
      "$cli" run --scene "$s" --algo "$a" --frames 4 >"$tmp/out" 2>"$tmp/err"
      check "$a on gen $(basename "$s")" cmp -s "$tmp/out" "$tmp/want"
    done
    "$cli" run --scene "$s" --arrays --frames 4 >"$tmp/out" 2>"$tmp/err"
    check "arrays on gen $(basename "$s")" cmp -s "$tmp/out" "$tmp/want"
  done
  # The lean path over many frames of a periodic world: objects wrap at
  # every face, the tracker's candidates renewed as they go.
  "$cli" gen --dist even --n 600 --seed 9 --periodic xyz --out "$tmp/wrap.scene"
  "$cli" run --scene "$tmp/wrap.scene" --oracle --frames 40 >"$tmp/want"
  "$cli" run --scene "$tmp/wrap.scene" --arrays --frames 40 >"$tmp/out" 2>"$tmp/err"
  check "arrays on 40 frames of gen even 600 xyz" cmp -s "$tmp/out" "$tmp/want"
  "$cli" run --scene "$tmp/bulk.scene" --algo grid-verlet --frames 2 --json >"$tmp/j"
  check "json names the periodic axes and images" python3 -c "import json,sys; j=json.load(open('$tmp/j')); sys.exit(0 if j['periodic'] == 'xyz' and j['images'] > 0 else 1)"
}

case $mode in
  input) input_checks ;;
  rays) replay_all rays ;;
  filters) replay_all filters ;;
  periodic) replay_all periodic; periodic_gen ;;
  *) echo "unknown mode $mode"; exit 2 ;;
esac
echo "$pass passed, $fail failed"
[ $fail -eq 0 ]
