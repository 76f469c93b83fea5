#!/usr/bin/env python3
"""Writes the nasty scenes of the MPI tests (tests/data/mpi/*.scene).

Deterministic (fixed seeds); the files are committed, this script is how
they were made. Each targets one way a decomposition can go wrong; the
test replays it on one process and over the ranks and compares frames.
"""
import math
import os
import random
import sys

L = 1000.0


def g(x):
    return repr(float(x))


def write(path, objects, world=L):
    """objects: (kind, cx, cy, cz, hx|r, hy, hz, vx, vy, vz)."""
    boxes = any(o[0] == "box" for o in objects)
    with open(path, "w") as f:
        f.write("broadphase-scene %d\nworld %s\nobjects %d\n" % (2 if boxes else 1, g(world), len(objects)))
        for o in objects:
            kind = o[0]
            if kind == "sphere":
                nums = [o[1], o[2], o[3], o[4], o[7], o[8], o[9]]
            else:
                nums = [o[1], o[2], o[3], o[4], o[5], o[6], o[7], o[8], o[9]]
            line = " ".join(g(v) for v in nums)
            f.write((kind + " " + line if boxes else line) + "\n")


def sphere(c, r, v=(0, 0, 0)):
    return ("sphere", c[0], c[1], c[2], r, r, r, v[0], v[1], v[2])


def box(c, h, v=(0, 0, 0)):
    return ("box", c[0], c[1], c[2], h[0], h[1], h[2], v[0], v[1], v[2])


def direction(rng):
    while True:
        v = [rng.uniform(-1, 1) for _ in range(3)]
        n = math.sqrt(sum(x * x for x in v))
        if 0.1 < n <= 1:
            return [x / n for x in v]


def main(out):
    os.makedirs(out, exist_ok=True)
    rng = random.Random(19)

    # Outside the world and larger than it; two spheres so large that their
    # bounds are infinite (radius >= 2^511) and they overlap everything.
    objs = []
    for i in range(60):
        c = [rng.uniform(-L, 2 * L) for _ in range(3)]
        r = rng.choice([0.0, rng.uniform(0, 20), rng.uniform(L, 3 * L)])
        v = [x * rng.uniform(0, 30) for x in direction(rng)] if i % 3 == 0 else [0, 0, 0]
        objs.append(sphere(c, r, v))
    objs.append(sphere((-5e3, 500, 500), 1e200))
    objs.append(sphere((500, 7e3, -2e3), 2.0 ** 600, (1, 0, 0)))
    objs.append(box((500, 500, 500), (1e308, 1, 1)))
    write(os.path.join(out, "outside-huge.scene"), objs)

    # Centres and faces exactly on the cut planes of the grids the tests use
    # (2, 3 and 4 ranks on an axis: the cut expression of partition.cpp), and
    # touching pairs across them.
    cuts = sorted({0.0 + (L - 0.0) * m / d for d in (2, 3, 4) for m in range(1, d)} | {0.0, L})
    objs = []
    for i, x in enumerate(cuts):
        y = cuts[(i * 3) % len(cuts)]
        z = cuts[(i * 5) % len(cuts)]
        objs.append(sphere((x, y, z), 0.0))
        objs.append(sphere((x - 2.5, y, z), 2.5))
        objs.append(sphere((x + 2.5, y, z), 2.5))
        objs.append(box((x - 1.5, y + 0.5, z), (1.5, 0.5, 0.5)))
        objs.append(box((x + 1.5, y, z - 0.5), (1.5, 0.5, 0.5)))
        objs.append(sphere((x, y, z), 7.0, (0.25, -0.25, 0.5)))
    write(os.path.join(out, "cut-planes.scene"), objs)

    # Identical centres: two points with many objects each, some moving.
    objs = []
    for i in range(80):
        c = (500.0, 500.0, 500.0) if i % 2 else (250.0, 250.0, 250.0)
        v = (1.0, 0.0, 0.0) if i % 5 == 0 else (0, 0, 0)
        objs.append(sphere(c, rng.uniform(0, 30)) if i % 4 else box(c, (3, 0, 9), v))
    write(os.path.join(out, "same-centres.scene"), objs)

    # Everything in one corner: most ranks own nothing.
    objs = [sphere([rng.uniform(0, 100) for _ in range(3)], rng.uniform(0.5, 15),
                   [x * 0.5 for x in direction(rng)] if i % 4 == 0 else (0, 0, 0)) for i in range(120)]
    write(os.path.join(out, "corner.scene"), objs)

    # One object per rank of a 2x2x2 grid, overlapping across the cuts.
    objs = [sphere((250.0 + 500 * (i >> 2), 250.0 + 500 * ((i >> 1) & 1), 250.0 + 500 * (i & 1)), 260.0,
                   (3.0, -2.0, 1.0) if i % 2 else (0, 0, 0)) for i in range(8)]
    write(os.path.join(out, "one-per-rank.scene"), objs)

    # Radii over five decades, 0.001 to 100.
    objs = [sphere([rng.uniform(0, L) for _ in range(3)], 10 ** rng.uniform(-3, 2),
                   [x * rng.uniform(0.1, 2) for x in direction(rng)] if i % 5 == 0 else (0, 0, 0))
            for i in range(400)]
    write(os.path.join(out, "decades.scene"), objs)

    # Objects that cross several subdomains in one frame (300 to 700 units).
    objs = [sphere([rng.uniform(0, L) for _ in range(3)], rng.uniform(5, 60),
                   [x * rng.uniform(300, 700) for x in direction(rng)] if i % 2 == 0 else (0, 0, 0))
            for i in range(80)]
    write(os.path.join(out, "jumpers.scene"), objs)

    # Random motion with migration: every object moves, some fast.
    objs = [sphere([rng.uniform(0, L) for _ in range(3)], rng.uniform(2, 25),
                   [x * rng.uniform(1, 40) for x in direction(rng)]) for i in range(300)]
    write(os.path.join(out, "random-motion.scene"), objs)

    # Touching pairs across every cut plane, away from the cuts of the other
    # axes: an object whose face lies exactly on a cut must still reach the
    # rank beyond it (whose subdomain holds the pair's point on the cut),
    # although nothing else takes it there.
    inner = [137.25, 611.5, 893.0]
    objs = []
    for a in range(3):
        for c in cuts[1:-1]:
            for k, o in enumerate(inner):
                p = [inner[(k + 1) % 3], inner[(k + 2) % 3], o]
                p.insert(a, c)
                p = p[:3]
                lo, hi = list(p), list(p)
                lo[a], hi[a] = c - 2.0, c + 2.0
                objs.append(sphere(lo, 2.0))
                objs.append(sphere(hi, 2.0))
                bl, bh = list(p), list(p)
                bl[a], bh[a] = c - 0.75, c + 0.5
                for b in (2, 1, 0):
                    if b != a:
                        bl[b] += 10.0
                        bh[b] += 10.0
                        break
                objs.append(box(bl, (0.75, 0.75, 0.75)))
                objs.append(box(bh, (0.5, 0.5, 0.5)))
                # One object across the cut, its partner wholly beyond it:
                # the pair's point lies beyond the cut, so the rank there
                # must receive the straddling object (and the same mirrored).
                for side in (1.0, -1.0):
                    q = list(p)
                    q[(a + 1) % 3] += 20.0 * side
                    s1, s2 = list(q), list(q)
                    s1[a], s2[a] = c - side, c + 2.0 * side
                    objs.append(sphere(s1, 2.0))
                    objs.append(sphere(s2, 1.0))
                    q[(a + 2) % 3] += 20.0
                    b1, b2 = list(q), list(q)
                    b1[a], b2[a] = c - 0.5 * side, c + 1.5 * side
                    objs.append(box(b1, (1.0, 1.0, 1.0)))
                    objs.append(box(b2, (0.5, 0.25, 0.75)))
    write(os.path.join(out, "cut-faces.scene"), objs)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "data", "mpi"))
