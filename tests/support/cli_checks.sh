# The checks the command-line tests share; source it after setting `cli`
# (the program), `tmp` (a scratch folder) and `pass=0 fail=0`.

check() {  # check NAME COMMAND...: counts a pass when COMMAND succeeds
  local name=$1; shift
  if "$@"; then pass=$((pass + 1)); else fail=$((fail + 1)); echo "FAIL: $name"; fi
}

# expect_error NAME PATTERN ARGS...: `$cli ARGS...` must fail cleanly (a
# non-zero exit that is not a signal), name PATTERN on stderr and print
# nothing on stdout.
expect_error() {
  local name=$1 pattern=$2; shift 2
  "$cli" "$@" >"$tmp/out" 2>"$tmp/err"
  local rc=$?
  if [ $rc -ne 0 ] && [ $rc -lt 128 ] && grep -q -- "$pattern" "$tmp/err" && [ ! -s "$tmp/out" ]; then
    pass=$((pass + 1))
  else
    fail=$((fail + 1)); echo "FAIL: $name (exit $rc): $(cat "$tmp/err")"
  fi
}

# replayed_structures: the structures whose replays the CLI tests compare
# with the expected lines: every one of `list`, or under the sanitizers
# (BROADPHASE_SANITIZED) four of them: the oracle, the default, a sweep
# and a tree. The sanitized build still replays every structure over the
# reference scenes in process (test_reference_scenes, test_scenes_v3;
# trajectories: test_ccd), and the Release stage all of it through the
# CLI. One sanitized process per structure and scene made these the
# longest tests of CI's ASan stage after the lab's (cli 59 s,
# cli_v3_periodic 70 s, sim 39 s).
replayed_structures() {
  if [ -n "${BROADPHASE_SANITIZED:-}" ]; then
    echo naive grid-verlet sap kdtree
  else
    "$cli" list | awk '{print $1}'
  fi
}
