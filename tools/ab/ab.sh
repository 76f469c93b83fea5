#!/usr/bin/env bash
# Frame-interleaved A/B of the library at a past commit (A) against the
# working tree (B), in one process (see ab.cpp):
#   tools/ab/ab.sh COMMIT SCENE [FRAMES] [SPEC1] [SPEC2] [BLOCK]
# e.g. tools/ab/ab.sh HEAD~3 /tmp/se102k.scene 100 grid-verlet grid-verlet:threads=2
# Both sides are compiled here with g++ (-O3, as the Release build), each
# with its namespace renamed, into a work directory under /tmp.
set -euo pipefail
[ $# -ge 2 ] || { sed -n '2,7p' "$0"; exit 2; }
root="$(cd "$(dirname "$0")/../.." && pwd)"
commit=$1 scene=$2 frames=${3:-100} spec1=${4:-grid-verlet} spec2=${5:-grid-verlet:threads=2} block=${6:-5}
work=$(mktemp -d /tmp/broadphase-ab.XXXXXX)
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/A"
git -C "$root" archive "$commit" include src | tar -x -C "$work/A"
flags="-std=c++20 -O3 -DNDEBUG -ffp-contract=off -pthread"
build_side() {  # side, tree
  local side=$1 tree=$2 obj="$work/obj$1"
  mkdir -p "$obj"
  # src/mpi/ (src/distributed/ in older commits) is broadphase::mpi (needs
  # mpi.h), src/bullet/ and src/fcl/ the engines' adapters (their headers):
  # not the library under test.
  find "$tree/src" -name '*.cpp' -not -path '*/distributed/*' -not -path '*/mpi/*' \
    -not -path '*/bullet/*' -not -path '*/fcl/*' |
    xargs -P "$(nproc)" -I{} sh -c \
      'g++ '"$flags"' -Dbroadphase=bp'"$side"' -I'"$tree"'/include -c "$1" -o '"$obj"'/$(echo "$1" | md5sum | cut -c1-12).o' _ {}
  g++ $flags -Dbroadphase=bp"$side" -DSIDE="$side" -I"$tree/include" -I"$root/tools/ab" \
    -c "$root/tools/ab/runner.cpp" -o "$obj/runner.o"
  ar rcs "$work/lib$side.a" "$obj"/*.o
}
echo "building A ($commit) and B (working tree)..." >&2
build_side A "$work/A"
build_side B "$root"
g++ $flags -I"$root/tools/ab" -I"$root/include" "$root/tools/ab/ab.cpp" "$work/libA.a" "$work/libB.a" -o "$work/ab"
"$work/ab" "$scene" "$frames" "$spec1" "$spec2" "$block"
