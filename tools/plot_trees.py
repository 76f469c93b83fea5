#!/usr/bin/env python3
"""Figures of the trees-and-sweeps lab experiment.

Usage: plot_trees.py OUT_DIR
Reads tree_orderings.csv, tree_front.csv and sweeps.csv from OUT_DIR and
writes trees_orderings.png, trees_front.png and trees_sweeps.png beside them.
"""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def bars(ax, labels, values, title, ylabel, log=False):
    ax.bar(range(len(values)), values, color="#4c72b0")
    if log:
        # The explosion dwarfs the coherent scene; a log axis keeps both legible.
        ax.set_yscale("log")
    ax.set_xticks(range(len(labels)))
    ax.set_xticklabels(labels, rotation=30, ha="right", fontsize=8)
    ax.set_title(title, fontsize=10)
    ax.set_ylabel(ylabel)


def main():
    out = sys.argv[1]
    rows = read(os.path.join(out, "tree_orderings.csv"))
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6))
    labels = [r["order"] for r in rows]
    bars(axes[0], labels, [float(r["pairs_ms"]) for r in rows], "all pairs", "ms per frame")
    bars(axes[1], labels, [float(r["node_tests"]) for r in rows], "all pairs", "node-pair tests")
    bars(axes[2], labels, [float(r["touch_node_tests"]) for r in rows], "touch query",
         "node tests per query")
    fig.tight_layout()
    fig.savefig(os.path.join(out, "trees_orderings.png"), dpi=110)

    rows = read(os.path.join(out, "tree_front.csv"))
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    labels = [f'{r["scene"]}\n{r["front"]}' for r in rows]
    bars(axes[0], labels, [float(r["pairs_ms"]) for r in rows], "front tracking", "all pairs ms",
         log=True)
    bars(axes[1], labels, [float(r["node_tests"]) for r in rows], "front tracking",
         "node-pair tests", log=True)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "trees_front.png"), dpi=110)

    rows = read(os.path.join(out, "sweeps.csv"))
    fig, ax = plt.subplots(figsize=(7, 3.6))
    labels = [f'{r["scene"]}\n{r["algo"]}' for r in rows]
    bars(ax, labels, [float(r["frame_ms"]) for r in rows], "update + all pairs",
         "median frame ms", log=True)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "trees_sweeps.png"), dpi=110)


if __name__ == "__main__":
    main()
