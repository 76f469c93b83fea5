#!/usr/bin/env bash
# `paper` over a long run: the output directory is checked before any work;
# Ctrl-C (SIGINT) or SIGTERM at any step, the plotting step included, ends
# the run with the signal's status, leaves no half-written file under a
# real name and marks the run incomplete; `paper --resume DIR` finishes it
# without redoing the steps done. The plotting script is a stand-in
# (BROADPHASE_PYTHON) that draws instantly, or waits to be interrupted.
set -u
# Job control: each background run is its own process group (pgid = pid),
# and its SIGINT is not ignored as a non-interactive shell's would be.
set -m
cli=$1
fail=0
pass=0
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
ok() { pass=$((pass + 1)); }
ko() { fail=$((fail + 1)); echo "FAIL: $*"; }
check() { local name=$1; shift; if "$@"; then ok; else ko "$name"; fi; }

# The stand-in python: "import matplotlib" works; draw.py writes its picture;
# plot_paper.py writes one figure, or with $tmp/hold present records its pid
# and waits (exec: the shell becomes the sleep, so the signal reaches it).
cat >"$tmp/python" <<PY
#!/usr/bin/env bash
[ "\$1" = -c ] && exit 0
case "\$1" in
  *draw.py) out=\$(/usr/bin/python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["out"])' "\$2")
            printf PNG >"\$out" ;;
  *plot_paper.py)
    while [ \$# -gt 0 ]; do [ "\$1" = --out ] && out=\$2; shift; done
    if [ -e "$tmp/hold" ]; then
      printf 'half a figure' >"\$out/fig3_1_query_time_uneven.png"
      echo \$\$ >"$tmp/child"
      exec sleep 120
    fi
    printf PNG >"\$out/fig3_1_query_time_uneven.png" ;;
esac
PY
chmod +x "$tmp/python"
export BROADPHASE_PYTHON=$tmp/python
args=(paper --quick --algos naive,grid-hashed --max-n 100 --no-peers)

# waits up to 300 s for a file to exist
wait_for() { for _ in $(seq 3000); do [ -e "$1" ] && return 0; sleep 0.1; done; return 1; }
partials() { find "$1" -name '*.partial*' -not -path '*/.paper-steps/*' | grep -q .; }
started() {  # started DIR [ARGS]: the background run's pid in $pid (own process group)
  local dir=$1
  shift
  if [ $# -gt 0 ]; then set -- "$@"; else set -- "${args[@]}"; fi
  "$cli" "$@" --out "$dir" >"$tmp/stdout" 2>"$tmp/stderr" &
  pid=$!
}

# --- The output directory is checked before any work, with the reason.
: >"$tmp/regular"
start=$(date +%s)
"$cli" "${args[@]}" --out "$tmp/regular/run" >/dev/null 2>"$tmp/err"
rc=$?
check "--out under a regular file exits 1" test $rc -eq 1
check "--out under a regular file names the reason" grep -q "Not a directory" "$tmp/err"
check "--out is refused before any work" test $(( $(date +%s) - start )) -lt 10
mkdir "$tmp/empty"
"$cli" paper --resume "$tmp/empty" >/dev/null 2>"$tmp/err"
check "--resume without a run exits 1" test $? -eq 1
check "--resume without a run says so" grep -q "no run of broadphase paper to resume" "$tmp/err"
"$cli" paper --resume "$tmp/empty" --quick >/dev/null 2>"$tmp/err"
check "--resume with other options is a usage error" test $? -eq 2

# --- Ctrl-C during the study: exit 130, nothing that looks whole.
# A study large enough to be still running when the signal comes, on an
# idle machine too (at --max-n 100 it can end within the polling interval).
started "$tmp/a" paper --quick --algos naive,grid-hashed --max-n 3200 --no-peers
for _ in $(seq 3000); do grep -q "study:" "$tmp/stderr" 2>/dev/null && break; sleep 0.1; done
kill -INT -- -$pid
wait $pid
rc=$?
check "SIGINT in the study: exit 130 (got $rc)" test $rc -eq 130
check "SIGINT in the study: RUN-INCOMPLETE" grep -q "Steps done: none" "$tmp/a/RUN-INCOMPLETE"
check "SIGINT in the study: it names --resume" grep -q -- "--resume" "$tmp/a/RUN-INCOMPLETE"
check "SIGINT in the study: no results.csv" test ! -e "$tmp/a/results.csv"
check "SIGINT in the study: no REPORT.md" test ! -e "$tmp/a/REPORT.md"
check "SIGINT in the study: no temporary file" bash -c "! find '$tmp/a' -name '.*partial*' | grep -q ."
check "SIGINT in the study: the message says how to resume" grep -q "paper --resume" "$tmp/stderr"

# --- Ctrl-C during the plotting step: the child dies with the run.
touch "$tmp/hold"
started "$tmp/b"
if wait_for "$tmp/child"; then
  kill -INT -- -$pid
  wait $pid
  rc=$?
else
  rc=timeout
fi
check "SIGINT while plotting: exit 130 (got $rc)" test "$rc" = 130
check "SIGINT while plotting: the state names the steps done" \
  grep -q '"tunneling"' "$tmp/b/paper-state.json"
check "SIGINT while plotting: plots not done" bash -c "! grep -q '\"plots\"' '$tmp/b/paper-state.json'"
check "SIGINT while plotting: RUN-INCOMPLETE lists the study" grep -q "^  study" "$tmp/b/RUN-INCOMPLETE"
check "SIGINT while plotting: no half figure in the directory" test ! -e "$tmp/b/fig3_1_query_time_uneven.png"
check "SIGINT while plotting: no REPORT.md" test ! -e "$tmp/b/REPORT.md"
check "SIGINT while plotting: not taken for a missing matplotlib" bash -c "! grep -qi matplotlib '$tmp/stderr'"
check "SIGINT while plotting: results.csv whole" test -s "$tmp/b/results.csv"
cp "$tmp/b/results.csv" "$tmp/results.before"
cp "$tmp/b/performance.csv" "$tmp/performance.before"
touch -d '2001-01-01' "$tmp/b/results.csv" "$tmp/b/performance.csv"

# --- SIGTERM to the run alone while plotting: the child is stopped too.
rm -f "$tmp/child"
"$cli" paper --resume "$tmp/b" >"$tmp/stdout" 2>"$tmp/stderr" &
pid=$!
if wait_for "$tmp/child"; then
  child=$(cat "$tmp/child")
  kill -TERM $pid
  wait $pid
  rc=$?
else
  rc=timeout child=0
fi
check "SIGTERM while plotting: exit 143 (got $rc)" test "$rc" = 143
check "SIGTERM while plotting: the plotting child is gone" bash -c "! kill -0 $child 2>/dev/null"
check "SIGTERM while plotting: a resume does not redo the study" bash -c "! grep -q 'study:' '$tmp/stderr'"

# --- The plotting child killed alone: a failure named, not "no matplotlib".
rm -f "$tmp/child"
"$cli" paper --resume "$tmp/b" >"$tmp/stdout" 2>"$tmp/stderr" &
pid=$!
if wait_for "$tmp/child"; then
  kill -INT "$(cat "$tmp/child")"
  wait $pid
  rc=$?
else
  rc=timeout
fi
check "plot script killed alone: exit 1 (got $rc)" test "$rc" = 1
check "plot script killed alone: the signal is named" grep -q "killed by signal 2" "$tmp/stderr"
check "plot script killed alone: the run stays incomplete" test -e "$tmp/b/RUN-INCOMPLETE"

# --- --resume finishes the run without redoing what is done.
rm -f "$tmp/hold"
"$cli" paper --resume "$tmp/b" >"$tmp/stdout" 2>"$tmp/stderr"
rc=$?
check "resume: exit 0 (got $rc: $(tail -2 "$tmp/stderr"))" test $rc -eq 0
check "resume: REPORT.md written" test -s "$tmp/b/REPORT.md"
check "resume: results.json written" test -s "$tmp/b/results.json"
check "resume: the figure is in place" test "$(cat "$tmp/b/fig3_1_query_time_uneven.png")" = PNG
check "resume: the report shows the figure" grep -q "fig3_1_query_time_uneven.png" "$tmp/b/REPORT.md"
check "resume: RUN-INCOMPLETE removed" test ! -e "$tmp/b/RUN-INCOMPLETE"
check "resume: the state says complete" grep -q '"complete": true' "$tmp/b/paper-state.json"
check "resume: the study not redone" bash -c "! grep -q 'study:' '$tmp/stderr'"
check "resume: results.csv kept" test "$(stat -c %Y "$tmp/b/results.csv")" = "$(date -d 2001-01-01 +%s)"
check "resume: performance.csv kept" test "$(stat -c %Y "$tmp/b/performance.csv")" = "$(date -d 2001-01-01 +%s)"
check "resume: results.csv as before" cmp -s "$tmp/b/results.csv" "$tmp/results.before"
check "resume: the report has the study's rows" grep -q "grid-hashed" "$tmp/b/REPORT.md"
check "resume: no temporary file" bash -c "! find '$tmp/b' -name '*partial*' | grep -q ."

echo "$pass passed, $fail failed"
[ $fail -eq 0 ]
