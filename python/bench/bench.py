#!/usr/bin/python3
"""broadphase from Python against what Python users reach for, in one run.

Every timing covers what a user waits for: build + query + the (M, 2) int
array of pairs i < j (converted to that form when a library returns
something else). Each entry is the median of several runs (the count is in
the table); every method's pair count is checked against broadphase's.

Workloads (centres uniform in the unit cube):
  monodisperse  N = 1e4 .. 1e6, radius 0.00565 at 1e6 and the same density
                below (r ~ N^(-1/3)): cKDTree.query_pairs(2r, output_type=
                'ndarray'), sklearn radius_neighbors, ASE neighbor_list
  polydisperse  N = 1e5, radii log-uniform over 1, 2, 3 decades below
                r_max = 0.02: cKDTree at 2 r_max + exact filter, ASE with
                per-atom cutoffs
  moving        N = 1e5 monodisperse, 100 frames, 20% moving: Index.update
                + pairs() per frame against rebuilding cKDTree each frame
  boxes         N = 1e4 .. 1e5 boxes: box_pairs against rtree (bulk-loaded,
                intersection_v batch query)

Usage: PYTHONPATH=build/python /usr/bin/python3 python/bench/bench.py [--quick]
       [--out results/python] [--runs 5]
"""

import argparse
import datetime
import json
import os
import pathlib
import platform
import subprocess
import sys
import time

import numpy as np

import broadphase

try:
    from scipy.spatial import cKDTree
    import scipy
except ImportError:  # pragma: no cover - reported in the output
    cKDTree = None
try:
    import sklearn
    from sklearn.neighbors import NearestNeighbors
except ImportError:
    NearestNeighbors = None
try:
    import ase
    from ase import Atoms
    from ase.neighborlist import neighbor_list
except ImportError:
    neighbor_list = None
try:
    import rtree
    from rtree import index as rtree_index
except ImportError:
    rtree_index = None

NOTES = []


def note(msg):
    print("note:", msg, flush=True)
    NOTES.append(msg)


CPU = {}  # id of a measurement's result -> median process CPU seconds


def measure(fn, runs, budget=20.0):
    """Median seconds of `runs` calls of fn after one untimed call (fewer when a call takes long:
    at least 1, and no more than `budget` seconds in all). Returns
    (median, runs done, last result). The median CPU time of the process
    (all its threads) is kept too: on a shared host the wall time carries
    the other tenants' load, the CPU time much less of it."""
    times, cpu = [], []
    out = fn()  # one call untimed, for every method alike: first-touch and cache warm-up
    for _ in range(runs):
        t, c = time.perf_counter(), time.process_time()
        out = fn()
        times.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
        if sum(times) > budget:
            break
    median = float(np.median(times))
    CPU[median] = float(np.median(cpu))
    return median, len(times), out


def upper(i, j):
    keep = i < j
    return np.stack([i[keep], j[keep]], axis=1).astype(np.int64)


# --- the methods -------------------------------------------------------------

def bp_spheres(c, r, threads=1):
    return broadphase.sphere_pairs(c, r, threads=threads)


def kdtree_mono(c, r):
    return cKDTree(c).query_pairs(2 * r, output_type="ndarray")


def kdtree_poly(c, r):
    # One radius for all: query at twice the largest, then filter exactly.
    p = cKDTree(c).query_pairs(2 * r.max(), output_type="ndarray")
    d = c[p[:, 0]] - c[p[:, 1]]
    s = r[p[:, 0]] + r[p[:, 1]]
    return p[np.einsum("ij,ij->i", d, d) <= s * s]


def sklearn_mono(c, r):
    nn = NearestNeighbors(radius=2 * r).fit(c)
    g = nn.radius_neighbors_graph(c, mode="connectivity")
    g = g.tocoo()
    return upper(g.row, g.col)


# ASE works in angstroms: in the unit cube its neighbour list took 72 s for
# 3000 atoms (against 0.7 s scaled up), so positions and cutoffs are scaled
# by 128 (a power of two: the same numbers, exactly) to ASE's usual range
# (cutoffs of a few angstroms).
ASE_SCALE = 128.0


def ase_pairs(c, r):
    atoms = Atoms(positions=c * ASE_SCALE, cell=np.eye(3) * ASE_SCALE, pbc=False)
    # Per-atom cutoffs: atoms i, j are neighbours when d < r_i + r_j.
    cut = np.broadcast_to(np.asarray(r, float) * ASE_SCALE, (len(c),))
    i, j = neighbor_list("ij", atoms, cut, self_interaction=False)
    return upper(i, j)


def rtree_boxes(lo, hi):
    n = len(lo)
    stream = ((k, (lo[k, 0], lo[k, 1], lo[k, 2], hi[k, 0], hi[k, 1], hi[k, 2]), None) for k in range(n))
    p = rtree_index.Property()
    p.dimension = 3
    idx = rtree_index.Index(stream, properties=p)
    if hasattr(idx, "intersection_v"):  # rtree >= 1.1: one batch call
        ids, counts = idx.intersection_v(lo, hi)
        i = np.repeat(np.arange(n), counts)
        return upper(i, ids.astype(np.int64))
    # Debian 12's rtree 1.0: one query per box.
    i, j = [], []
    for k in range(n):
        hits = np.fromiter(idx.intersection((lo[k, 0], lo[k, 1], lo[k, 2], hi[k, 0], hi[k, 1], hi[k, 2])),
                           dtype=np.int64)
        hits = hits[hits > k]
        i.append(np.full(len(hits), k, np.int64))
        j.append(hits)
    return np.stack([np.concatenate(i), np.concatenate(j)], axis=1) if n else np.zeros((0, 2), np.int64)


# --- the workloads -----------------------------------------------------------

def mono_radius(n):
    return 0.00565 * (1e6 / n) ** (1 / 3)


def run_mono(sizes, runs, rng, rows):
    for n in sizes:
        c = rng.random((n, 3))
        r = mono_radius(n)
        t_bp, k_bp, p = measure(lambda: bp_spheres(c, r), runs)
        m = len(p)
        row = {"workload": "monodisperse", "n": n, "param": f"r={r:.5f}", "pairs": m,
               "broadphase": t_bp, "broadphase_runs": k_bp}
        t2, k2, p2 = measure(lambda: bp_spheres(c, r, threads=2), runs)
        assert len(p2) == m
        row["broadphase_2threads"] = t2
        if cKDTree is not None:
            t, k, q = measure(lambda: kdtree_mono(c, r), runs)
            assert len(q) == m, (len(q), m)
            row.update(cKDTree=t, cKDTree_runs=k)
        if NearestNeighbors is not None:
            if n <= 100000:
                t, k, q = measure(lambda: sklearn_mono(c, r), runs)
                assert len(q) == m, (len(q), m)
                row.update(sklearn=t, sklearn_runs=k)
            else:
                note(f"sklearn radius_neighbors skipped at N={n} (left out above 100 000 objects to keep the run short; its time at 100 000 is in the table)")
        if neighbor_list is not None:
            if n <= 100000:
                t, k, q = measure(lambda: ase_pairs(c, r), runs)
                assert abs(len(q) - m) <= 2, (len(q), m)  # ASE: d < cutoff, strict
                row.update(ase=t, ase_runs=k)
            else:
                note(f"ASE neighbor_list skipped at N={n} (left out above 100 000 objects to keep the run short; its time at 100 000 is in the table)")
        rows.append(row)
        print(json.dumps(row), flush=True)


def run_poly(n, runs, rng, rows):
    r_max = 0.02
    for decades in (1, 2, 3):
        c = rng.random((n, 3))
        r = r_max * 10.0 ** (-decades * rng.random(n))
        t_bp, k_bp, p = measure(lambda: bp_spheres(c, r), runs)
        m = len(p)
        row = {"workload": "polydisperse", "n": n, "param": f"{decades} decade{'s' if decades > 1 else ''}",
               "pairs": m, "broadphase": t_bp, "broadphase_runs": k_bp}
        if cKDTree is not None:
            cand = len(cKDTree(c).query_pairs(2 * r_max, output_type="ndarray"))
            row["kdtree_candidates"] = cand
            t, k, q = measure(lambda: kdtree_poly(c, r), runs)
            assert len(q) == m, (len(q), m)
            row.update(cKDTree=t, cKDTree_runs=k)
        if neighbor_list is not None:
            t, k, q = measure(lambda: ase_pairs(c, r), min(runs, 3), budget=30)
            assert abs(len(q) - m) <= 2, (len(q), m)
            row.update(ase=t, ase_runs=k)
        rows.append(row)
        print(json.dumps(row), flush=True)


def run_moving(n, frames, rng, rows):
    r = mono_radius(n)
    c = rng.random((n, 3))
    movers = np.sort(rng.choice(n, size=n // 5, replace=False))
    v = rng.normal(size=(len(movers), 3))
    v *= (0.1 * r) / np.linalg.norm(v, axis=1, keepdims=True)  # a tenth of a radius per frame

    def step():
        p = c[movers] + v
        out = (p < 0) | (p > 1)
        v[out] = -v[out]
        p[out] = c[movers][out]
        c[movers] = p

    ix = broadphase.Index(c, r)  # borrows c: moved in place below
    bp_times, kd_times, bp_cpu, kd_cpu, pair_counts = [], [], [], [], []
    for f in range(frames):
        step()
        t, u = time.perf_counter(), time.process_time()
        ix.update(movers)
        p = ix.pairs()
        bp_times.append(time.perf_counter() - t)
        bp_cpu.append(time.process_time() - u)
        pair_counts.append(len(p))
        if cKDTree is not None:
            t, u = time.perf_counter(), time.process_time()
            q = kdtree_mono(c, r)
            kd_times.append(time.perf_counter() - t)
            kd_cpu.append(time.process_time() - u)
            assert len(q) == len(p), (f, len(q), len(p))
    row = {"workload": "moving", "n": n, "param": f"{frames} frames, 20% moving", "pairs": int(np.median(pair_counts)),
           "broadphase": float(np.median(bp_times)), "broadphase_runs": frames,
           "broadphase_cpu": float(np.median(bp_cpu))}
    if kd_times:
        row.update(cKDTree=float(np.median(kd_times)), cKDTree_runs=frames, cKDTree_cpu=float(np.median(kd_cpu)))
    rows.append(row)
    print(json.dumps(row), flush=True)


def run_boxes(sizes, runs, rng, rows):
    for n in sizes:
        c = rng.random((n, 3))
        h = rng.random((n, 3)) * 2 * mono_radius(n)
        lo, hi = c - h, c + h
        t_bp, k_bp, p = measure(lambda: broadphase.box_pairs(lo, hi), runs)
        m = len(p)
        row = {"workload": "boxes", "n": n, "param": "half-extents U(0, 2r)", "pairs": m,
               "broadphase": t_bp, "broadphase_runs": k_bp}
        if rtree_index is not None:
            t, k, q = measure(lambda: rtree_boxes(lo, hi), runs)
            assert len(q) == m, (len(q), m)
            row.update(rtree=t, rtree_runs=k)
        rows.append(row)
        print(json.dumps(row), flush=True)


# --- the report --------------------------------------------------------------

def machine():
    cpu = "unknown CPU"
    try:
        for ln in open("/proc/cpuinfo"):
            if ln.startswith("model name"):
                cpu = ln.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        osname = [ln.split("=", 1)[1].strip().strip('"') for ln in open("/etc/os-release")
                  if ln.startswith("PRETTY_NAME=")][0]
    except (OSError, IndexError):
        osname = platform.platform()
    root = pathlib.Path(__file__).resolve().parents[2]
    try:
        commit = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"],
                                capture_output=True, text=True).stdout.strip()
    except OSError:
        commit = "?"
    v = {"python": platform.python_version(), "numpy": np.__version__, "broadphase": broadphase.__version__}
    if cKDTree is not None:
        v["scipy"] = scipy.__version__
    if NearestNeighbors is not None:
        v["sklearn"] = sklearn.__version__
    if neighbor_list is not None:
        v["ase"] = ase.__version__
    if rtree_index is not None:
        v["rtree"] = rtree.__version__
    return {"cpu": cpu, "cores": os.cpu_count(), "os": osname, "commit": commit, "versions": v,
            "date": datetime.datetime.utcnow().strftime("%Y-%m-%d %H:%M UTC"),
            "load_at_start": os.getloadavg()[0]}


PEERS = ["cKDTree", "sklearn", "ase", "rtree"]


def ms(t):
    return "" if t is None else (f"{t * 1e3:.1f}" if t < 10 else f"{t * 1e3:.0f}")


def markdown(rows, info, args):
    out = ["# broadphase from Python against cKDTree, sklearn, ASE and rtree", "",
           f"Machine: {info['cpu']}, {info['cores']} cores, {info['os']}. Run {info['date']}, "
           f"commit {info['commit']}.", "",
           "Versions: " + ", ".join(f"{k} {v}" for k, v in info["versions"].items()) + ".", "",
           "Times in milliseconds: build + query + the (M, 2) int array of pairs i < j, the median "
           "of the runs in brackets (moving: the median per frame over the frames). broadphase runs on "
           "one thread unless said; the ratio is the peer's time over broadphase's. Every method's "
           "pair count was checked against broadphase's (ASE counts d < cutoff, strictly, and may "
           "differ by a tie).", "",
           f"Command: `PYTHONPATH=build/python /usr/bin/python3 python/bench/bench.py {' '.join(sys.argv[1:])}`", "",
           f"Host load (1-minute average) at the start: {info.get('load_at_start', 0):.1f}, at the end: "
           f"{info.get('load_at_end', 0):.1f}, on {info['cores']} cores. The CPU ratio compares the process "
           "CPU time of the two calls (medians), which a loaded host distorts less than the wall time.", ""]
    for wl in ["monodisperse", "polydisperse", "moving", "boxes"]:
        sel = [r for r in rows if r["workload"] == wl]
        if not sel:
            continue
        peers = [p for p in PEERS if any(p in r for r in sel)]
        extra = ["broadphase_2threads"] if any("broadphase_2threads" in r for r in sel) else []
        head = ["N", "case", "pairs", "broadphase"] + (["broadphase, 2 threads"] if extra else [])
        for p in peers:
            head += [p, f"{p} / broadphase", "CPU ratio"]
        if wl == "polydisperse":
            head.append("cKDTree candidates")
        out += [f"## {wl}", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for r in sel:
            cells = [f"{r['n']:,}", r["param"], f"{r['pairs']:,}", f"{ms(r['broadphase'])} ({r['broadphase_runs']})"]
            if extra:
                cells.append(ms(r.get("broadphase_2threads")))
            for p in peers:
                if p in r:
                    cpu_p, cpu_b = r.get(p + "_cpu"), r.get("broadphase_cpu")
                    cells += [f"{ms(r[p])} ({r[p + '_runs']})", f"**{r[p] / r['broadphase']:.1f}x**",
                              f"{cpu_p / cpu_b:.1f}x" if cpu_p and cpu_b else ""]
                else:
                    cells += ["skipped", "", ""]
            if wl == "polydisperse":
                cells.append(f"{r.get('kdtree_candidates', 0):,}")
            out.append("| " + " | ".join(cells) + " |")
        out.append("")
    if NOTES:
        out += ["## Skipped", ""] + [f"- {n}" for n in NOTES] + [""]
    return "\n".join(out)


def plot(rows, path):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        note("matplotlib missing: no plot")
        return
    fig, axes = plt.subplots(1, 4, figsize=(18, 4.5))
    styles = {"broadphase": "o-", "broadphase_2threads": "o--", "cKDTree": "s-", "sklearn": "^-",
              "ase": "v-", "rtree": "D-"}
    for ax, wl, xkey in zip(axes, ["monodisperse", "polydisperse", "moving", "boxes"],
                            ["n", "param", "n", "n"]):
        sel = [r for r in rows if r["workload"] == wl]
        if not sel:
            ax.set_visible(False)
            continue
        for m, st in styles.items():
            pts = [(r[xkey], r[m]) for r in sel if m in r]
            if not pts:
                continue
            if wl == "moving":
                ax.bar([m], [pts[0][1] * 1e3])
                continue
            xs = [p[0] for p in pts]
            ax.plot(range(len(xs)) if xkey == "param" else xs, [p[1] * 1e3 for p in pts], st,
                    label=m.replace("_", ", "))
            if xkey == "param":
                ax.set_xticks(range(len(xs)), xs)
        ax.set_yscale("log")
        if xkey == "n" and wl != "moving":
            ax.set_xscale("log")
            ax.set_xlabel("objects")
        ax.set_ylabel("ms per frame" if wl == "moving" else "ms (build + pairs array)")
        ax.set_title(f"{wl}" + (f" (N={sel[0]['n']:,})" if wl in ("polydisperse", "moving") else ""))
        ax.grid(True, which="both", alpha=0.3)
        if wl != "moving":
            ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="small sizes, a minute or so")
    ap.add_argument("--runs", type=int, default=5, help="runs per entry (median)")
    ap.add_argument("--out", default=None, help="results folder (default results/python/<date>)")
    ap.add_argument("--seed", type=int, default=20261125)
    ap.add_argument("--only", default="mono,poly,moving,boxes",
                    help="workloads to run, comma-separated (mono, poly, moving, boxes)")
    ap.add_argument("--skip", default="", help="peers to leave out, comma-separated (scipy, sklearn, ase, rtree)")
    ap.add_argument("--mono-sizes", default=None,
                    help="monodisperse sizes, comma-separated (default 1e4,3e4,1e5,3e5,1e6)")
    args = ap.parse_args()
    root = pathlib.Path(__file__).resolve().parents[2]
    out = pathlib.Path(args.out) if args.out else root / "results" / "python" / datetime.date.today().isoformat()
    out.mkdir(parents=True, exist_ok=True)
    global cKDTree, NearestNeighbors, neighbor_list, rtree_index
    skip = set(filter(None, args.skip.split(",")))
    for name in skip:
        note(f"{name} left out of this run (--skip)")
    cKDTree = None if "scipy" in skip else cKDTree
    NearestNeighbors = None if "sklearn" in skip else NearestNeighbors
    neighbor_list = None if "ase" in skip else neighbor_list
    rtree_index = None if "rtree" in skip else rtree_index
    for name, mod in [("scipy", cKDTree), ("sklearn", NearestNeighbors), ("ase", neighbor_list), ("rtree", rtree_index)]:
        if mod is None and name not in skip:
            note(f"{name} is not installed: its comparisons are skipped (tools/deps.sh installs it)")
    rng = np.random.default_rng(args.seed)
    info = machine()
    print(json.dumps(info), flush=True)
    rows = []
    only = set(args.only.split(","))
    mono = [10000, 30000] if args.quick else [10000, 30000, 100000, 300000, 1000000]
    if args.mono_sizes:
        mono = [int(float(v)) for v in args.mono_sizes.split(",")]
    if "mono" in only:
        run_mono(mono, args.runs, rng, rows)
    if "poly" in only:
        run_poly(20000 if args.quick else 100000, args.runs, rng, rows)
    if "moving" in only:
        run_moving(20000 if args.quick else 100000, 20 if args.quick else 100, rng, rows)
    if "boxes" in only:
        run_boxes([10000] if args.quick else [10000, 100000], args.runs, rng, rows)
    info["load_at_end"] = os.getloadavg()[0]
    for r in rows:  # the CPU medians of the entries measured by measure()
        for k in ["broadphase", "broadphase_2threads"] + PEERS:
            if k in r and k + "_cpu" not in r and r[k] in CPU:
                r[k + "_cpu"] = CPU[r[k]]
    (out / "bench.json").write_text(json.dumps({"machine": info, "rows": rows, "notes": NOTES}, indent=1))
    plot(rows, out / "bench.png")
    (out / "bench.md").write_text(markdown(rows, info, args))
    print(f"wrote {out}/bench.md, bench.png, bench.json")


if __name__ == "__main__":
    sys.exit(main())
