#!/usr/bin/env bash
# Installs the library into a temporary prefix, builds the README example
# against it with find_package(broadphase), and runs it.
set -eu
build=$1
src=$2
flags=${3:-}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cmake --install "$build" --prefix "$tmp/prefix" >/dev/null
cmake -S "$src/tests/install" -B "$tmp/consumer" -DCMAKE_PREFIX_PATH="$tmp/prefix" \
  -DEXAMPLE_SOURCE="$src/examples/quickstart.cpp" -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_FLAGS="$flags" >/dev/null
cmake --build "$tmp/consumer" >/dev/null
out=$("$tmp/consumer/quickstart")
echo "$out"
expected='pair 1-2
touches 2
touches 3
3 narrow-phase tests'
if [ "$out" = "$expected" ]; then echo "1 passed, 0 failed"; else echo "0 passed, 1 failed"; exit 1; fi
