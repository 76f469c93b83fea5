#!/usr/bin/env bash
# The lab's MPI section (not part of `broadphase paper`): weak scaling of
# broadphase-mpi from 1 to 2 ranks beside the machine's ceiling (two
# independent one-rank runs at once), the decomposition's machine-independent
# figures for P = 1..16, the targets at 1 024 000 objects per rank, and
# identical hashes over the rank counts. Writes one JSON file per run into
# OUT and a summary (summary.md) from tools/mpi_bench_summary.py.
#
# Usage: [SKIN=10] [WEAK_ONLY=1] tools/mpi_bench.sh OUT [PER_RANK] [FRAMES]
#   (defaults 1024000 objects per rank, 10 frames; WEAK_ONLY=1 runs the
#   weak scaling alone, for repeats)
set -eu
out=$1
per=${2:-1024000}
frames=${3:-10}
bin=${BROADPHASE_MPI:-build/apps/broadphase-mpi/broadphase-mpi}
mkdir -p "$out"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
# --bind-to none: mpirun binds a lone rank to core 0, so the two one-rank
# runs of the ceiling, started by two mpiruns, shared core 0 (the ceiling of
# the run of 2026-11-25 was one core time-shared: 40% efficiency). Unbound,
# the system spreads them, and the two-rank runs alike.
run() {  # run FILE RANKS ARGS...
  local f=$1 p=$2; shift 2
  timeout 3000 mpirun --oversubscribe --bind-to none -np "$p" "$bin" run --json "$@" >"$out/$f"
  echo "$(date -u +%T) $f done" >&2
}
uptime >"$out/load.txt"

# Weak scaling: scaled-even on a grid, scaled-uneven on a bisection; every
# frame afresh, then with a skin of $SKIN units (default 10; the movers go
# up to 2 units a frame).
skin=${SKIN:-10}
for variant in "" "-skin"; do
  extra=""
  [ -n "$variant" ] && extra="--skin $skin"
  for kind in scaled-even scaled-uneven; do
    dec=--bisect
    [ "$kind" = scaled-even ] && dec="--grid 2x1x1"
    one=""
    [ "$kind" = scaled-even ] && one="--grid 1x1x1"
    f="weak-$kind$variant"
    run "$f-p1.json" 1 --gen "$kind" --per-rank "$per" --frames "$frames" $one $extra
    # The ceiling: the same one-rank run twice at once.
    run "$f-pair-a.json" 1 --gen "$kind" --per-rank "$per" --frames "$frames" $one $extra &
    run "$f-pair-b.json" 1 --gen "$kind" --per-rank "$per" --frames "$frames" $one $extra
    wait
    run "$f-p2.json" 2 --gen "$kind" --per-rank "$per" --frames "$frames" $dec $extra
  done
done

if [ -n "${WEAK_ONLY:-}" ]; then
  uptime >>"$out/load.txt"
  python3 "$(dirname "$0")/mpi_bench_summary.py" "$out" >"$out/summary.md"
  exit 0
fi

# Targets at 1 024 000 per rank, decomposition only (no pairs).
run "ghosts-scaled-even-p8-2x2x2.json" 8 --gen scaled-even --per-rank 1024000 --frames 1 \
  --grid 2x2x2 --skip-local
run "imbalance-scaled-uneven-p8-bisect.json" 8 --gen scaled-uneven --per-rank 1024000 --frames 2 \
  --bisect --skip-local

# Identical hashes at 8 192 000 objects: one process against 8 ranks (2x2x2),
# pairs included, every rank generating its share.
run "hash-big-p1.json" 1 --gen scaled-even --n 8192000 --frames 3 --grid 1x1x1
run "hash-big-p8.json" 8 --gen scaled-even --n 8192000 --frames 3 --grid 2x2x2

# Identical hashes over the rank counts (one scene, full pairs).
for p in 1 2 3 4 8; do
  run "hash-p$p.json" "$p" --gen scaled-uneven --n 32000 --frames 3 --bisect
done

# Figures for P = 1..16 at 32 000 objects per rank, decomposition only.
for p in $(seq 1 16); do
  run "figures-even-p$p.json" "$p" --gen scaled-even --per-rank 32000 --frames 2 --skip-local
  run "figures-uneven-p$p.json" "$p" --gen scaled-uneven --per-rank 32000 --frames 2 --bisect \
    --skip-local
done
uptime >>"$out/load.txt"
python3 "$(dirname "$0")/mpi_bench_summary.py" "$out" >"$out/summary.md"
