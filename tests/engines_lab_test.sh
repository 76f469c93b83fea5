#!/usr/bin/env bash
# The engines' lab section (bench/engines/engines_lab.cpp) end to end at
# tiny size: `--quick` writes its CSVs, JSON, section and figure, and they
# hold every world, broad phase, size and manager of the plan, for every
# run, with finite positive times; bad options fail with a message.
set -u
cli=$1
fail=0
pass=0
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# shellcheck source=support/cli_checks.sh
. "$(dirname "$0")/support/cli_checks.sh"

out=$tmp/run
"$cli" --quick --out "$out" >"$tmp/stdout" 2>"$tmp/stderr"
rc=$?
check "engines_lab --quick exits 0 (exit $rc: $(tail -3 "$tmp/stderr"))" test $rc -eq 0
for f in bullet.csv fcl.csv engines.json section.md; do
  check "$f written" test -s "$out/$f"
done
check "stdout is the section" cmp -s "$tmp/stdout" "$out/section.md"
if /usr/bin/python3 -c "import matplotlib" 2>/dev/null; then
  check "figure written" test -s "$out/engines.png"
  check "the section shows the figure" grep -q "engines.png" "$out/section.md"
fi

cat >"$tmp/consistent.py" <<'PY'
import csv, json, math, sys
out = sys.argv[1]
bullet = list(csv.DictReader(open(out + "/bullet.csv")))
fcl = list(csv.DictReader(open(out + "/fcl.csv")))
j = json.load(open(out + "/engines.json"))
errors = []
runs = j["runs"]
if runs != 2:
    errors.append("--quick runs 2 runs, the JSON says %r" % runs)
worlds = ["falling 200", "pyramid 55", "mixed 60", "groups 60", "ghost 60", "falling 400"]
# BulletOptions{}.structure (kdtree) and grid-verlet, engines_lab.cpp's bullet_cases
ours = ["ours (kdtree)", "ours (grid-verlet)"]
for run in range(1, runs + 1):
    for w in worlds:
        names = [r["broadphase"] for r in bullet if r["run"] == str(run) and r["world"] == w]
        want = ["btDbvtBroadphase"] + ([] if w == "falling 400" else ["bt32BitAxisSweep3"]) + ours
        if names != want:
            errors.append("run %d, %s: broad phases %r, expected %r" % (run, w, names, want))
    for n, managers in (("300", ["broadphase (grid-verlet)", "fcl DynamicAABBTree", "fcl SaP",
                                  "fcl SpatialHashing", "fcl Naive"]),
                        ("1000", ["broadphase (grid-verlet)", "fcl DynamicAABBTree"])):
        got = [r["manager"] for r in fcl if r["run"] == str(run) and r["n"] == n]
        if got != managers:
            errors.append("run %d, FCL %s: managers %r, expected %r" % (run, n, got, managers))
for r in bullet:
    for k in ("step_ms", "broad_ms", "share"):
        v = float(r[k])
        if not (math.isfinite(v) and v > 0):
            errors.append("bullet.csv: %s %s %s = %r" % (r["world"], r["broadphase"], k, r[k]))
    if float(r["broad_ms"]) > float(r["step_ms"]) or float(r["share"]) > 1:
        errors.append("bullet.csv: %s %s: broad phase above its step" % (r["world"], r["broadphase"]))
    if int(r["pairs"]) <= 0:
        errors.append("bullet.csv: %s %s: no pairs at the end" % (r["world"], r["broadphase"]))
for r in fcl:
    if not float(r["total_ms"]) > 0 or int(r["frames"]) != 2 or int(r["pairs"]) <= 0:
        errors.append("fcl.csv: bad row %r" % r)
    if abs(float(r["update_ms"]) + float(r["collide_ms"]) - float(r["total_ms"])) > \
            1e-6 + 0.5 * float(r["total_ms"]):
        errors.append("fcl.csv: update + collide far from the total in %r" % r)
# The JSON's medians: one entry per world and broad phase, per size and manager.
if [w["world"] for w in j["bullet"]] != worlds:
    errors.append("engines.json worlds %r" % [w["world"] for w in j["bullet"]])
for w in j["bullet"]:
    dbvt = [b for b in w["broad_phases"] if b["name"] == "btDbvtBroadphase"]
    if len(dbvt) != 1 or abs(dbvt[0]["broad_dbvt_over_this"] - 1) > 1e-12:
        errors.append("engines.json %s: the dbvt's ratio to itself is not 1" % w["world"])
if len(j["fcl"]) != 7:
    errors.append("engines.json: %d FCL entries, expected 7" % len(j["fcl"]))
for f in j["fcl"]:
    if f["manager"].startswith("broadphase") and abs(f["total_over_ours"] - 1) > 1e-12:
        errors.append("engines.json: ours over ours is not 1 at %d" % f["n"])
if j["errors"]:
    errors.append("disagreements: %r" % j["errors"])
for k in ("cpu", "cores", "compiler"):
    if not j["machine"].get(k):
        errors.append("engines.json: no machine %s" % k)
section = open(out + "/section.md").read()
for w in worlds:
    if "| %s | btDbvtBroadphase |" % w not in section:
        errors.append("section.md has no row for %s" % w)
print("\n".join(errors))
sys.exit(1 if errors else 0)
PY
check "outputs hold the whole plan, consistently ($(/usr/bin/python3 "$tmp/consistent.py" "$out" 2>&1 | head -5))" \
  /usr/bin/python3 "$tmp/consistent.py" "$out"

expect_error "unknown option" "unknown option '--bogus'" --bogus
expect_error "bad --runs" "--runs: '0'" --runs 0 --out "$tmp/x"
expect_error "bad --parts" "--parts: 'ode'" --parts ode --out "$tmp/x"
expect_error "missing value" "--out needs a value" --out

# One part alone writes only its own files.
"$cli" --quick --runs 1 --parts fcl --out "$tmp/fcl" >/dev/null 2>"$tmp/stderr"
check "--parts fcl exits 0 ($(tail -2 "$tmp/stderr"))" test $? -eq 0
check "--parts fcl writes fcl.csv" test -s "$tmp/fcl/fcl.csv"
check "--parts fcl writes no bullet.csv" test ! -e "$tmp/fcl/bullet.csv"

echo "engines_lab: $pass passed, $fail failed"
[ "$fail" -eq 0 ]
