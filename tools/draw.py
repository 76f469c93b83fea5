#!/usr/bin/env python3
"""Renders what `broadphase draw` decided to draw.

Usage: draw.py DATA.json

The JSON (written by lab/draw.cpp) holds the scene's
objects, optionally the cells of a structure, optionally recorded
simulation runs, and where to write the picture (.png, .svg or .gif).
"""
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.collections import LineCollection, PatchCollection  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Circle, Rectangle  # noqa: E402

STATIC = "#a7adb4"
STATIC_EDGE = "#5f6368"
MOVING = "#1a73e8"
MOVING_EDGE = "#0b3d91"
WORLD = "#202124"
# Screen axes of each 2D view: (horizontal, vertical) scene axes and labels.
VIEWS = {"side": (0, 1, "x", "y (up)"), "top": (0, 2, "x", "z")}
VIEW_NAMES = {"side": "side view", "top": "top view", "3d": "3D view"}


def objects_of(d):
    o = d["objects"]
    n = len(o["x"])
    centre = [(o["x"][i], o["y"][i], o["z"][i]) for i in range(n)]
    half = [(o["hx"][i], o["hy"][i], o["hz"][i]) for i in range(n)]
    return centre, half, o["box"], o["moving"]


def shape_patch(c, h, box, ai, bi):
    if box:
        return Rectangle((c[ai] - h[ai], c[bi] - h[bi]), 2 * h[ai], 2 * h[bi])
    return Circle((c[ai], c[bi]), h[0])


def draw_objects(ax, d, view, centres=None, only=None, alpha=0.85, zorder=2):
    """Objects as true-size circles and rectangles; movers blue, static grey."""
    centre, half, box, moving = objects_of(d)
    if centres is not None:
        centre = centres
    ai, bi = VIEWS[view][:2]
    groups = {True: [], False: []}
    # Larger objects first, so small ones stay visible on top.
    order = sorted(range(len(centre)), key=lambda i: -max(half[i]))
    for i in order:
        if only is not None and moving[i] != only:
            continue
        groups[bool(moving[i])].append(shape_patch(centre[i], half[i], box[i], ai, bi))
    for mv, patches in groups.items():
        if not patches:
            continue
        ax.add_collection(
            PatchCollection(
                patches,
                facecolor=MOVING if mv else STATIC,
                edgecolor=MOVING_EDGE if mv else STATIC_EDGE,
                linewidth=0.4,
                alpha=alpha,
                zorder=zorder + (1 if mv else 0),
            )
        )


def frame_world(ax, d, view):
    L = d["world"]
    ai, bi, xl, yl = VIEWS[view]
    ax.add_patch(Rectangle((0, 0), L, L, fill=False, edgecolor=WORLD, linewidth=1.2, zorder=5))
    m = 0.03 * L
    ax.set_xlim(-m, L + m)
    ax.set_ylim(-m, L + m)
    ax.set_aspect("equal")
    ax.set_xlabel(xl)
    ax.set_ylabel(yl)
    if view == "side":
        ax.axhline(0, color="#7c4a03", linewidth=2.5, zorder=6)


def legend_objects(ax, extra=()):
    handles = [
        Line2D([], [], marker="o", linestyle="", markerfacecolor=STATIC,
               markeredgecolor=STATIC_EDGE, markersize=8, label="static"),
        Line2D([], [], marker="o", linestyle="", markerfacecolor=MOVING,
               markeredgecolor=MOVING_EDGE, markersize=8, label="moving"),
    ]
    ax.legend(handles=handles + list(extra), loc="upper right", fontsize=8, framealpha=0.9)


def velocity_arrows(ax, d, view):
    """Red arrows: how far each mover goes in a number of frames chosen so
    that the median arrow is 4% of the world."""
    centre, _, _, moving = objects_of(d)
    vel = d["objects"]["velocity"]
    ai, bi = VIEWS[view][:2]
    pts = [(centre[i][ai], centre[i][bi], vel[i][ai], vel[i][bi])
           for i in range(len(centre)) if moving[i]]
    if not pts:
        return []
    speeds = sorted((p[2] ** 2 + p[3] ** 2) ** 0.5 for p in pts)
    med = speeds[len(speeds) // 2] or 1.0
    frames = 0.04 * d["world"] / med
    ax.quiver([p[0] for p in pts], [p[1] for p in pts], [p[2] * frames for p in pts],
              [p[3] * frames for p in pts], angles="xy", scale_units="xy", scale=1,
              color="#d93025", width=0.0025, zorder=7)
    return [Line2D([], [], color="#d93025", label="motion in %.0f frames" % frames)]


# ---------------------------------------------------------------- cells


def value_of(cells, b):
    """A cell's colour value: objects per cell for a grid, else its level."""
    return b[6] if cells["kind"] == "grid" else b[7]


def project_boxes(cells, view):
    ai, bi = VIEWS[view][:2]
    return [(b[ai], b[bi], b[3 + ai], b[3 + bi], value_of(cells, b)) for b in cells["boxes"]]


def draw_cells_2d(ax, fig, cells, view):
    kind = cells["kind"]
    rects = project_boxes(cells, view)
    if kind == "grid":
        # Colour = the most objects in one cell along the line of sight.
        col = {}
        for x0, y0, x1, y1, v in rects:
            key = (x0, y0, x1, y1)
            col[key] = max(col.get(key, 0), v)
        patches = [Rectangle((k[0], k[1]), k[2] - k[0], k[3] - k[1]) for k in col]
        pc = PatchCollection(patches, cmap="YlOrRd", edgecolor="#80868b", linewidth=0.3,
                             alpha=0.6, zorder=4)
        pc.set_array([v for v in col.values()])
        ax.add_collection(pc)
        cb = fig.colorbar(pc, ax=ax, shrink=0.8)
        cb.set_label("most objects in one cell along the line of sight")
        return []
    cmap = plt.get_cmap("tab10" if kind == "hgrid" else "viridis")
    values = sorted({r[4] for r in rects})
    top = max(values) if values else 1
    colour = {v: cmap(int(v) % 10) if kind == "hgrid" else cmap(v / max(top, 1) * 0.9) for v in values}
    by_value = {}
    for x0, y0, x1, y1, v in rects:
        by_value.setdefault(v, []).append(Rectangle((x0, y0), x1 - x0, y1 - y0))
    for v in values:
        lw = 1.6 if kind == "hgrid" else max(0.4, 1.8 - 0.35 * v)
        ax.add_collection(PatchCollection(by_value[v], facecolor="none", edgecolor=colour[v],
                                          linewidth=lw, zorder=4 + (0.1 * v if kind != "hgrid" else 0)))
    word = "level" if kind == "hgrid" else "depth"
    edge = {b[7]: b[3] - b[0] for b in cells["boxes"]}
    handles = []
    for v in values:
        label = "%s %d" % (word, v)
        if kind == "hgrid":
            label += " (cell %.3g)" % edge[v]
        handles.append(Line2D([], [], color=colour[v], linewidth=2, label=label))
    return handles


def draw_cells_3d(ax, cells):
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    kind = cells["kind"]
    boxes = cells["boxes"]
    if kind == "grid":
        cx = [(b[0] + b[3]) / 2 for b in boxes]
        cy = [(b[1] + b[4]) / 2 for b in boxes]
        cz = [(b[2] + b[5]) / 2 for b in boxes]
        v = [value_of(cells, b) for b in boxes]
        top = max(v) if v else 1
        sc = ax.scatter(cx, cz, cy, c=v, cmap="YlOrRd", s=[8 + 60 * x / top for x in v],
                        marker="s", alpha=0.6, depthshade=False)
        return sc
    boxes = sorted(boxes, key=lambda b: value_of(cells, b))[:1500]
    cmap = plt.get_cmap("tab10" if kind == "hgrid" else "viridis")
    top = max((value_of(cells, b) for b in boxes), default=1)
    segs, cols = [], []
    for b in boxes:
        x0, y0, z0, x1, y1, z1 = b[:6]
        v = value_of(cells, b)
        # Plot axes (x, z, y) so that y is up.
        corners = [(x, z, y) for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)]
        for i in range(8):
            for j in range(i + 1, 8):
                a, c = corners[i], corners[j]
                if sum(1 for k in range(3) if a[k] != c[k]) == 1:
                    segs.append([a, c])
                    cols.append(cmap(int(v) % 10) if kind == "hgrid" else cmap(v / max(top, 1) * 0.9))
    ax.add_collection3d(Line3DCollection(segs, colors=cols, linewidths=0.6, alpha=0.7))
    return None


# ---------------------------------------------------------------- views


def title_of(d, default):
    return d["title"] or default


def scene_summary(d):
    n = len(d["objects"]["x"])
    m = sum(1 for v in d["objects"]["moving"] if v)
    return "%s: %d objects (%d moving), world %g" % (d["scene"], n, m, d["world"])


def draw_3d(d):
    fig = plt.figure(figsize=(7.5, 7))
    ax = fig.add_subplot(projection="3d")
    centre, half, _, moving = objects_of(d)
    L = d["world"]
    ppu = 0.42 * 7.5 * 72 / L  # points per world unit, roughly, at this size
    for mv in (False, True):
        idx = [i for i in range(len(centre)) if bool(moving[i]) == mv]
        if not idx:
            continue
        ax.scatter([centre[i][0] for i in idx], [centre[i][2] for i in idx],
                   [centre[i][1] for i in idx],
                   s=[max(1.0, (2 * max(half[i]) * ppu) ** 2) for i in idx],
                   c=MOVING if mv else STATIC, edgecolors=MOVING_EDGE if mv else STATIC_EDGE,
                   linewidths=0.2, alpha=0.8 if mv else 0.45, depthshade=True,
                   label="moving" if mv else "static")
    handles = []
    if "cells" in d:
        draw_cells_3d(ax, d["cells"])
        handles.append(Line2D([], [], color="#5f6368", label=d["cells"]["label"]))
    ax.set_xlim(0, L)
    ax.set_ylim(0, L)
    ax.set_zlim(0, L)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel("x")
    ax.set_ylabel("z")
    ax.set_zlabel("y (up)")
    ax.view_init(elev=22, azim=-58)
    leg = ax.legend(loc="upper left", fontsize=8)
    for h in leg.legend_handles if hasattr(leg, "legend_handles") else leg.legendHandles:
        h.set_sizes([40])
    sub = "3D view" + ("\n" + d["cells"]["label"] if handles else "")
    ax.set_title(title_of(d, scene_summary(d) + " — " + sub), fontsize=10)
    return fig


def draw_2d(d):
    view = d["view"]
    fig, ax = plt.subplots(figsize=(7.5, 7))
    extra = []
    if "cells" in d:
        extra = draw_cells_2d(ax, fig, d["cells"], view)
    draw_objects(ax, d, view, alpha=0.35 if "cells" in d else 0.85)
    if "cells" not in d:
        extra = velocity_arrows(ax, d, view)
    frame_world(ax, d, view)
    if "cells" in d and d["cells"]["boxes"]:
        # Show cells that reach past the world (an octree's cube is larger),
        # up to 30% of the world beyond each wall.
        L = d["world"]
        rects = project_boxes(d["cells"], view)
        lo = max(-0.3 * L, min(min(r[0] for r in rects), min(r[1] for r in rects)))
        hi = min(1.3 * L, max(max(r[2] for r in rects), max(r[3] for r in rects)))
        m = 0.03 * L
        ax.set_xlim(min(-m, lo - m), max(L + m, hi + m))
        ax.set_ylim(min(-m, lo - m), max(L + m, hi + m))
    legend_objects(ax, extra)
    sub = VIEW_NAMES[view]
    if "cells" in d:
        sub += "\n" + d["cells"]["label"]
    ax.set_title(title_of(d, scene_summary(d) + " — " + sub), fontsize=10)
    return fig


def trail_collection(track, upto, ai, bi, tail, colour):
    segs, alphas = [], []
    lo = max(0, upto - tail)
    for f in range(lo, upto):
        a, b = track[f], track[f + 1]
        segs.append([(a[ai], a[bi]), (b[ai], b[bi])])
        alphas.append(0.15 + 0.85 * (f - lo + 1) / max(1, upto - lo))
    lc = LineCollection(segs, colors=[(*matplotlib.colors.to_rgb(colour), al) for al in alphas],
                        linewidths=1.2, zorder=3)
    return lc


def mover_centres(d, run, f):
    centre, _, _, _ = objects_of(d)
    centre = list(centre)
    for k, i in enumerate(run["movers"]):
        centre[i] = tuple(run["positions"][f][k])
    return centre


def draw_strip(d, panels=4):
    view = d["view"] if d["view"] != "3d" else "side"
    run = d["sim"]["runs"][0]
    frames = len(run["positions"]) - 1
    picks = sorted({round(frames * k / (panels - 1)) for k in range(panels)})
    fig, axes = plt.subplots(1, len(picks), figsize=(4.2 * len(picks), 4.6))
    if len(picks) == 1:
        axes = [axes]
    ai, bi = VIEWS[view][:2]
    for ax, f in zip(axes, picks):
        draw_objects(ax, d, view, centres=mover_centres(d, run, f))
        for k in range(len(run["movers"])):
            track = [run["positions"][g][k] for g in range(len(run["positions"]))]
            if f > 0:
                ax.add_collection(trail_collection(track, f, ai, bi, 12, "#d93025"))
        frame_world(ax, d, view)
        done = sum(run["contacts"][:f])
        ax.set_title("frame %d — %d contacts so far" % (f, done), fontsize=10)
    fig.suptitle(title_of(d, "%s — %s, ccd %s, restitution %g (trails: last 12 frames)"
                          % (scene_summary(d), VIEW_NAMES[view], run["ccd"], run["restitution"])),
                 fontsize=11)
    fig.tight_layout()
    return fig


def draw_compare(d):
    view = d["view"] if d["view"] != "3d" else "side"
    runs = d["sim"]["runs"]
    fig, axes = plt.subplots(1, len(runs), figsize=(6.2 * len(runs), 6.4))
    ai, bi = VIEWS[view][:2]
    colours = plt.get_cmap("tab10")
    for ax, run in zip(axes, runs):
        draw_objects(ax, d, view, only=False)
        for k, i in enumerate(run["movers"]):
            track = [p[k] for p in run["positions"]]
            c = colours(k % 10)
            ax.plot([p[ai] for p in track], [p[bi] for p in track], "-", color=c, linewidth=1.0,
                    alpha=0.9, zorder=3)
            ax.plot([p[ai] for p in track], [p[bi] for p in track], "o", color=c, markersize=2.2,
                    zorder=4)
            ax.plot([track[0][ai]], [track[0][bi]], "o", markerfacecolor="none", markeredgecolor=c,
                    markersize=7, zorder=4)
        frame_world(ax, d, view)
        ax.set_title("ccd %s: %d of %d contacts missed" % (run["ccd"], run["missed"],
                                                          run["true_contacts"]), fontsize=11)
    handles = [
        Line2D([], [], marker="o", linestyle="", markerfacecolor=STATIC,
               markeredgecolor=STATIC_EDGE, markersize=8, label="static target"),
        Line2D([], [], color="#1f77b4", marker="o", markersize=3, label="bullet, one dot per frame"),
        Line2D([], [], marker="o", linestyle="", markerfacecolor="none",
               markeredgecolor="#1f77b4", markersize=7, label="start"),
    ]
    axes[-1].legend(handles=handles, loc="upper right", fontsize=8, framealpha=0.9)
    fig.suptitle(title_of(d, "Tunneling — %s, %d frames: each step tests only where the bullets "
                          "are, or where they pass" % (scene_summary(d), d["sim"]["frames"])),
                 fontsize=11)
    fig.tight_layout()
    return fig


def write_gif(d):
    from matplotlib.animation import FuncAnimation, PillowWriter

    view = d["view"] if d["view"] != "3d" else "side"
    run = d["sim"]["runs"][0]
    ai, bi = VIEWS[view][:2]
    frames = len(run["positions"])
    fig, ax = plt.subplots(figsize=(4.6, 4.8), dpi=72)

    def update(f):
        ax.clear()
        draw_objects(ax, d, view, centres=mover_centres(d, run, f))
        for k in range(len(run["movers"])):
            if f > 0:
                track = [run["positions"][g][k] for g in range(frames)]
                ax.add_collection(trail_collection(track, f, ai, bi, 10, "#d93025"))
        frame_world(ax, d, view)
        ax.set_title(title_of(d, "%s, ccd %s, k %g — frame %d, %d contacts"
                              % (d["scene"], run["ccd"], run["restitution"], f,
                                 sum(run["contacts"][:f]))), fontsize=9)

    anim = FuncAnimation(fig, update, frames=frames)
    anim.save(d["out"], writer=PillowWriter(fps=12))


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: draw.py DATA.json")
    with open(sys.argv[1]) as f:
        d = json.load(f)
    out = d["out"]
    if "sim" in d:
        if d["gif"]:
            try:
                import PIL  # noqa: F401
            except ImportError:
                out = out[: -len(".gif")] + ".png"
                print("draw.py: python3-pil is missing: writing a strip to %s instead" % out,
                      file=sys.stderr)
                d["gif"] = False
        if d["gif"]:
            write_gif(d)
            return
        fig = draw_compare(d) if d["sim"]["compare"] else draw_strip(d)
    elif d["view"] == "3d":
        fig = draw_3d(d)
    else:
        fig = draw_2d(d)
    fig.savefig(out, dpi=100 if out.endswith(".png") else None, bbox_inches="tight")
    if out.endswith(".png"):
        shrink_png(out)


def shrink_png(path):
    """A 256-colour palette keeps README pictures small; skipped without PIL."""
    try:
        from PIL import Image
    except ImportError:
        return
    with Image.open(path) as im:
        small = im.convert("RGB").quantize(colors=256, method=Image.Quantize.MEDIANCUT)
    small.save(path, optimize=True)


if __name__ == "__main__":
    main()
