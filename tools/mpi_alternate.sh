#!/usr/bin/env bash
# Weak scaling 1 -> 2 ranks, alternated: for each repeat and configuration,
# the same one-rank run twice at once (the machine's two-process ceiling),
# then the two-rank run, so that both see the host as it is at that moment.
# Writes one --json per run into OUT and alternated.md
# (tools/mpi_alternate_summary.py).
#
# Usage: [SKIN=10] tools/mpi_alternate.sh OUT [REPEATS] [PER_RANK] [FRAMES]
#   (defaults 4 repeats, 1024000 objects per rank, 10 frames; every
#   configuration runs with no skin and with SKIN, SKIN=0 runs no skin only)
set -eu
out=$1
repeats=${2:-4}
per=${3:-1024000}
frames=${4:-10}
skin=${SKIN:-10}
bin=${BROADPHASE_MPI:-build/apps/broadphase-mpi/broadphase-mpi}
mkdir -p "$out"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
run() {  # run FILE RANKS ARGS... (unbound: see tools/mpi_bench.sh)
  local f=$1 p=$2; shift 2
  timeout 3000 mpirun --oversubscribe --bind-to none -np "$p" "$bin" run --json "$@" >"$out/$f"
}
uptime >"$out/load.txt"
for rep in $(seq 1 "$repeats"); do
  skins="0 $skin"
  [ "$skin" = 0 ] && skins=0
  for sk in $skins; do
    for kind in scaled-even scaled-uneven; do
      dec=--bisect
      [ "$kind" = scaled-even ] && dec="--grid 2x1x1"
      one=""
      [ "$kind" = scaled-even ] && one="--grid 1x1x1"
      f=$kind-s$sk-r$rep
      run "$f-a.json" 1 --gen "$kind" --per-rank "$per" --frames "$frames" $one --skin "$sk" &
      run "$f-b.json" 1 --gen "$kind" --per-rank "$per" --frames "$frames" $one --skin "$sk"
      wait
      run "$f-p2.json" 2 --gen "$kind" --per-rank "$per" --frames "$frames" $dec --skin "$sk"
      echo "$(date -u +%T) $f done" >&2
    done
  done
done
uptime >>"$out/load.txt"
python3 "$(dirname "$0")/mpi_alternate_summary.py" "$out" >"$out/alternated.md"
