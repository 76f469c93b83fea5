#!/usr/bin/env bash
# Builds the fuzz targets (clang's libFuzzer with AddressSanitizer and
# UndefinedBehaviorSanitizer) in build-fuzz/ and runs each for a bounded
# time, starting from the committed seeds in fuzz/corpus/<target>/. New
# inputs go to build-fuzz/corpus/<target>/ (the tree stays clean); a finding
# is written to build-fuzz/artifacts/ and makes the script exit non-zero.
#
# Usage: [FUZZ_PARALLEL=N] [FUZZ_OPT=-O0] fuzz/run.sh [SECONDS per target, default 60] [TARGET...]
# Extra libFuzzer flags: FUZZ_FLAGS="-runs=10000000" fuzz/run.sh 0 fuzz_scene_reader
# (SECONDS 0: no time limit, for campaigns bounded by -runs).
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(fuzz_scene_reader fuzz_structure_spec fuzz_operations fuzz_arrays fuzz_partition)
build=${FUZZ_BUILD_DIR:-build-fuzz}
launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
# -O1 with line tables: libFuzzer's usual level, and a tenth less compile
# than -O2 -g (registry/trees.cpp: 31 against 34 s of CPU on the Intel VM).
# FUZZ_OPT=-O0 (CI's short runs): 2.4 times less compile (registry/trees.cpp
# 11 against 26 s), for slower runs.
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="${FUZZ_OPT:--O1} -gline-tables-only -DNDEBUG" \
  -DBROADPHASE_FUZZ=ON -DBROADPHASE_BUILD_TESTS=OFF -DBROADPHASE_BUILD_APPS=OFF \
  -DBROADPHASE_BUILD_BENCH=OFF -DBROADPHASE_WITH_PEERS=OFF -DBROADPHASE_BUILD_PYTHON=OFF \
  -DBROADPHASE_BUILD_MPI=OFF "${launcher[@]}" >/dev/null
cmake --build "$build" -j "${FUZZ_JOBS:-2}" --target "${targets[@]}"
# An allocation beyond 512 MB is a finding (ASan's operator new stops the
# run rather than throw): no input of a few kilobytes should ask for that.
export ASAN_OPTIONS=${ASAN_OPTIONS:-allocator_may_return_null=1:max_allocation_size_mb=512:detect_leaks=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1:suppressions=$PWD/fuzz/ubsan.supp}
# FUZZ_PARALLEL targets run at once (default 1; CI runs two, one a core),
# each with its own log, reported as it ends.
parallel=${FUZZ_PARALLEL:-1}
run_target() {
  local t=$1 work="$build/corpus/$1" limit=()
  mkdir -p "$work" "$build/artifacts"
  [ "$seconds" -gt 0 ] && limit=(-max_total_time="$seconds")
  # shellcheck disable=SC2086
  "$build/fuzz/$t" "${limit[@]}" -timeout=60 -rss_limit_mb=4096 -print_final_stats=1 \
    -artifact_prefix="$build/artifacts/$t-" ${FUZZ_FLAGS:-} "$work" "fuzz/corpus/$t" 2>"$build/$t.log"
}
report() {  # target, its exit status
  echo "== $1 (${seconds}s)"
  if [ "$2" -ne 0 ]; then
    failed+=("$1")
    tail -n 60 "$build/$1.log"
  fi
  grep -E "^#[0-9]+ +DONE|^stat::number_of_executed_units|cov:" "$build/$1.log" | tail -n 2 || true
}
failed=()
running=()
for t in "${targets[@]}"; do
  run_target "$t" &
  running+=("$!:$t")
  if [ ${#running[@]} -ge "$parallel" ]; then
    status=0
    wait "${running[0]%%:*}" || status=$?
    report "${running[0]#*:}" "$status"
    running=("${running[@]:1}")
  fi
done
for r in "${running[@]}"; do
  status=0
  wait "${r%%:*}" || status=$?
  report "${r#*:}" "$status"
done
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz/run.sh: findings in ${failed[*]} (inputs in $build/artifacts/)" >&2
  exit 1
fi
