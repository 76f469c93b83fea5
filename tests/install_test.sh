#!/usr/bin/env bash
# Installs the library into a temporary prefix, builds the README example
# against it with find_package(broadphase), and runs it; with a fourth
# argument ON, also the MPI example (find_package(broadphase COMPONENTS
# mpi), broadphase::mpi) on two ranks.
set -eu
build=$1
src=$2
flags=${3:-}
mpi=${4:-OFF}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cmake --install "$build" --prefix "$tmp/prefix" >/dev/null
cmake -S "$src/tests/install" -B "$tmp/consumer" -DCMAKE_PREFIX_PATH="$tmp/prefix" \
  -DEXAMPLE_SOURCE="$src/examples/quickstart.cpp" -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_FLAGS="$flags" \
  -DWITH_MPI="$mpi" -DMPI_EXAMPLE_SOURCE="$src/examples/mpi.cpp" >/dev/null
cmake --build "$tmp/consumer" >/dev/null
out=$("$tmp/consumer/quickstart")
echo "$out"
expected='pair 1-2
touches 2
touches 3
3 narrow-phase tests'
if [ "$out" != "$expected" ]; then echo "0 passed, 1 failed"; exit 1; fi
if [ "$("$tmp/consumer/quickstart_old_names")" != "$expected" ]; then
  echo "broadphase::lab (the former name of broadphase::scenes) no longer links"
  echo "0 passed, 1 failed"; exit 1
fi
if [ "$mpi" = ON ]; then
  # Bounded: an MPI program that hangs fails the test instead.
  out=$(OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 timeout 120 \
    mpirun --oversubscribe -np 2 "$tmp/consumer/mpi_example")
  echo "$out"
  first=$(echo "$out" | head -1)
  second=$(echo "$out" | sed -n 2p)
  if [ "$first" != "pairs 99, on 2 ranks" ]; then echo "1 passed, 1 failed"; exit 1; fi
  case "$second" in
    "10 frames, 99 to 99 pairs, ghost lists built "[1-9]" times") ;;
    *) echo "1 passed, 1 failed"; exit 1 ;;
  esac
  echo "2 passed, 0 failed"
else
  echo "1 passed, 0 failed"
fi
