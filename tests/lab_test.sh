#!/usr/bin/env bash
# `broadphase paper --quick` end to end: the outputs exist and agree with
# each other, figures are made when matplotlib is there, and bad options
# fail with a clear message and a non-zero exit.
set -u
cli=$1
fail=0
pass=0
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# shellcheck source=support/cli_checks.sh
. "$(dirname "$0")/support/cli_checks.sh"

out=$tmp/run
start=$(date +%s)
TIMEFORMAT='%U %S'
# The run stops at size 800, in the study and in every experiment, and the
# sanitized build's at 400, for CI's time: every experiment's code still
# runs, on smaller worlds. The quick run alone took 88 s in Release (48 s
# capped at 800) on the Intel VM, the longest test of CI's Release stage,
# and 270 s of CPU under ASan (55 s capped at 800).
quick=(paper --quick --max-n 800)
kind_n=800  # the size of the lab's kinds in this run (2000 in a quick run, lab/goals.json)
[ -z "${BROADPHASE_SANITIZED:-}" ] || { quick=(paper --quick --max-n 400); kind_n=400; }
{ time "$cli" "${quick[@]}" --out "$out" >"$tmp/stdout" 2>"$tmp/stderr"; } 2>"$tmp/time"
rc=$?
took=$(( $(date +%s) - start ))
cpu=$(awk '{printf "%d", $1 + $2}' "$tmp/time")
check "paper --quick exits 0 (exit $rc: $(tail -3 "$tmp/stderr"))" test $rc -eq 0
# "Under a minute" is checked on CPU time, which a busy machine does not
# inflate; sanitizer builds run several times slower and are exempt.
if [ -z "${BROADPHASE_SANITIZED:-}" ]; then
  check "paper --quick returns (a hang guard, not a timing: took ${cpu}s CPU, ${took}s wall)" test "$cpu" -lt 600
fi
for f in results.csv results.json REPORT.md; do
  check "$f written" test -s "$out/$f"
done
check "stdout is one summary line naming the report" \
  test "$(wc -l <"$tmp/stdout")" -eq 1 -a -n "$(grep -F "$out/REPORT.md" "$tmp/stdout")"

# The CSV, the JSON and the report describe the same run.
cat >"$tmp/consistent.py" <<'PY'
import csv, json, sys
out = sys.argv[1]
rows = list(csv.DictReader(open(out + "/results.csv")))
j = json.load(open(out + "/results.json"))
report = open(out + "/REPORT.md").read()
errors = []
if not rows:
    errors.append("results.csv has no rows")
if len(rows) != len(j["rows"]):
    errors.append("csv has %d rows, json %d" % (len(rows), len(j["rows"])))
for r, k in zip(rows, j["rows"]):
    if (r["structure"], r["test"], r["placement"], int(r["n"])) != (k["structure"], k["test"], k["placement"], k["n"]):
        errors.append("row order differs: %s vs %s" % (r, k)); break
    if abs(float(r["median"]) - k["median"]) > 1e-5 * max(1.0, abs(k["median"])):
        errors.append("medians differ: %s vs %s" % (r["median"], k["median"])); break
    if not (float(r["min"]) <= float(r["median"]) <= float(r["max"])):
        errors.append("median outside [min, max]: %s" % r); break
tests = {r["test"] for r in rows}
for t in ("query_time", "query_tests", "insert_time", "remove_time", "memory", "frame_time"):
    if t not in tests:
        errors.append("no %s rows" % t)
for s in j["run"]["structures"]:
    if ("| " + s) not in report:
        errors.append("structure %s missing from REPORT.md" % s)
    if not any(r["structure"] == s for r in rows) and s not in [k["structure"] for k in j["skipped"]]:
        errors.append("structure %s has neither rows nor a skip" % s)
for k in j["skipped"]:
    if k["structure"] not in report.split("## Skipped")[1]:
        errors.append("skip of %s not reported" % k["structure"])
# The lean path (arrays) is one more series of the default run: frame
# times and memory at every size it ran, its pairs compared with the rest.
if "arrays" not in j["run"]["structures"]:
    errors.append("the default run lacks the lean path (arrays)")
arrays_tests = {r["test"] for r in rows if r["structure"] == "arrays"}
if arrays_tests != {"build_time", "frame_time", "memory", "memory_with_arrays"}:
    errors.append("arrays rows are of %s" % sorted(arrays_tests))
if "| arrays with the caller's arrays |" not in report:
    errors.append("the memory table lacks the lean path with the caller's arrays")
if j["mismatches"]:
    errors.append("structures disagree: %s" % j["mismatches"][:3])
if j["comparisons"] <= 0:
    errors.append("no results were compared")
for needle in ("## The study's findings, checked", "(a) the hgrid", "(e) the octree", "## Memory",
               "## Exactness", "| commit |", "| machine |", "| compiler |", "| command |", "paper --quick"):
    if needle not in report:
        errors.append("REPORT.md lacks %r" % needle)
# The structure `advise` recommends on each kind of lab/goals.json marked so,
# against the fastest peer, all pairs agreeing.
if "**Where the lead is thin**" in report:
    thin = report.split("**Where the lead is thin**")[1].split("\n\n**")[0]
    for kind in ("clusters", "decades", "all-moving", "explosion", "flat", "coincident", "outside",
                 "boxes", "half-boxes", "box-decades", "city", "shapes-uneven", "shapes-decades",
                 "shapes-flat"):
        if ("| %s %s |" % (kind, sys.argv[2])) not in thin:
            errors.append("advise's pick is missing on %s" % kind)
elif "this build has no peer adapter" not in report:
    errors.append("REPORT.md lacks advise's picks against the peers")
# The first six frames of every workload, the warm-up included: the lean
# path's first two calls and the default structure's inserts, all times.
if "**A short run**" in report:
    short = report.split("**A short run**")[1].split("\n\n**")[0]
    lines = [l for l in short.splitlines() if l.startswith("| ") and "---" not in l][1:]
    if len(lines) < 9:
        errors.append("the short-run table has %d rows" % len(lines))
    for l in lines:
        cells = [c.strip() for c in l.strip("|").split("|")]
        try:
            if len(cells) != 7 or min(float(c) for c in cells[1:]) <= 0:
                errors.append("short-run row not seven positive times: %s" % l)
        except ValueError:
            errors.append("short-run row not seven positive times: %s" % l)
else:
    errors.append("REPORT.md lacks the short-run table")
if "**pairs differ**" in report:
    errors.append("the performance tables report pairs that differ")
# Medians of the study's tests are positive where they are times.
for r in rows:
    if r["test"] in ("query_time", "frame_time") and float(r["median"]) <= 0:
        errors.append("non-positive time: %s" % r); break
if j["run"]["plots"]:
    for f in j["figures"]:
        if ("(" + f + ")") not in report:
            errors.append("figure %s not in REPORT.md" % f)
else:
    if "Plots were skipped" not in report:
        errors.append("plots missing but the report does not say so")
if errors:
    print("\n".join(errors))
sys.exit(1 if errors else 0)
PY
check "CSV, JSON and REPORT.md agree" python3 "$tmp/consistent.py" "$out" "$kind_n"

# The lab as data: results.csv has exactly the columns of lab/metrics.json,
# each row's metric, unit and study test are that file's, docs/lab.md shows
# that file's tables, and every registered experiment wrote its section.
src=$(cd "$(dirname "$0")/.." && pwd)
cat >"$tmp/data.py" <<'PY'
import csv, json, sys
out, src = sys.argv[1], sys.argv[2]
m = json.load(open(src + "/lab/metrics.json"))
metrics = {x["name"]: x for x in m["metrics"]}
errors = []
with open(out + "/results.csv") as f:
    header = next(csv.reader(f))
if header != [c["name"] for c in m["columns"]]:
    errors.append("results.csv columns %s are not lab/metrics.json's" % header)
for r in csv.DictReader(open(out + "/results.csv")):
    x = metrics.get(r["test"])
    if x is None:
        errors.append("metric %s not in lab/metrics.json" % r["test"]); break
    if r["unit"] != x["unit"] or int(r["study_test"]) != x["study_test"].get(r["placement"], 0):
        errors.append("row %s disagrees with lab/metrics.json" % r); break
report = open(out + "/REPORT.md").read()
for section in ("## Pictures of the workloads", "## Cell-size sweep", "## Trees, sweeps and caches",
                "## Octrees and the k-d tree", "## Tunneling", "## Performance",
                "## Neighbour lists and nearest neighbours"):
    if section not in report:
        errors.append("REPORT.md lacks the experiment section %r" % section)
if "lab/goals.json" not in report:
    errors.append("the performance section does not name lab/goals.json")
print("\n".join(errors))
sys.exit(1 if errors else 0)
PY
check "results follow lab/metrics.json; experiments reported" python3 "$tmp/data.py" "$out" "$src"
check "docs/lab.md shows lab/metrics.json's tables" python3 "$src/tools/lab_columns.py" --check "$src/docs/lab.md"

# Figures, whenever a Python the CLI would pick has matplotlib (see plot_python()).
. "$(dirname "$0")/support/have_matplotlib.sh"
if have_matplotlib; then
  for f in fig3_1_query_time_uneven fig3_4_query_tests_even fig3_5_insert_time fig3_10_query_tests_placement frame_time_even; do
    check "figure $f.png" test -s "$out/$f.png"
    check "figure $f.svg" test -s "$out/$f.svg"
  done
else
  check "report says plots were skipped" grep -q "Plots were skipped" "$out/REPORT.md"
fi

# Bad options: a clear message, a non-zero exit, nothing on stdout, no crash.
expect_error "unknown structure" "unknown structure 'nope'; valid: .*naive" paper --quick --algos nope --out "$tmp/bad"
expect_error "unknown structure in a list" "unknown structure 'nope'" paper --quick --algos naive,nope --out "$tmp/bad"
expect_error "bad structure option" "naive" paper --quick --algos naive:foo=1 --out "$tmp/bad"
expect_error "max-n 0" "max-n" paper --quick --max-n 0 --out "$tmp/bad"
expect_error "max-n not a number" "max-n" paper --quick --max-n lots --out "$tmp/bad"
expect_error "negative budget" "budget" paper --quick --budget -3 --out "$tmp/bad"
touch "$tmp/file"
expect_error "out is a file" "cannot create" paper --quick --out "$tmp/file"
check "no output directory for rejected runs" test ! -e "$tmp/bad"

# A small explicit run: --max-n caps the sizes, --algos picks structures.
"$cli" paper --quick --algos naive --max-n 100 --no-peers --out "$tmp/small" >/dev/null 2>"$tmp/err"
check "small run exits 0" test $? -eq 0
check "small run stops at N=100" python3 -c "
import csv, sys
ns = {int(r['n']) for r in csv.DictReader(open('$tmp/small/results.csv'))}
sys.exit(0 if ns == {50, 100} else 1)"

# The budget kept on a loaded machine: with the lab's clock running 6 times
# fast (BROADPHASE_LAB_TIME_SCALE, lab/budget.hpp) and a budget of 4 s, the
# run falls behind the plan its measurements make: it cuts repetitions and
# sizes and says so in REPORT.md and results.json, and its progress line,
# re-estimated from the rates measured, does not claim less time left than
# the run then took (over the second half of the run: before the first
# experiments end, nothing measured says how long --quick's fixed sizes take).
# The sanitized build leaves this second run out, for CI's time: the run
# above already takes the budget's code through the sanitizers.
if [ -z "${BROADPHASE_SANITIZED:-}" ]; then
BROADPHASE_LAB_TIME_SCALE=6 "$cli" paper --quick --algos naive,grid-hashed,sap --no-peers \
  --budget 4 --out "$tmp/slow" >/dev/null 2>"$tmp/slow_err"
rc=$?
check "a slow run exits 0 (exit $rc: $(tail -3 "$tmp/slow_err"))" test $rc -eq 0
# Which cut comes first depends on the host's speed: a slow host cuts the
# study's repetitions, a fast one (a 2-core AMD EPYC VM) reaches the large
# sizes with all three and leaves a structure out there instead.
check "a slow run cuts repetitions or sizes and says so in REPORT.md" \
  grep -Eq "^- budget: (cut repetitions from 3 to 2 for N >= |left out .* from N = )" \
  "$tmp/slow/REPORT.md"
# A structure left out (the fast host's cut; a loaded or slow one may cut
# only repetitions) is named with the size and the reason.
check "a slow run says what it left out for the budget" python3 -c "
import re, sys
lines = [l for l in open('$tmp/slow/REPORT.md').read().splitlines() if l.startswith('- budget: left out')]
sys.exit(0 if all(re.search(r' from N = .* on: projected beyond', l) for l in lines) else 1)"
check "a slow run's cuts are in results.json" python3 -c "
import json, sys
info = json.load(open('$tmp/slow/results.json'))['run']
notes = info['budget_notes']
sys.exit(0 if info['time_scale'] == 6 and any(n.startswith(('budget: cut', 'budget: left out')) for n in notes) else 1)"
cat >"$tmp/honest.py" <<'PY'
# Each progress line "(elapsed E, about L left)" of the run's second half
# against the total of the closing "done in T": L must not fall short of
# what remained, T - E, by more than 3 s (the rounding of the three
# figures) or a tenth of it.
import re, sys
def seconds(t):
    m = re.fullmatch(r"(?:(\d+)h)?(?:(\d+)m)?(?:(\d+)s)?", t)
    if not m or not t:
        return None
    h, mi, s = (int(x) if x else 0 for x in m.groups())
    return h * 3600 + mi * 60 + s
total = None
points = []
for line in open(sys.argv[1]).read().splitlines():
    m = re.search(r"\(elapsed (\S+), about (\S+) left\)$", line)
    if m:
        points.append((seconds(m.group(1)), seconds(m.group(2)), line))
    m = re.search(r"done in (\S+)$", line)
    if m:
        total = seconds(m.group(1))
late = [p for p in points if total is not None and p[0] >= total / 2 and p[1] is not None]
if total is None or len(late) < 2:
    print("too few progress lines in the second half:", len(late), "total", total)
    sys.exit(1)
bad = [(e, left, line) for e, left, line in late if left < (total - e) - max(3, 0.1 * (total - e))]
for e, left, line in bad:
    print("at %d s: claimed %d s left, %d s remained: %s" % (e, left, total - e, line))
sys.exit(1 if bad else 0)
PY
check "the progress line's estimate does not fall short of the time left" \
  python3 "$tmp/honest.py" "$tmp/slow_err"
fi

echo "$pass passed, $fail failed"
[ $fail -eq 0 ]
