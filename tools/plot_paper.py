#!/usr/bin/env python3
"""Figures of `broadphase paper`: the study's figures 3.1 to 3.10 and the
frame time up to a million objects, from results.csv; and the ray
experiment's figure from rays.csv (beside results.csv, or given alone).

Usage: plot_paper.py --csv results.csv --out DIR
       plot_paper.py --rays rays.csv --out DIR

Writes every figure as PNG and SVG into DIR. Prints only to stderr, so the
command that runs it keeps stdout for its results. Needs matplotlib.
"""
import argparse
import csv
import json
import os
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))


def lab_data(name):
    """lab/<name>: beside this script when installed, else in the source tree."""
    for d in (HERE, os.path.join(HERE, "..", "lab")):
        path = os.path.join(d, name)
        if os.path.exists(path):
            with open(path) as f:
                return json.load(f)
    raise SystemExit("plot_paper: cannot find " + name + " beside the script or in ../lab")


METRICS = {m["name"]: m for m in lab_data("metrics.json")["metrics"]}
FAMILIES = lab_data("families.json")["families"]
MAX_LINES = 8  # lines per panel: more cannot be told apart by colour
STUDY = tuple(next(f["structures"] for f in FAMILIES if f["name"] == "study"))
STUDY_DISTS = ("even", "uneven")
FORMULA = {  # the study's memory, bytes on its 32-bit machine
    "naive": lambda n: 4 + 4 * n,
    "octree-paper": lambda n: 44460 + 4 * n,
    "hgrid-paper": lambda n: 37452 + 12 * n,
}


def read_rows(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        r["n"] = int(r["n"])
        for k in ("median", "min", "max", "q1", "q3"):
            r[k] = float(r[k])
        r["peer"] = r["peer"] == "1"
    return rows


class Styles:
    """A stable colour, line style and marker per structure."""

    def __init__(self, names):
        cmap = plt.get_cmap("tab20")
        lines = ["-", "--", "-.", ":"]
        markers = ["o", "s", "^", "v", "D", "P", "X", "*"]
        self.style = {}
        others = [n for n in names if n not in STUDY]
        for i, name in enumerate(others):
            self.style[name] = dict(color=cmap(i % 20), linestyle=lines[(i // 20) % 4],
                                    marker=markers[i % len(markers)], linewidth=1.0, markersize=3)
        study_colors = {"naive": "black", "octree-paper": "tab:red", "hgrid-paper": "tab:blue"}
        for name in STUDY:
            self.style[name] = dict(color=study_colors[name], linestyle="-", marker="o",
                                    linewidth=2.4, markersize=5)

    def __call__(self, name):
        return self.style.get(name, {})


def series(rows, test, placement, study_only):
    """{structure: [(n, median, min, max)]} for one test and placement."""
    out = defaultdict(list)
    for r in rows:
        if r["test"] != test or r["placement"] != placement:
            continue
        if study_only and r["dist"] not in STUDY_DISTS:
            continue
        out[r["structure"]].append((r["n"], r["median"], r["min"], r["max"]))
    for v in out.values():
        v.sort()
    return out


def order(names, peers):
    """The study's structures first, then ours, then the peers."""
    return sorted(names, key=lambda s: (s not in STUDY, s in peers, s))


def finish(fig, ax, out, name, title, ylabel, logy=True, legend=True):
    ax.set_xscale("log")
    if logy:
        ax.set_yscale("log")
    ax.set_xlabel("number of objects N")
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="major", alpha=0.3)
    if legend and ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    fig.tight_layout()
    for ext in ("png", "svg"):
        fig.savefig(os.path.join(out, name + "." + ext), dpi=130)
    plt.close(fig)
    print("plot_paper: wrote " + name + ".png/.svg", file=sys.stderr)


def line_plot(rows, styles, peers, out, name, title, test, placement, ylabel, study_only=True,
              only=None, scale=1.0, spread=True):
    data = series(rows, test, placement, study_only)
    if only is not None:
        data = {k: v for k, v in data.items() if k in only}
    if not data:
        return False
    fig, ax = plt.subplots(figsize=(8, 4.8))
    for s in order(data, peers):
        pts = data[s]
        xs = [p[0] for p in pts]
        label = s + (" (peer)" if s in peers else "")
        ax.plot(xs, [p[1] * scale for p in pts], label=label, **styles(s))
        if spread and s in STUDY:
            ax.fill_between(xs, [p[2] * scale for p in pts], [p[3] * scale for p in pts],
                            color=styles(s).get("color"), alpha=0.12, linewidth=0)
    finish(fig, ax, out, name, title, ylabel)
    return True


def placement_plot(rows, styles, out, name, title, test, ylabel):
    fig, ax = plt.subplots(figsize=(8, 4.8))
    drawn = False
    for s in STUDY:
        for placement, ls in (("uneven", "-"), ("even", "--")):
            pts = series(rows, test, placement, True).get(s)
            if not pts:
                continue
            st = dict(styles(s))
            st["linestyle"] = ls
            ax.plot([p[0] for p in pts], [p[1] for p in pts], label=s + ", " + placement, **st)
            drawn = True
    if drawn:
        finish(fig, ax, out, name, title, ylabel)
    else:
        plt.close(fig)


def memory_plots(rows, styles, peers, out):
    data = series(rows, "memory", "even", True)
    if not data:
        return
    fig, ax = plt.subplots(figsize=(8, 4.8))
    for s in order(data, peers):
        pts = data[s]
        ax.plot([p[0] for p in pts], [p[1] for p in pts],
                label=s + (" (peer)" if s in peers else ""), **styles(s))
        if s in FORMULA:
            st = dict(styles(s))
            st.update(linestyle=":", marker=None, linewidth=1.5)
            ax.plot([p[0] for p in pts], [FORMULA[s](p[0]) for p in pts],
                    label=s + ": study's formula (32-bit)", **st)
    finish(fig, ax, out, "fig3_7_memory", "Figure 3.7: memory held (even placement)", "bytes")
    # The lean path reads the caller's arrays in place: its own bytes, and
    # (dashed) with those arrays, which the other structures hold a copy of.
    with_arrays = series(rows, "memory_with_arrays", "even", True)
    fig, ax = plt.subplots(figsize=(8, 4.8))
    for s in order(data, peers):
        pts = data[s]
        ax.plot([p[0] for p in pts], [p[1] / p[0] for p in pts],
                label=s + (" (peer)" if s in peers else ""), **styles(s))
        if s in with_arrays:
            st = dict(styles(s))
            st.update(linestyle="--")
            pts = with_arrays[s]
            ax.plot([p[0] for p in pts], [p[1] / p[0] for p in pts],
                    label=s + " with the caller's arrays", **st)
    finish(fig, ax, out, "fig3_8_memory_per_object", "Figure 3.8: memory per object (even placement)",
           "bytes per object")


def panels(names, peers):
    """[(title, [structures])]: one panel per family (split when it has more
    than MAX_LINES lines), then the structures of no family, then the peers."""
    out = []
    placed = set()

    def add(title, members):
        members = list(members)
        chunks = max(1, -(-len(members) // MAX_LINES))
        for k in range(chunks):
            part = members[k::chunks]
            if part:
                out.append((title + ("" if chunks == 1 else " (%d/%d)" % (k + 1, chunks)), part))

    for fam in FAMILIES:
        members = [s for s in fam["structures"] if s in names and s not in peers]
        placed.update(members)
        add(fam["title"], members)
    add("other", sorted(s for s in names if s not in placed and s not in peers))
    add("peers", sorted(s for s in names if s in peers))
    return out


def small_multiples(data, peers, out, name, title, ylabel, reference=None):
    """One panel per family, the same axes everywhere; in each panel the
    structure lowest at the panel's largest N is drawn thick and named."""
    groups = panels(set(data), peers)
    if not groups:
        return
    cols = 2 if len(groups) > 1 else 1
    rows_n = -(-len(groups) // cols)
    fig, axes = plt.subplots(rows_n, cols, figsize=(6.2 * cols, 3.6 * rows_n), sharex=True,
                             sharey=True, squeeze=False)
    cmap = plt.get_cmap("tab10")
    overall = None
    wins_all = defaultdict(int)
    for ax, (panel, members) in zip(axes.flat, groups):
        # The fastest of a panel is the structure lowest at the most sizes:
        # the lowest at the largest N alone could be one that ran there only
        # because the faster ones were stopped short by the budget.
        by_n = defaultdict(dict)
        for s in members:
            for p in data[s]:
                by_n[p[0]][s] = p[1]
        wins = defaultdict(int)
        for n, vals in by_n.items():
            if len(vals) >= 2:
                wins[min(vals, key=vals.get)] += 1
                wins_all[min(vals, key=vals.get)] += 0  # keep the key
        best = max(wins, key=lambda s: (wins[s], -data[s][-1][1])) if wins else None
        sizes = sum(1 for vals in by_n.values() if len(vals) >= 2)
        for i, s in enumerate(members):
            pts = data[s]
            thick = s == best
            label = ("fastest: %s (lowest at %d of %d N)" % (s, wins[s], sizes)) if thick else s
            ax.plot([p[0] for p in pts], [p[1] for p in pts], color=cmap(i % 10),
                    linewidth=2.6 if thick else 1.0, marker="o", markersize=3 if thick else 2,
                    label=label, zorder=3 if thick else 2)
        if best is not None:
            last = data[best][-1]
            ax.annotate("%.3g" % last[1], (last[0], last[1]), textcoords="offset points",
                        xytext=(4, -3), fontsize=7, fontweight="bold")
        if reference is not None:
            ax.axhline(reference, color="gray", linewidth=0.8)
        ax.set_title(panel, fontsize=9)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=6, loc="upper left", frameon=False)
    by_n = defaultdict(dict)
    for s, pts in data.items():
        for p in pts:
            by_n[p[0]][s] = p[1]
    for vals in by_n.values():
        if len(vals) >= 2:
            wins_all[min(vals, key=vals.get)] += 1
    overall = max(wins_all, key=wins_all.get) if wins_all else None
    for ax in axes.flat[len(groups):]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel("number of objects N")
    for ax in axes[:, 0]:
        ax.set_ylabel(ylabel)
    if overall is not None:
        title += "\nfastest of all: %s, lowest at %d of the %d sizes measured" % (
            overall, wins_all[overall], sum(1 for v in by_n.values() if len(v) >= 2))
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    for ext in ("png", "svg"):
        fig.savefig(os.path.join(out, name + "." + ext), dpi=110)
    plt.close(fig)
    print("plot_paper: wrote " + name + ".png/.svg", file=sys.stderr)


def frame_plots(rows, peers, out):
    label = METRICS["frame_time"]["label"]
    for placement in ("even", "uneven"):
        data = series(rows, "frame_time", placement, False)
        if data:
            small_multiples(data, peers, out, "frame_time_" + placement,
                            "Frame time (" + METRICS["frame_time"]["what"] + "), " + placement +
                            " placement", label)
    # Versus peers: each structure's frame time over the fastest peer's.
    if not peers:
        return
    data = series(rows, "frame_time", "even", False)
    best = {}
    for s, pts in data.items():
        if s in peers:
            for n, med, _, _ in pts:
                if med > 0 and (n not in best or med < best[n]):
                    best[n] = med
    if not best:
        return
    ratios = {}
    for s, pts in data.items():
        r = [(n, med / best[n], 0, 0) for n, med, _, _ in pts if n in best]
        if r:
            ratios[s] = r
    small_multiples(ratios, peers, out, "frame_versus_peers",
                    "Frame time / the fastest peer's at the same N (even placement; below the grey "
                    "line beats every peer)", "ratio", reference=1.0)


RAY_KINDS = ("uniform", "clustered", "boxes", "mixed", "city")
RAY_LINE = {"random": "-", "lidar": "--"}


def rays_figure(path, out):
    """rays.png: rays per second against the object count, one line per
    structure or peer (the fastest of ours as one line whatever its name),
    random rays solid and the lidar fan dashed; a row of panels per kind of
    scene, the static world left and the moving one right."""
    with open(path, newline="") as f:
        rows = [r for r in csv.DictReader(f) if not r["error"] and float(r["rays_per_s"]) > 0]
    if not rows:
        print("plot_paper: " + path + " has no rays measured", file=sys.stderr)
        return
    kinds = [k for k in RAY_KINDS if any(r["kind"] == k for r in rows)]
    kinds += sorted({r["kind"] for r in rows} - set(kinds))

    def line_of(r):
        return "fastest of ours" if r["role"] == "fastest-ours" else r["structure"]

    lines = []
    for r in rows:
        if line_of(r) not in lines:
            lines.append(line_of(r))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    colour = {name: colours[i % len(colours)] for i, name in enumerate(lines)}
    height = 2.8 * len(kinds) + 1.0  # inches: the panels, then the title and legend above
    fig, axes = plt.subplots(len(kinds), 2, figsize=(10, height), squeeze=False, sharex=True,
                             sharey=True)
    for i, kind in enumerate(kinds):
        for j, world in enumerate(("static", "moving")):
            ax = axes[i][j]
            for name in lines:
                for rays, style in RAY_LINE.items():
                    pts = sorted((int(r["n"]), float(r["rays_per_s"])) for r in rows
                                 if r["kind"] == kind and r["world"] == world
                                 and r["rays"] == rays and line_of(r) == name)
                    if pts:
                        ax.plot([p[0] for p in pts], [p[1] for p in pts], style, marker="o",
                                markersize=3, color=colour[name],
                                label=name if (rays == "random") else None)
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.grid(True, which="major", alpha=0.3)
            ax.set_title(kind + ", " + world + (" (movers step between batches)"
                                                 if world == "moving" else ""), fontsize=9)
            if j == 0:
                ax.set_ylabel("rays / s (one thread)")
            if i == len(kinds) - 1:
                ax.set_xlabel("objects")
    handles, labels = [], []
    for ax in axes.flat:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    fig.suptitle("Closest-hit rays per second (solid: random rays; dashed: lidar fan)",
                 fontsize=10, y=1 - 0.1 / height)
    fig.legend(handles, labels, loc="upper center", ncol=min(4, len(labels)), fontsize=8,
               bbox_to_anchor=(0.5, 1 - 0.35 / height))
    fig.tight_layout(rect=(0, 0, 1, 1 - 1.0 / height))
    for ext in ("png", "svg"):
        fig.savefig(os.path.join(out, "rays." + ext), dpi=110)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--csv", help="results.csv written by broadphase paper")
    ap.add_argument("--rays", help="rays.csv of the ray experiment (default: beside --csv)")
    ap.add_argument("--out", required=True, help="directory for the figures")
    a = ap.parse_args()
    if not a.csv and not a.rays:
        ap.error("give --csv, --rays or both")
    os.makedirs(a.out, exist_ok=True)
    rays = a.rays or os.path.join(os.path.dirname(a.csv), "rays.csv")
    if os.path.exists(rays):
        rays_figure(rays, a.out)
    if not a.csv:
        return 0
    rows = read_rows(a.csv)
    if not rows:
        print("plot_paper: " + a.csv + " has no rows", file=sys.stderr)
        return 1
    os.makedirs(a.out, exist_ok=True)
    names = sorted({r["structure"] for r in rows})
    peers = {r["structure"] for r in rows if r["peer"]}
    styles = Styles(names)
    figs = [
        ("fig3_1_query_time_uneven", "Figure 3.1 (Test 1): time of one query, uneven placement",
         "query_time", "uneven", "ns per query"),
        ("fig3_2_query_time_even", "Figure 3.2 (Test 2): time of one query, even placement",
         "query_time", "even", "ns per query"),
        ("fig3_3_query_tests_uneven", "Figure 3.3 (Test 3): narrow-phase tests per query, uneven",
         "query_tests", "uneven", "tests per query"),
        ("fig3_4_query_tests_even", "Figure 3.4 (Test 4): narrow-phase tests per query, even",
         "query_tests", "even", "tests per query"),
        ("fig3_5_insert_time", "Figure 3.5 (Test 5): time to insert one object (even)",
         "insert_time", "even", "ns per insertion"),
        ("fig3_6_remove_time", "Figure 3.6 (Test 6): time to remove one object (even)",
         "remove_time", "even", "ns per removal"),
    ]
    for name, title, test, placement, _ in figs:
        line_plot(rows, styles, peers, a.out, name, title, test, placement, METRICS[test]["label"])
    memory_plots(rows, styles, peers, a.out)
    placement_plot(rows, styles, a.out, "fig3_9_query_time_placement",
                   "Figure 3.9: the study's structures, query time, uneven vs even", "query_time",
                   "ns per query")
    placement_plot(rows, styles, a.out, "fig3_10_query_tests_placement",
                   "Figure 3.10: the study's structures, tests per query, uneven vs even",
                   "query_tests", "tests per query")
    frame_plots(rows, peers, a.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
