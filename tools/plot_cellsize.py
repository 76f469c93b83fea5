#!/usr/bin/env python3
"""Plots the lab's cell-size sweep: frame time and candidate pairs per
object against the cell edge, one line per workload, the automatic choice
marked with a star.

Usage: plot_cellsize.py SWEEP.csv OUT_PREFIX   (writes OUT_PREFIX.png and .svg)
"""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: plot_cellsize.py SWEEP.csv OUT_PREFIX")
    rows = list(csv.DictReader(open(sys.argv[1], newline="")))
    workloads = sorted({r["workload"] for r in rows})
    fig, (ax_time, ax_work) = plt.subplots(1, 2, figsize=(11, 4.2))
    for w in workloads:
        sweep = sorted((float(r["cell"]), r) for r in rows if r["workload"] == w and r["automatic"] == "0")
        auto = [r for r in rows if r["workload"] == w and r["automatic"] == "1"]
        cells = [c for c, _ in sweep]
        line, = ax_time.plot(cells, [float(r["frame_ms"]) for _, r in sweep], "o-", label=w)
        ax_work.plot(cells, [float(r["candidates_per_object"]) for _, r in sweep], "o-",
                     color=line.get_color(), label=w + " candidates")
        ax_work.plot(cells, [float(r["tests_per_object"]) for _, r in sweep], "x--",
                     color=line.get_color(), alpha=0.6, label=w + " exact tests")
        for r in auto:
            ax_time.plot([float(r["cell"])], [float(r["frame_ms"])], "*", ms=16,
                         color=line.get_color(), markeredgecolor="black", label=w + " automatic")
            ax_work.plot([float(r["cell"])], [float(r["candidates_per_object"])], "*", ms=16,
                         color=line.get_color(), markeredgecolor="black")
    for ax in (ax_time, ax_work):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("cell edge (world units; radii 0.5 to 50)")
        ax.grid(True, which="both", alpha=0.3)
    ax_time.set_ylabel("median frame time (ms)")
    ax_work.set_ylabel("per object per frame")
    ax_time.set_title("Frame time against cell size")
    ax_work.set_title("Grid candidates and exact tests")
    lo, hi = ax_time.get_xlim()
    ax_time.text(lo * 1.1, ax_time.get_ylim()[1] / 1.6, "too fine:\nmany cells,\noverflow", fontsize=8)
    ax_time.text(hi / 4.5, ax_time.get_ylim()[1] / 1.6, "too coarse:\ncrowded cells", fontsize=8)
    ax_time.legend(fontsize=8)
    ax_work.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(sys.argv[2] + ".png", dpi=120)
    fig.savefig(sys.argv[2] + ".svg")


if __name__ == "__main__":
    main()
