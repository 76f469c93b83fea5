#!/usr/bin/env bash
# broadphase-mpi end to end: the same lines as `broadphase run`, the
# generated mode, --json, and failures that are loud and never hang.
# Usage: cli_mpi_test.sh MPIRUN BROADPHASE_MPI BROADPHASE DATA_DIR
set -u
mpirun=$1
mpi_cli=$2
cli=$3
data=$4
fail=0
pass=0
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1

ok() { pass=$((pass + 1)); }
no() { fail=$((fail + 1)); echo "FAIL: $*"; }
mpi() {  # mpi RANKS ARGS...: bounded, so a hang fails instead of blocking
  local p=$1; shift
  timeout 120 "$mpirun" --oversubscribe -np "$p" "$mpi_cli" "$@"
}

# The same lines as one process, on several ranks and structures.
s=$data/scenes/mixed-400.scene
"$cli" run --scene "$s" --frames 25 >"$tmp/one"
for cfg in "2 --bisect --algo grid-verlet" "3 --grid 3x1x1 --algo grid-hashed" "4 --grid 2x2x1 --algo naive"; do
  set -- $cfg
  p=$1; shift
  mpi "$p" run --scene "$s" --frames 25 "$@" >"$tmp/many" 2>"$tmp/err"
  if cmp -s "$tmp/one" "$tmp/many"; then ok; else no "run -np $p $*: $(head -3 "$tmp/err")"; fi
done

# Generated on the ranks: object i the same whatever the ranks, so the
# same frames as the written file replayed on one process.
"$mpi_cli" gen --gen scaled-uneven --n 3000 --seed 7 --out "$tmp/gen.scene"
"$cli" run --scene "$tmp/gen.scene" --frames 5 >"$tmp/one"
for p in 1 3; do
  mpi "$p" run --gen scaled-uneven --n 3000 --seed 7 --frames 5 --bisect >"$tmp/many" 2>"$tmp/err"
  if cmp -s "$tmp/one" "$tmp/many"; then ok; else no "gen -np $p: $(head -3 "$tmp/err")"; fi
done

# --json: the fields the lab reads.
if mpi 2 run --gen scaled-even --per-rank 2000 --frames 3 --json >"$tmp/json" 2>"$tmp/err" &&
  python3 - "$tmp/json" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
for k in ("ranks", "phases", "ghosts_per_rank", "bytes_per_rank_per_frame",
          "messages_per_rank_per_frame", "load_imbalance_last", "hash_total", "balance_by"):
    assert k in j, k
for k in ("local_pairs", "ghost_exchange", "migration", "balancing", "reduction"):
    assert k in j["phases"], k
assert j["ranks"] == 2 and len(j["ghosts_per_rank"]) == 2
PY
then ok; else no "--json: $(cat "$tmp/err")"; fi

# A skin: the same frames, with ghost lists kept on most of them (slow
# movers, a skin of 20 units), and rebuilt on every frame at a skin of 0.
d=$data/mpi/decades.scene
"$cli" run --scene "$d" --frames 60 >"$tmp/one"
for sk in 0 20; do
  if mpi 3 run --scene "$d" --frames 60 --bisect --skin "$sk" --json >"$tmp/json" 2>"$tmp/err" &&
    python3 - "$tmp/json" "$tmp/one" "$sk" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
lines = open(sys.argv[2]).read().split()
pairs = sum(int(lines[k]) for k in range(1, len(lines), 3))
assert j["pairs_total"] == pairs, (j["pairs_total"], pairs)
hashes = sum(int(lines[k], 16) for k in range(2, len(lines), 3)) % 2**64
assert int(j["hash_total"], 16) == hashes, (j["hash_total"], hashes)
assert j["skin"] == float(sys.argv[3])
if j["skin"] == 0:
    assert j["rebuilds"] == 60, j["rebuilds"]
else:
    assert 1 <= j["rebuilds"] <= 20, j["rebuilds"]
PY
  then ok; else no "--skin $sk: $(cat "$tmp/err")"; fi
done

# Version 3 scenes with filters: the lines of `broadphase run` and of its
# brute-force oracle, and the .expected files, on 1 to 4 ranks, grids,
# bisection, a skin and a registry structure; generated worlds of random
# bits and of 4 and 16 layers (moving, uneven, over many frames) too.
"$cli" gen --dist uneven --n 1500 --seed 21 --layers 4 --out "$tmp/layers4.scene"
"$cli" gen --dist scaled-uneven --n 1500 --seed 22 --layers 16 --out "$tmp/layers16.scene"
"$cli" gen --dist decades --n 1500 --seed 23 --filters random --out "$tmp/random.scene"
for f in "$data"/scenes/v3/filter-layers-400.scene "$data"/scenes/v3/filter-random-400.scene \
  "$data"/scenes/v3/gen-random-400.scene "$tmp"/layers4.scene "$tmp"/layers16.scene \
  "$tmp"/random.scene; do
  frames=30
  e=${f%.scene}.expected
  [ -f "$e" ] && frames=$(wc -l <"$e")
  "$cli" run --scene "$f" --frames "$frames" --algo grid-verlet >"$tmp/one"
  "$cli" run --scene "$f" --frames "$frames" --oracle >"$tmp/oracle"
  if cmp -s "$tmp/one" "$tmp/oracle"; then ok; else no "$(basename "$f"): run and its oracle differ"; fi
  if [ ! -f "$e" ] || cmp -s "$tmp/one" "$e"; then ok; else no "$(basename "$f"): .expected differs"; fi
  for cfg in "1" "2 --grid 2x1x1" "3 --bisect" "4 --grid 2x2x1" "4 --bisect --skin 2" \
    "3 --grid 3x1x1 --algo grid-hashed"; do
    set -- $cfg
    p=$1; shift
    mpi "$p" run --scene "$f" --frames "$frames" "$@" >"$tmp/many" 2>"$tmp/err"
    if cmp -s "$tmp/one" "$tmp/many"; then ok; else
      no "$(basename "$f") -np $p $*: $(head -3 "$tmp/err") $(diff "$tmp/one" "$tmp/many" | head -4)"
    fi
  done
done
# The filters are in the lines: the same scenes without them pair more.
sed 's/ filter [^ ]* [^ ]*$//' "$tmp/layers4.scene" >"$tmp/nofilter.scene"
mpi 2 run --scene "$tmp/nofilter.scene" --frames 3 >"$tmp/many" 2>"$tmp/err"
"$cli" run --scene "$tmp/layers4.scene" --frames 3 >"$tmp/one"
if [ "$(awk '{s += $2} END {print s}' "$tmp/many")" -gt "$(awk '{s += $2} END {print s}' "$tmp/one")" ]
then ok; else no "the layers' filters rule out no pair: $(cat "$tmp/err")"; fi
# Rays: the lines of `broadphase run --oracle` (hits, hits_hash,
# closest_hash), with and without filters, on a grid, bisection and a skin;
# a scene generated with layered filters and rays, moving over 30 frames.
# (mpi_check_filters_* cover the reference ray scenes at 2 to 4 ranks.)
"$cli" gen --dist uneven --n 1200 --seed 24 --layers 4 --rays 50 --out "$tmp/rays.scene"
for cfg in "rays-mixed-300 2 --grid 2x1x1" "gen-layers-rays-400 3 --bisect" \
  "gen-layers-rays-400 4 --grid 2x2x1 --skin 2" "generated 3 --grid 3x1x1"; do
  set -- $cfg
  f=$data/scenes/v3/$1.scene
  [ "$1" = generated ] && f=$tmp/rays.scene
  p=$2; shift 2
  "$cli" run --scene "$f" --frames 30 --oracle >"$tmp/oracle"
  mpi "$p" run --scene "$f" --frames 30 "$@" >"$tmp/many" 2>"$tmp/err"
  if cmp -s "$tmp/oracle" "$tmp/many"; then ok; else
    no "$(basename "$f") -np $p $*: $(head -3 "$tmp/err") $(diff "$tmp/oracle" "$tmp/many" | head -4)"
  fi
done
# The rays are in the lines: six columns, some hits.
if awk 'NF != 6 {bad = 1} {s += $4} END {exit bad || s == 0}' "$tmp/many"; then ok; else
  no "ray lines: $(head -2 "$tmp/many")"
fi
# --json sums the hits as `broadphase run --json` does.
mpi 2 run --scene "$tmp/rays.scene" --frames 30 --bisect --json >"$tmp/json" 2>"$tmp/err"
"$cli" run --scene "$tmp/rays.scene" --frames 30 --json >"$tmp/one_json"
if python3 - "$tmp/json" "$tmp/one_json" <<'PY'
import json, sys
many, one = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
for k in ("hits_total", "hits_hash_total", "closest_hash_total"):
    assert many[k] == one[k], (k, many[k], one[k])
assert "rays" in many["phases"]
PY
then ok; else no "--json with rays: $(cat "$tmp/err")"; fi

# Failures: every rank exits non-zero, the message printed, no hang.
expect_fail() {  # expect_fail NAME PATTERN RANKS ARGS...
  local name=$1 pattern=$2; shift 2
  mpi "$@" >"$tmp/out" 2>"$tmp/err"
  local rc=$?
  if [ $rc -ne 0 ] && [ $rc -ne 124 ] && grep -q -- "$pattern" "$tmp/err"; then ok; else
    no "$name (exit $rc): $(head -5 "$tmp/err")"
  fi
}
printf 'broadphase-scene 1\nworld 100\nobjects 3\n1 2 3 1 0 0 0\n1 2 x 1 0 0 0\n4 5 6 1 0 0 0\n' >"$tmp/bad.scene"
expect_fail "bad scene line read by rank 0" "bad.scene:5" 3 run --scene "$tmp/bad.scene"
expect_fail "missing scene" "nowhere.scene" 2 run --scene "$tmp/nowhere.scene"
expect_fail "a periodic world" "periodic world, which broadphase-mpi does not take yet" 2 \
  run --scene "$data/scenes/v3/periodic-xyz-300.scene"
expect_fail "unknown structure" "no-such" 2 run --scene "$s" --algo no-such
expect_fail "grid that does not fit" "does not fit" 2 run --scene "$s" --grid 3x1x1
expect_fail "unknown balance weight" "balance-by" 2 run --scene "$s" --bisect --balance-by cost
expect_fail "a skin with a structure" "lean path" 2 run --scene "$s" --algo grid-hashed --skin 1
BROADPHASE_MPI_FAIL=1:3 expect_fail "a rank that throws" "injected failure at frame 3" 3 run --scene "$s"
if [ "$(wc -l <"$tmp/out")" -eq 3 ]; then ok; else no "frames before the failure: $(cat "$tmp/out")"; fi
BROADPHASE_MPI_FAIL=2:2:abort expect_fail "a rank that throws outside a collective step" \
  "outside an agreed phase" 3 run --scene "$s"
# Motion beyond the doubles: the one-process message, after the frames before.
printf 'broadphase-scene 1\nworld 1e308\nobjects 2\n1e308 1 1 1 1e308 0 0\n5 5 5 1 0 0 0\n' >"$tmp/over.scene"
"$cli" run --scene "$tmp/over.scene" --frames 3 >"$tmp/one" 2>"$tmp/one_err"
expect_fail "motion that overflows" "$(sed 's/.*error: //' "$tmp/one_err")" 2 run --scene "$tmp/over.scene" --frames 3
if cmp -s "$tmp/one" "$tmp/out"; then ok; else no "frames before the overflow differ"; fi

# More ranks than objects.
mpi 5 run --scene "$data/scenes/touching.scene" --frames 6 --bisect >"$tmp/many" 2>"$tmp/err"
if cmp -s "$data/scenes/touching.expected" "$tmp/many"; then ok; else no "5 ranks, 8 objects"; fi

echo "cli_mpi_test: $pass passed, $fail failed"
[ $fail -eq 0 ]
