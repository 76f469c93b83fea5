#!/usr/bin/env python3
"""The figure of the engines' lab section (bench/engines/engines_lab.cpp).

Usage: plot_engines.py [--bullet bullet.csv] [--fcl fcl.csv] --out DIR
Writes engines.png and engines.svg into DIR: Bullet's step time per world
and broad phase relative to btDbvtBroadphase's step, the broad phase's part
shaded; Bullet's broad-phase time alone (ms, log); FCL's update + collide
per frame against the object count, one line per manager. Each value is the
median over the runs of the CSV.
"""
import argparse
import csv
import os
import statistics
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

DBVT = "btDbvtBroadphase"


def read(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def in_order(values):
    seen = []
    for v in values:
        if v not in seen:
            seen.append(v)
    return seen


def bullet_medians(rows):
    """{(world, broad phase): (step ms, broad ms)}, medians over the runs."""
    out = {}
    for world in in_order(r["world"] for r in rows):
        for name in in_order(r["broadphase"] for r in rows if r["world"] == world):
            mine = [r for r in rows if r["world"] == world and r["broadphase"] == name]
            out[(world, name)] = (statistics.median(float(r["step_ms"]) for r in mine),
                                  statistics.median(float(r["broad_ms"]) for r in mine))
    return out


def bullet_panels(rows, ax_step, ax_broad):
    worlds = in_order(r["world"] for r in rows)
    names = in_order(r["broadphase"] for r in rows)
    med = bullet_medians(rows)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    width = 0.8 / len(names)
    for k, name in enumerate(names):
        xs, rel, rel_broad, broad = [], [], [], []
        for i, world in enumerate(worlds):
            if (world, name) not in med or (world, DBVT) not in med:
                continue
            step, bp = med[(world, name)]
            ref = med[(world, DBVT)][0]
            xs.append(i - 0.4 + width * (k + 0.5))
            rel.append(step / ref)
            rel_broad.append(bp / ref)
            broad.append(bp)
        colour = colours[k % len(colours)]
        ax_step.bar(xs, rel, width, color=colour, alpha=0.35, edgecolor=colour, label=name)
        ax_step.bar(xs, rel_broad, width, color=colour, edgecolor=colour)
        ax_broad.bar(xs, broad, width, color=colour, label=name)
    labels = ["%s\n(dbvt step %.3g ms)" % (w, med[(w, DBVT)][0]) if (w, DBVT) in med else w
              for w in worlds]
    for ax in (ax_step, ax_broad):
        ax.set_xticks(range(len(worlds)))
        ax.set_xticklabels(labels, fontsize=7)
        ax.grid(True, axis="y", alpha=0.3)
    ax_step.axhline(1, color="grey", linewidth=0.8)
    ax_step.set_ylabel("step time / btDbvtBroadphase's step")
    ax_step.set_title("Bullet: step time (light) and its broad-phase part (dark), "
                      "relative to the dbvt's step", fontsize=9)
    # Room above the bars at 1 for the legend, which hid the tallest ones.
    ax_step.set_ylim(0, 1.3)
    ax_step.legend(fontsize=7, ncol=len(names), loc="upper center")
    ax_broad.set_yscale("log")
    ax_broad.set_ylabel("broad phase ms per step (CPU)")
    ax_broad.set_title("Bullet: broad-phase time per step (updateAabbs + "
                       "computeOverlappingPairs)", fontsize=9)


def fcl_panel(rows, ax):
    names = in_order(r["manager"] for r in rows)
    for name in names:
        sizes = sorted({int(r["n"]) for r in rows if r["manager"] == name})
        pts = []
        for n in sizes:
            mine = [r for r in rows if r["manager"] == name and int(r["n"]) == n]
            pts.append((n, statistics.median(float(r["total_ms"]) for r in mine)))
        ours = name.startswith("broadphase")
        ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", markersize=4,
                linewidth=2.5 if ours else 1.2, label=name)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.grid(True, which="major", alpha=0.3)
    ax.set_xlabel("objects (scaled-even, a fifth moving)")
    ax.set_ylabel("update + collide ms per frame (CPU)")
    ax.set_title("FCL: update + collide per frame, by manager", fontsize=9)
    ax.legend(fontsize=7)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bullet", help="bullet.csv of engines_lab")
    ap.add_argument("--fcl", help="fcl.csv of engines_lab")
    ap.add_argument("--out", required=True, help="directory for engines.png and engines.svg")
    a = ap.parse_args()
    if not a.bullet and not a.fcl:
        ap.error("give --bullet, --fcl or both")
    bullet = read(a.bullet) if a.bullet else []
    fcl = read(a.fcl) if a.fcl else []
    if not bullet and not fcl:
        print("plot_engines: no rows to draw", file=sys.stderr)
        return 1
    panels = (2 if bullet else 0) + (1 if fcl else 0)
    fig, axes = plt.subplots(panels, 1, figsize=(11, 3.6 * panels), squeeze=False)
    axes = [row[0] for row in axes]
    if bullet:
        bullet_panels(bullet, axes[0], axes[1])
    if fcl:
        fcl_panel(fcl, axes[-1])
    fig.suptitle("Engines: Bullet and FCL with their own broad phases and ours "
                 "(thread CPU time, medians over runs)", fontsize=10)
    fig.tight_layout()
    os.makedirs(a.out, exist_ok=True)
    for ext in ("png", "svg"):
        fig.savefig(os.path.join(a.out, "engines." + ext), dpi=110)
    plt.close(fig)
    return 0


if __name__ == "__main__":
    sys.exit(main())
