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
counts are checked against broadphase's. Ours runs on each of --threads
(default 1 and 2): the first gives the wall and CPU ratios, each other one
a wall ratio (the peers run on one thread), its arrays checked equal to the
first's.

With --moving: a moving system instead, 100 frames (--frames) of
thermal-like motion of N points in the cube at the same density: each point
has a velocity, Gaussian with 0.015 Å a frame per axis (--step; a mean
step of 0.024 Å), that relaxes towards a new random one (v = 0.9 v + 0.44 noise,
the velocity autocorrelation of a liquid over a few frames), and the
positions are wrapped into the cell after each step (points cross the
faces). broadphase.NeighbourList('ijS', 3.0, skin=...) updated on every
frame (its total CPU time over the frames, rebuilds included, divided by
the frames; median of --runs replays of the same trajectory), against
rebuilding each frame: cKDTree(x, boxsize=L).query_pairs(3.0) and our own
one-shot neighbor_list('ijS'), each timed on --peer-frames frames spread
over the trajectory (their cost does not depend on the frame), median;
every list checked against the one-shot one on those frames. --skins
measures several skins (the default skin's choice).

Usage: PYTHONPATH=build/python /usr/bin/python3 python/bench/neighbours.py
       [--sizes 1000 10000 100000 1000000] [--runs 5] [--ase-max 100000] [--threads 1 2]
       [--moving [--frames 100] [--peer-frames 5] [--skins 0.3 0.6]]
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


STEP = 0.015  # Å a frame per axis: the velocity's standard deviation
MEMORY = 0.9  # the velocity's autocorrelation from one frame to the next


def trajectory(n, frames, seed, step=STEP):
    """The positions of each frame of the moving system (generated on the
    fly: 10^6 points take 24 MB a frame) and the cube's side."""
    rng = np.random.default_rng(seed)
    side = (n / DENSITY) ** (1 / 3)
    x = rng.uniform(0, side, (n, 3))
    v = rng.normal(0, step, (n, 3))
    for frame in range(frames):
        if frame:
            v *= MEMORY
            v += rng.normal(0, step * np.sqrt(1 - MEMORY ** 2), (n, 3))
            x += v
            np.mod(x, side, out=x)
            x[x >= side] = 0.0  # a tiny negative x rounds to side (cKDTree wants [0, side))
        yield x, side


def cpu_call(fn):
    c = time.process_time()
    out = fn()
    return time.process_time() - c, out


def timed_call(fn):
    """CPU and wall seconds of one call, and its result."""
    t, c = time.perf_counter(), time.process_time()
    out = fn()
    return time.process_time() - c, time.perf_counter() - t, out


def moving(args, cpu, versions):
    """The moving-system table (see the module's docstring)."""
    rows = []
    for n in args.sizes:
        side = (n / DENSITY) ** (1 / 3)
        peer_frames = set(np.linspace(0, args.frames - 1, args.peer_frames).astype(int).tolist())
        # Rebuilding each frame: cKDTree and our one-shot list on a few
        # frames; the moving lists are checked against the one-shot ones.
        kd_cpu, kd_wall, one_cpu, checks = [], [], [], {}
        for frame, (x, _) in enumerate(trajectory(n, args.frames, n, args.step)):
            if frame not in peer_frames:
                continue
            c, one = cpu_call(lambda: broadphase.neighbor_list("ijS", x, CUTOFF, cell=side,
                                                               strict=True))
            one_cpu.append(c)
            checks[frame] = one
            if cKDTree is not None:
                c, w, p = timed_call(lambda: cKDTree(x, boxsize=side).query_pairs(
                    CUTOFF, output_type="ndarray"))
                kd_cpu.append(c)
                kd_wall.append(w)
                if len(p) != len(one[0]):
                    print(f"note: cKDTree found {len(p)} pairs, broadphase {len(one[0])} "
                          f"(n {n}, frame {frame}): ties at the cutoff")
        for skin, threads in [(s, t) for s in args.skins or [None] for t in args.threads]:
            totals, walls, rebuilds = [], [], 0
            for run in range(args.runs):
                nl = broadphase.NeighbourList("ijS", CUTOFF, skin=skin, cell=side, strict=True,
                                              threads=threads)
                total = wall = 0.0
                for frame, (x, _) in enumerate(trajectory(n, args.frames, n, args.step)):
                    c, w, out = timed_call(lambda: nl.update(x))
                    total += c
                    wall += w
                    if run == 0 and frame in checks:
                        assert all(np.array_equal(a, b) for a, b in zip(out, checks[frame])), \
                            f"n {n} frame {frame}: the moving list differs from the one-shot one"
                totals.append(total)
                walls.append(wall)
                rebuilds = nl.rebuilds
                if total > args.budget:
                    break
            per_frame = float(np.median(totals)) / args.frames
            per_frame_wall = float(np.median(walls)) / args.frames
            row = {"n": n, "frames": args.frames, "step": args.step, "skin": nl.skin,
                   "threads": threads, "rebuilds": rebuilds,
                   "pairs": len(checks[min(checks)][0]), "candidates": nl.candidates,
                   "moving_cpu": per_frame, "moving_wall": per_frame_wall, "runs": len(totals),
                   "oneshot_cpu": float(np.median(one_cpu)),
                   "oneshot_cpu_ratio": float(np.median(one_cpu)) / per_frame}
            if kd_cpu:
                row.update(ckdtree_cpu=float(np.median(kd_cpu)),
                           ckdtree_cpu_ratio=float(np.median(kd_cpu)) / per_frame,
                           ckdtree_wall=float(np.median(kd_wall)),
                           ckdtree_wall_ratio=float(np.median(kd_wall)) / per_frame_wall)
            rows.append(row)
            print(json.dumps(row), flush=True)

    print()
    print("| N | pairs | skin Å | threads | rebuilds | moving, CPU s a frame (wall) "
          "| one-shot each frame × (CPU) | cKDTree each frame × (CPU; wall) |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        kd = (f"{r['ckdtree_cpu_ratio']:.1f}×; {r['ckdtree_wall_ratio']:.1f}×"
              if "ckdtree_cpu_ratio" in r else "—")
        print(f"| {r['n']:,} | {r['pairs']:,} | {r['skin']:.2f} | {r['threads']} | "
              f"{r['rebuilds']} / {r['frames']} | {r['moving_cpu']:.4f} ({r['moving_wall']:.4f}) | "
              f"{r['oneshot_cpu_ratio']:.1f}× | {kd} |")
    if args.out:
        with open(args.out, "w") as f:
            json.dump({"machine": cpu, "versions": versions, "rows": rows}, f, indent=1)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000, 100000, 1000000])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--ase-max", type=int, default=100000,
                    help="largest N for ASE (its memory grows fast)")
    ap.add_argument("--out", help="write the rows as JSON here")
    ap.add_argument("--moving", action="store_true",
                    help="the moving system: NeighbourList over frames against rebuilding")
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--peer-frames", type=int, default=5,
                    help="frames on which the rebuilding methods are timed")
    ap.add_argument("--skins", type=float, nargs="+",
                    help="skins to measure (default: the list's default)")
    ap.add_argument("--step", type=float, default=STEP,
                    help="the velocity's standard deviation per axis, Å a frame")
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2],
                    help="thread counts of ours (threads=); the first is the one the CPU ratios "
                         "are of, the others are compared by wall time")
    ap.add_argument("--budget", type=float, default=60.0,
                    help="CPU seconds after which a moving case stops repeating")
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
    if args.moving:
        moving(args, cpu, versions)
        return
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
                    return broadphase.neighbor_list("ijS", x, cutoff, cell=cell, strict=True,
                                                    threads=args.threads[0])

                w, c, k, out = measure(ours, args.runs)
                pairs = len(out[0])
                row.update(pairs=pairs, broadphase=w, broadphase_cpu=c, runs=k)
                for threads in args.threads[1:]:
                    def ours_threads():
                        return broadphase.neighbor_list("ijS", x, cutoff, cell=cell, strict=True,
                                                        threads=threads)

                    w, _, _, more = measure(ours_threads, args.runs)
                    assert all(np.array_equal(a, b) for a, b in zip(out, more))
                    row[f"broadphase_t{threads}"] = w

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
                        for threads in args.threads[1:]:
                            row[f"{peer}_ratio_t{threads}"] = (row[peer] /
                                                               row[f"broadphase_t{threads}"])
                        row[f"{peer}_ratio"] = row[peer] / row["broadphase"]
                        row[f"{peer}_cpu_ratio"] = row[f"{peer}_cpu"] / row["broadphase_cpu"]
                        if row[f"{peer}_pairs"] != pairs:
                            print(f"note: {peer} found {row[f'{peer}_pairs']} pairs, broadphase "
                                  f"{pairs} (n {n}, {row['cell']}, cutoff {row['cutoff']}): ties "
                                  "at the cutoff or float32 coordinates")
                rows.append(row)
                print(json.dumps(row), flush=True)

    print()
    more = args.threads[1:]
    print("| cell | cutoff | N | pairs | broadphase s (cpu) | "
          + "".join(f"{t} threads, s | " for t in more)
          + "cKDTree × | MDAnalysis nsgrid × | ASE × |")
    print("|---|---|---:|---:|---:|" + "---:|" * len(more) + "---:|---:|---:|")
    for r in rows:
        def ratio(peer):
            if peer not in r:
                return "—"
            text = f"{r[peer + '_ratio']:.1f} ({r[peer + '_cpu_ratio']:.1f})"
            return text + "".join(f"; {r[f'{peer}_ratio_t{t}']:.1f}" for t in more)

        print(f"| {r['cell']} | {r['cutoff']} | {r['n']:,} | {r['pairs']:,} | "
              f"{r['broadphase']:.4f} ({r['broadphase_cpu']:.4f}) | "
              + "".join(f"{r[f'broadphase_t{t}']:.4f} | " for t in more)
              + f"{ratio('ckdtree')} | {ratio('mdanalysis')} | {ratio('ase')} |")
    if args.out:
        with open(args.out, "w") as f:
            json.dump({"machine": cpu, "versions": versions, "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
