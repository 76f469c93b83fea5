#!/usr/bin/python3
"""broadphase.knn against scipy's cKDTree and pykdtree, side by side in one
run: N points queried by themselves, k = 1, 8, 32, one thread each, build
included (what a user waits for). Each cell is the median of --runs runs,
the libraries alternating; every library's k-th distances are compared with
ours row by row.

Sets (unit cube): uniform; clustered: 1 000 Gaussian blobs (sigma 0.01),
centres uniform in the cube, every point in a blob (as bench/knn/knn_bench.cpp).

Usage: PYTHONPATH=build/python /usr/bin/python3 python/bench/knn.py
       [--n 1000000] [--runs 3] [--k 1,8,32] [--sets uniform,clustered]
"""

import os

# pykdtree queries on OpenMP threads: one, as the others (set before import).
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import platform  # noqa: E402
import subprocess  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from scipy.spatial import cKDTree  # noqa: E402

import broadphase  # noqa: E402

try:
    from pykdtree.kdtree import KDTree as PyKDTree  # noqa: E402
except ImportError:
    PyKDTree = None


def _version(package):
    """A Debian package's version (pykdtree has no __version__)."""
    try:
        out = subprocess.run(["dpkg-query", "-W", "-f=${Version}", package],
                             capture_output=True, text=True, check=True)
        return out.stdout
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def make(kind, n):
    rng = np.random.default_rng(2026)
    if kind == "uniform":
        return rng.uniform(0, 1, (n, 3))
    centres = rng.uniform(0, 1, (1000, 3))
    return centres[rng.integers(0, 1000, n)] + rng.normal(0, 0.01, (n, 3))


def ours(p, k):
    return broadphase.knn(p, k=k)


def ckdtree(p, k):
    return cKDTree(p).query(p, k, workers=1)


def pykdtree(p, k):
    return PyKDTree(p).query(p, k=k)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=1_000_000)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--k", default="1,8,32")
    ap.add_argument("--sets", default="uniform,clustered")
    args = ap.parse_args()
    libs = [("broadphase", ours), ("cKDTree", ckdtree)]
    if PyKDTree is not None:
        libs.append(("pykdtree", pykdtree))
    print(f"# knn of {args.n} points queried by themselves, one thread, build included; "
          f"medians of {args.runs} runs")
    print(f"# {platform.node()} {platform.processor() or platform.machine()}, "
          f"numpy {np.__version__}, scipy {__import__('scipy').__version__}, "
          f"pykdtree {_version('python3-pykdtree') if PyKDTree else 'absent'}")
    head = "| set | k | " + " | ".join(f"{name} s" for name, _ in libs) + " | " + \
        " | ".join(f"{name} / ours" for name, _ in libs[1:]) + " | k-th equal |"
    print(head)
    print("|" + "---|" * (head.count("|") - 1))
    for kind in args.sets.split(","):
        if kind not in ("uniform", "clustered"):
            ap.error(f"--sets: unknown set {kind!r} (uniform, clustered)")
        p = make(kind, args.n)
        for k in (int(v) for v in args.k.split(",")):
            times = {name: [] for name, _ in libs}
            results = {}
            for _ in range(args.runs):
                for name, f in libs:
                    t0 = time.perf_counter()
                    results[name] = f(p, k)
                    times[name].append(time.perf_counter() - t0)
                    del t0
            med = {name: float(np.median(v)) for name, v in times.items()}
            kth = lambda d: (d if d.ndim == 1 else d[:, -1])  # noqa: E731
            mine = kth(results["broadphase"][0])
            equal = min(float(np.mean(kth(np.asarray(results[name][0])) == mine))
                        for name, _ in libs[1:])
            row = f"| {kind} | {k} | " + " | ".join(f"{med[name]:.3f}" for name, _ in libs) + \
                " | " + " | ".join(f"{med[name] / med['broadphase']:.2f}" for name, _ in libs[1:]) + \
                f" | {100 * equal:.3f} % |"
            print(row, flush=True)
            results.clear()


if __name__ == "__main__":
    main()
