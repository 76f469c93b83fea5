#!/usr/bin/env bash
# Installs the library into a temporary prefix, builds examples/fcl.cpp
# against it with find_package(broadphase COMPONENTS fcl) and
# broadphase::fcl, and runs it.
set -u
here=$(cd "$(dirname "$0")" && pwd)
build=$1
src=$2
flags=${3:-}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
pass=0 fail=0
source "$here/../support/cli_checks.sh"
set -e
cmake --install "$build" --prefix "$tmp/prefix" >/dev/null
cmake -S "$src/tests/fcl/consumer" -B "$tmp/consumer" -DCMAKE_PREFIX_PATH="$tmp/prefix" \
  -DEXAMPLE_SOURCE="$src/examples/fcl.cpp" -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_FLAGS="$flags" \
  >/dev/null
cmake --build "$tmp/consumer" >/dev/null
set +e
"$tmp/consumer/fcl_example" >"$tmp/out"
cat "$tmp/out"
check "the installed example runs" test "$(grep -c '^step [0-9]: [1-9][0-9]* contacts$' "$tmp/out")" = 5
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
