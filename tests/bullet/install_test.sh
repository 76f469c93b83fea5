#!/usr/bin/env bash
# Installs the library into a temporary prefix, builds examples/bullet.cpp
# against it with find_package(broadphase COMPONENTS bullet), float and
# double Bullet, and runs both.
set -eu
build=$1
src=$2
flags=${3:-}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cmake --install "$build" --prefix "$tmp/prefix" >/dev/null
cmake -S "$src/tests/bullet/consumer" -B "$tmp/consumer" -DCMAKE_PREFIX_PATH="$tmp/prefix" \
  -DEXAMPLE_SOURCE="$src/examples/bullet.cpp" -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_CXX_FLAGS="$flags" >/dev/null
cmake --build "$tmp/consumer" >/dev/null
expected='boxes resting on the plane: 216 of 216
ray from above hits a box: yes
sensor overlaps something: yes'
for program in bullet_example bullet_example_double; do
  out=$("$tmp/consumer/$program")
  echo "$program: $out"
  if [ "$out" != "$expected" ]; then echo "$program: unexpected output"; exit 1; fi
done
echo "2 passed, 0 failed"
