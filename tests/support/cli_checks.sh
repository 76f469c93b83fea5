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
