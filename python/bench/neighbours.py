#!/usr/bin/python3
"""Periodic neighbour lists from Python, side by side in one run:
broadphase.neighbor_list against ASE's neighbor_list, MDAnalysis' grid
search (self_capped_distance, method='nsgrid'), scipy's
cKDTree(boxsize=...).query_pairs and pymatgen (when installed).

Workload: N points uniform in a periodic cell at a water-like number
density of 0.1 per Å^3, cutoff 3 Å (~5.7 pairs a point, half list), or
per-atom cutoffs c_i uniform in [1.2, 1.8] Å (pairs when |d| < c_i + c_j);
an orthorhombic cube, and a triclinic cell of the same volume (box
[l, l, l, 75, 85, 95] in MDAnalysis' notation; cKDTree has no triclinic
cells). Each timing is what a user waits for: build + query + the arrays
(broadphase and cKDTree: half-list pairs; broadphase with shifts, 'ijS';
MDAnalysis: pairs; ASE: its full list 'ijS', the only form it has). With
per-atom cutoffs, cKDTree and MDAnalysis run at the largest reach (3.6 Å)
and a numpy filter keeps the pairs within c_i + c_j. Medians of --runs
runs (fewer when a call takes long), wall and process CPU time; the pair
counts are checked against broadphase's.

Usage: PYTHONPATH=build/python /usr/bin/python3 python/bench/neighbours.py
       [--sizes 1000 10000 100000 1000000] [--runs 5] [--ase-max 100000]
       [--out FILE.json]
"""

import argparse
import json
import platform
import time

import numpy as np

import broadphase

try:
    import scipy
    from scipy.spatial import cKDTree
except ImportError:  # pragma: no cover - reported in the output
    cKDTree = None
try:
    import ase
    from ase import Atoms
    from ase.neighborlist import neighbor_list as ase_neighbor_list
except ImportError:
    ase_neighbor_list = None
try:
    import MDAnalysis
    from MDAnalysis.lib.distances import self_capped_distance
except ImportError:
    self_capped_distance = None
try:
    import pymatgen  # noqa: F401
    from pymatgen.core import Lattice, Structure
except ImportError:
    Structure = None

DENSITY = 0.1
CUTOFF = 3.0
ANGLES = (75.0, 85.0, 95.0)


def measure(fn, runs, budget=40.0):
    """Median wall and CPU seconds of `runs` calls after one untimed call
    (fewer when they pass `budget` seconds; a first call over a sixth of it
    is the only one, timed)."""
    t, c = time.perf_counter(), time.process_time()
    out = fn()
    first = time.perf_counter() - t
    if first > budget / 6:
        return first, time.process_time() - c, 1, out
    wall, cpu = [], []
    for _ in range(runs):
        t, c = time.perf_counter(), time.process_time()
        out = fn()
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
        if sum(wall) > budget:
            break
    return float(np.median(wall)), float(np.median(cpu)), len(wall), out


def cell_of(n, triclinic):
    """The cell matrix (rows) and MDAnalysis box of volume n / DENSITY."""
    volume = n / DENSITY
    if not triclinic:
        l = volume ** (1 / 3)
        return np.diag([l, l, l]), np.array([l, l, l, 90, 90, 90], np.float32)
    ca, cb, cg = np.cos(np.deg2rad(ANGLES))
    shape = np.sqrt(1 - ca * ca - cb * cb - cg * cg + 2 * ca * cb * cg)
    l = (volume / shape) ** (1 / 3)
    box = np.array([l, l, l, *ANGLES], np.float32)
    return broadphase.mdanalysis.triclinic_vectors(box).astype(np.float64), box


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000, 100000, 1000000])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--ase-max", type=int, default=100000,
                    help="largest N for ASE (its memory grows fast)")
    ap.add_argument("--out", help="write the rows as JSON here")
    args = ap.parse_args()

    versions = {"numpy": np.__version__, "broadphase": broadphase.__version__}
    if cKDTree is not None:
        versions["scipy"] = scipy.__version__
    if ase_neighbor_list is not None:
        versions["ase"] = ase.__version__
    if self_capped_distance is not None:
        versions["MDAnalysis"] = MDAnalysis.__version__
    cpu = platform.processor()
    try:
        cpu = [ln.split(":", 1)[1].strip() for ln in open("/proc/cpuinfo")
               if ln.startswith("model name")][0]
    except (OSError, IndexError):
        pass
    print(f"machine: {cpu}, {platform.node()}; versions {versions}")
    if Structure is None:
        print("note: pymatgen is not installed (not in Debian 12): not measured")

    rows = []
    rng = np.random.default_rng(2026)
    for triclinic in (False, True):
        for per_atom in (False, True):
            for n in args.sizes:
                cell, box = cell_of(n, triclinic)
                x = rng.uniform(0, 1, (n, 3)) @ cell
                x32 = x.astype(np.float32)
                radii = rng.uniform(1.2, 1.8, n) if per_atom else None
                cutoff = radii if per_atom else CUTOFF
                reach = 3.6 if per_atom else CUTOFF
                # Strict, as ASE, so that every method counts the same pairs.
                row = {"n": n, "cell": "triclinic" if triclinic else "orthorhombic",
                       "cutoff": "per-atom 1.2-1.8" if per_atom else f"{CUTOFF}"}

                def ours():
                    return broadphase.neighbor_list("ijS", x, cutoff, cell=cell, strict=True)

                w, c, k, out = measure(ours, args.runs)
                pairs = len(out[0])
                row.update(pairs=pairs, broadphase=w, broadphase_cpu=c, runs=k)

                if cKDTree is not None and not triclinic:
                    L = np.diag(cell).copy()

                    def kd():
                        p = cKDTree(x, boxsize=L).query_pairs(reach, output_type="ndarray")
                        if per_atom:
                            d = x[p[:, 1]] - x[p[:, 0]]
                            d -= np.round(d / L) * L
                            p = p[np.einsum("ij,ij->i", d, d) < (radii[p[:, 0]] + radii[p[:, 1]]) ** 2]
                        return p

                    w, c, _, p = measure(kd, args.runs)
                    row.update(ckdtree=w, ckdtree_cpu=c, ckdtree_pairs=len(p))

                if self_capped_distance is not None:
                    def ns():
                        if not per_atom:
                            return self_capped_distance(x32, CUTOFF, box=box, method="nsgrid",
                                                        return_distances=False)
                        p, d = self_capped_distance(x32, reach, box=box, method="nsgrid")
                        return p[d < radii[p[:, 0]] + radii[p[:, 1]]]

                    w, c, _, p = measure(ns, args.runs)
                    row.update(mdanalysis=w, mdanalysis_cpu=c, mdanalysis_pairs=len(p))

                if ase_neighbor_list is not None and n <= args.ase_max:
                    atoms = Atoms(positions=x, cell=cell, pbc=True)

                    def ase_nl():
                        return ase_neighbor_list("ijS", atoms, cutoff)

                    w, c, _, p = measure(ase_nl, min(args.runs, 3))
                    row.update(ase=w, ase_cpu=c, ase_pairs=len(p[0]) // 2)

                for peer in ("ckdtree", "mdanalysis", "ase"):
                    if peer in row:
                        row[f"{peer}_ratio"] = row[peer] / row["broadphase"]
                        row[f"{peer}_cpu_ratio"] = row[f"{peer}_cpu"] / row["broadphase_cpu"]
                        if row[f"{peer}_pairs"] != pairs:
                            print(f"note: {peer} found {row[f'{peer}_pairs']} pairs, broadphase "
                                  f"{pairs} (n {n}, {row['cell']}, cutoff {row['cutoff']}): ties "
                                  "at the cutoff or float32 coordinates")
                rows.append(row)
                print(json.dumps(row), flush=True)

    print()
    print("| cell | cutoff | N | pairs | broadphase s (cpu) | cKDTree × | MDAnalysis nsgrid × | ASE × |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        def ratio(peer):
            if peer not in r:
                return "—"
            return f"{r[peer + '_ratio']:.1f} ({r[peer + '_cpu_ratio']:.1f})"

        print(f"| {r['cell']} | {r['cutoff']} | {r['n']:,} | {r['pairs']:,} | "
              f"{r['broadphase']:.4f} ({r['broadphase_cpu']:.4f}) | {ratio('ckdtree')} | "
              f"{ratio('mdanalysis')} | {ratio('ase')} |")
    if args.out:
        with open(args.out, "w") as f:
            json.dump({"machine": cpu, "versions": versions, "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
