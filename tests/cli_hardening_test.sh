#!/usr/bin/env bash
# The command line at the edges: outputs whole or absent with the reason of
# a failed write, short escaped quotes of bad tokens, one set of exit codes
# (0 done, 1 bad input or failure, 2 wrong command line), --version.
# Write errors are provoked with a path under a regular file (ENOTDIR) and
# with /dev/full (ENOSPC): tests may run as root, where permissions do not.
set -u
cli=$1
version=${2:-}
fail=0
pass=0
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

ok() { pass=$((pass + 1)); }
ko() { fail=$((fail + 1)); echo "FAIL: $*"; }
check() {  # check NAME COMMAND...
  local name=$1; shift
  if "$@"; then ok; else ko "$name"; fi
}
# expect NAME EXIT PATTERN ARGS...: the exit status, the pattern on stderr,
# nothing on stdout, and a message of at most 600 bytes on one or two lines.
expect() {
  local name=$1 want=$2 pattern=$3; shift 3
  "$cli" "$@" >"$tmp/out" 2>"$tmp/err"
  local rc=$? size lines
  size=$(wc -c <"$tmp/err"); lines=$(wc -l <"$tmp/err")
  if [ "$rc" -eq "$want" ] && grep -q -- "$pattern" "$tmp/err" && [ ! -s "$tmp/out" ] &&
     [ "$size" -le 600 ] && [ "$lines" -le 2 ]; then
    ok
  else
    ko "$name (exit $rc, want $want; $size bytes, $lines lines): $(head -c 300 "$tmp/err")"
  fi
}
no_partials() {  # no_partials DIR: no temporary file left behind
  ! find "$1" -name '.*partial*' | grep -q .
}

printf 'broadphase-scene 1\nworld 10\nobjects 1\n1 2 3 1 0 0 0\n' >"$tmp/one.scene"
: >"$tmp/regular"

# --- Outputs: whole or absent, with the reason of a failure.
expect "gen under a regular file" 1 "regular/x.scene: cannot create: Not a directory" \
  gen --dist even --n 10 --out "$tmp/regular/x.scene"
expect "gen to a full disk" 1 "/dev/full: write failed: No space left on device" \
  gen --dist even --n 1000 --out /dev/full
mkdir "$tmp/gen"
"$cli" gen --dist even --n 100 --out "$tmp/gen/a.scene"
check "gen writes the scene" test -s "$tmp/gen/a.scene"
check "gen leaves no temporary file" test "$(ls -A "$tmp/gen")" = a.scene
cp "$tmp/gen/a.scene" "$tmp/gen/keep"
"$cli" gen --dist even --n 100 --out "$tmp/gen/a.scene/x" 2>/dev/null
check "a failed gen leaves the old file alone" cmp -s "$tmp/gen/a.scene" "$tmp/gen/keep"
expect "sim --out under a regular file" 1 "Not a directory" \
  sim --scene "$tmp/one.scene" --frames 1 --out "$tmp/regular/end.scene"
expect "sim --make-tunnel-scene to a full disk" 1 "No space left on device" \
  sim --make-tunnel-scene /dev/full
expect "draw under a regular file" 1 "regular: .*Not a directory" \
  draw --scene "$tmp/one.scene" --out "$tmp/regular/x.png"

# draw renders to a temporary name and renames it when the script is done.
cat >"$tmp/fake-python" <<'PY'
#!/usr/bin/env bash
# Stands in for python3 with matplotlib: "draws" by writing the bytes PNG.
[ "$1" = -c ] && exit 0
out=$(/usr/bin/python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["out"])' "$2")
printf 'PNG' >"$out"
PY
chmod +x "$tmp/fake-python"
mkdir "$tmp/pics"
BROADPHASE_PYTHON=$tmp/fake-python "$cli" draw --scene "$tmp/one.scene" --out "$tmp/pics/a.png" \
  2>"$tmp/err"
check "draw writes the picture under its name" test "$(cat "$tmp/pics/a.png" 2>/dev/null)" = PNG
check "draw leaves no temporary file" test "$(ls -A "$tmp/pics")" = a.png

# --- Messages: a short escaped excerpt of a bad token.
{ printf 'broadphase-scene 1\nworld 10\nobjects 1\n1 '
  head -c 10000000 /dev/zero | tr '\0' 7
  printf ' 3 1 0 0 0\n'; } >"$tmp/huge.scene"
expect "a 10 MB number is quoted short" 1 "huge.scene:4: y '7777777777.*'\.\.\. is out of the range" \
  run --scene "$tmp/huge.scene" --frames 1
printf 'broadphase-scene 1\nworld 10\nobjects 1\n1 \033[31mred 3 1 0 0 0\n' >"$tmp/esc.scene"
expect "control bytes are escaped" 1 "y '\\\\x1b\[31mred' is not a number" \
  run --scene "$tmp/esc.scene" --frames 1
check "no escape byte reaches the terminal" bash -c "! grep -q $'\\033' '$tmp/err'"
printf 'broadphase-scene 1\rworld 10\robjects 0\r' >"$tmp/cr.scene"
expect "a CR-only file shows the CR" 1 "cr.scene:1: lines end in a lone CR.*'broadphase-scene 1\\\\x0dworld 10" \
  run --scene "$tmp/cr.scene" --frames 1
mkdir "$tmp/dir.scene"
expect "a directory as a scene" 1 "dir.scene: cannot read: it is a directory" \
  run --scene "$tmp/dir.scene"
expect "advise: a directory as a scene" 1 "it is a directory" advise --scene "$tmp/dir.scene"
expect "sim: a directory as a scene" 1 "it is a directory" sim --scene "$tmp/dir.scene"
expect "draw: a directory as a scene" 1 "it is a directory" \
  draw --scene "$tmp/dir.scene" --out "$tmp/x.png"
long=$(head -c 100000 /dev/zero | tr '\0' 9)
expect "a 100 kB number on the command line" 2 "frames" run --scene "$tmp/one.scene" --frames "$long"
expect "a 100 kB structure name" 2 "unknown structure" run --scene "$tmp/one.scene" --algo "$long"
expect "--dt 0 names a short bound" 2 "--dt: 0 is not a positive number" \
  sim --scene "$tmp/one.scene" --dt 0
expect "--dt -1" 2 "--dt: -1 is not a positive number" sim --scene "$tmp/one.scene" --dt -1
expect "--seed -1 (gen)" 2 "--seed: -1 is not a whole number" gen --dist even --n 1 --seed -1 --out "$tmp/s"
expect "--seed -1 (sim)" 2 "--seed: -1 is not a whole number" sim --make-billiards-scene "$tmp/b" --seed -1
expect "--seed -1 (paper)" 2 "--seed: -1 is not a whole number" paper --out "$tmp/p" --seed -1
expect "--seed 2^64" 2 "--seed" gen --dist even --n 1 --seed 18446744073709551616 --out "$tmp/s"
expect "--n -1" 2 "--n" gen --dist even --n -1 --out "$tmp/s"
check "a refused --seed writes nothing" test ! -e "$tmp/s"

# A motion that overflows the doubles: sim names the frame and the object.
printf 'broadphase-scene 1\nworld 1e300\nobjects 2\n0 0 0 1 0 0 0\n1.79e308 0 0 1 1e306 0 0\n' >"$tmp/overflow.scene"
for ccd in off substep swept; do
  "$cli" sim --scene "$tmp/overflow.scene" --frames 3 --ccd $ccd >"$tmp/out" 2>"$tmp/err"
  rc=$?
  # off and substep reflect the object at the wall; swept's sweep overflows.
  if [ $rc -ne 0 ] || [ $ccd = swept ]; then
    check "sim --ccd $ccd: overflowing motion exits 1" test "$rc" -eq 1
    check "sim --ccd $ccd: names the frame and object" \
      grep -q "frame [0-9]*: object 1 moves beyond the range of doubles" "$tmp/err"
  fi
done

# --- Exit codes: 2 for a wrong command line, 1 for bad input and failures.
expect "no subcommand" 2 "" 
expect "unknown subcommand" 2 "" frobnicate
expect "unknown flag" 2 "bogus" run --scene "$tmp/one.scene" --bogus
expect "missing required option" 2 "scene" run
expect "not a number" 2 "frames" run --scene "$tmp/one.scene" --frames abc
expect "out of range" 2 "frames" run --scene "$tmp/one.scene" --frames 0
expect "unknown structure" 2 "valid:" run --scene "$tmp/one.scene" --algo nope
expect "missing scene file" 1 "cannot open" run --scene "$tmp/none.scene"
expect "paper: bad --max-n" 2 "max-n" paper --out "$tmp/p" --max-n 3
expect "advise: unknown structure" 2 "nope" advise --scene "$tmp/one.scene" --algos nope
"$cli" advise --scene "$tmp/overflow.scene" --algos naive,grid-hashed --frames 4 --seconds 1 >"$tmp/out" 2>"$tmp/err"
check "advise: every structure failed exits 1" test $? -eq 1
check "advise: every structure failed says so" grep -q "no structure could run" "$tmp/err"
"$cli" --help >"$tmp/help" 2>&1
check "--help exits 0" test $? -eq 0
check "--help names the exit codes" grep -q "Exit status: 0" "$tmp/help"

# --- --version: the project's version.
"$cli" --version >"$tmp/out" 2>"$tmp/err"
check "--version exits 0" test $? -eq 0
check "--version prints the version" grep -qx "broadphase ${version:-[0-9]*\.[0-9]*\.[0-9]*}" "$tmp/out"

check "no temporary file left anywhere" no_partials "$tmp"
echo "$pass passed, $fail failed"
[ $fail -eq 0 ]
