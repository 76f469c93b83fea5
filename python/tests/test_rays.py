"""Ray casts against a numpy oracle written from the contract's ray test
(docs/scene-format.md, "Rays"), one IEEE operation per ufunc, and against
the shared reference scenes' first frames."""

import math
import os

import numpy as np
import pytest

import broadphase
from conftest import DATA, QUICK


def oracle_hits(c, r, h, kinds, groups, o, d, tmax, mask):
    """(ids, t) of every object the ray (o, d, tmax, mask) hits."""
    n = len(c)
    t = np.full(n, np.inf)
    hit = np.zeros(n, bool)
    with np.errstate(all="ignore"):
        # Spheres.
        mx, my, mz = o[0] - c[:, 0], o[1] - c[:, 1], o[2] - c[:, 2]
        c2 = (mx * mx + my * my + mz * mz) - r * r
        inside = c2 <= 0
        b = mx * d[0] + my * d[1] + mz * d[2]
        a = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
        f = b / a
        qx, qy, qz = mx - f * d[0], my - f * d[1], mz - f * d[2]
        h2 = r * r - (qx * qx + qy * qy + qz * qz)
        ts = -f - np.sqrt(h2 / a)
        ts = np.where(ts < 0, 0.0, ts)
        sph = inside | ((b < 0) & (h2 >= 0) & (ts <= tmax))
        ts = np.where(inside, 0.0, ts)
        # Boxes.
        tn = np.zeros(n)
        tf = np.full(n, float(tmax))
        ok = np.ones(n, bool)
        for ax in range(3):
            lo = (c[:, ax] - h[:, ax]) - o[ax]
            hi = (c[:, ax] + h[:, ax]) - o[ax]
            if d[ax] == 0:
                ok &= ~((lo > 0) | (hi < 0))
                continue
            t1, t2 = lo / d[ax], hi / d[ax]
            t1, t2 = np.minimum(t1, t2), np.maximum(t1, t2)
            tn = np.where(t1 > tn, t1, tn)
            tf = np.where(t2 < tf, t2, tf)
        box = ok & (tn <= tf)
    is_box = kinds == 1
    hit = np.where(is_box, box, sph) & ((groups & mask) != 0)
    t = np.where(is_box, tn, ts)
    ids = np.flatnonzero(hit)
    return ids, t[ids]


def oracle_closest(hits):
    ids, t = hits
    if len(ids) == 0:
        return -1, math.inf
    k = np.lexsort((ids, t))[0]
    return ids[k], t[k]


def random_world(rng, n, kind):
    c = rng.uniform(0, 100, (n, 3))
    r = rng.uniform(0, 4, n)
    h = rng.uniform(0, 4, (n, 3))
    if kind == "spheres":
        kinds = np.zeros(n, np.uint8)
    elif kind == "boxes":
        kinds = np.ones(n, np.uint8)
    else:
        kinds = rng.integers(0, 2, n).astype(np.uint8)
    return c, r, h, kinds


def random_rays(rng, k):
    o = rng.uniform(-20, 120, (k, 3))
    d = rng.normal(size=(k, 3))
    # Some along the axes, some of zero direction, some starting at a centre.
    d[: k // 8] = np.eye(3)[rng.integers(0, 3, k // 8)] * rng.choice([-1, 1], (k // 8, 1))
    d[k // 8: k // 6] = 0
    tmax = rng.choice([np.inf, 0.0, 10.0, 75.5], k)
    return o, d, tmax


def as_args(c, r, h, kinds):
    return dict(centers=c, radii=r, half_extents=h, kinds=kinds)


@pytest.mark.parametrize("kind", ["spheres", "boxes", "mixed"])
@pytest.mark.parametrize("structure", ["", "lean", "kdtree", "grid-verlet", "aabb-tree", "naive"])
def test_ray_cast_matches_the_oracle(kind, structure):
    seed = int(os.environ.get("BROADPHASE_SEED", "11"))
    print(f"seed {seed}")
    rng = np.random.default_rng(seed)
    n, k = (60, 40) if QUICK else (300, 120)
    c, r, h, kinds = random_world(rng, n, kind)
    groups = rng.integers(1, 16, n).astype(np.uint32)
    o, d, tmax = random_rays(rng, k)
    # Some rays start inside objects.
    o[-4:] = c[:4]
    ray_masks = rng.integers(0, 16, k).astype(np.uint32)
    ray_masks[: k // 2] = 0xFFFFFFFF
    args = as_args(c, r, h, kinds)
    ids, t = broadphase.ray_cast(**args, origins=o, directions=d, tmax=tmax, groups=groups,
                                 ray_masks=ray_masks, structure=structure, threads=2)
    offsets, all_ids, all_t = broadphase.ray_cast(
        **args, origins=o, directions=d, tmax=tmax, groups=groups, ray_masks=ray_masks,
        structure=structure, all_hits=True)
    assert ids.dtype == np.int64 and t.dtype == np.float64 and offsets.shape == (k + 1,)
    for q in range(k):
        want = oracle_hits(c, r, h, kinds, groups, o[q], d[q], tmax[q], ray_masks[q])
        cid, ct = oracle_closest(want)
        assert ids[q] == cid, f"ray {q}"
        assert t[q] == ct or (math.isinf(ct) and math.isinf(t[q])), f"ray {q}"
        got = sorted(zip(all_ids[offsets[q]:offsets[q + 1]].tolist(),
                         all_t[offsets[q]:offsets[q + 1]].tolist()))
        assert got == sorted(zip(want[0].tolist(), want[1].tolist())), f"ray {q}"
        row_t = all_t[offsets[q]:offsets[q + 1]]
        assert np.all(row_t[:-1] <= row_t[1:])


def test_index_ray_cast_lean_and_structure():
    rng = np.random.default_rng(5)
    c, r, _, _ = random_world(rng, 200, "spheres")
    o, d, tmax = random_rays(rng, 50)
    one = broadphase.ray_cast(c, r, origins=o, directions=d, tmax=tmax)
    for structure in (None, "octree"):
        idx = broadphase.Index(c, r) if structure is None else broadphase.Index(
            c, r, structure=structure)
        ids, t = idx.ray_cast(o, d, tmax)
        np.testing.assert_array_equal(ids, one[0])
        np.testing.assert_array_equal(t, one[1])
        # Ids stay the index's after a removal.
        idx.remove([0, 1])
        ids2, _ = idx.ray_cast(o, d, tmax)
        assert not np.isin(ids2, [0, 1]).any()


def test_lean_index_ray_cast_follows_moves_filters_and_removals():
    # A borrowing lean index casts through its tracker's grid: after each
    # change (moves in place, filters, removals and insertions), with new
    # rays and ray masks every time, against the oracle.
    seed = int(os.environ.get("BROADPHASE_SEED", "23"))
    print(f"seed {seed}")
    rng = np.random.default_rng(seed)
    n, k = (80, 30) if QUICK else (300, 80)
    c, r, h, kinds = random_world(rng, n, "mixed")
    groups = rng.integers(1, 16, n).astype(np.uint32)
    masks = np.full(n, 0xFFFFFFFF, np.uint32)
    idx = broadphase.Index(c, r, h, kinds, groups=groups, masks=masks)
    live = np.arange(n)
    for step in range(6):
        o, d, tmax = random_rays(rng, k)
        ray_masks = rng.integers(0, 16, k).astype(np.uint32)
        ids, t = idx.ray_cast(o, d, tmax, ray_masks=ray_masks, threads=2)
        offsets, all_ids, all_t = idx.ray_cast(o, d, tmax, ray_masks=ray_masks, all_hits=True)
        for q in range(k):
            want_ids, want_t = oracle_hits(c[live], r[live], h[live], kinds[live], groups[live],
                                           o[q], d[q], tmax[q], ray_masks[q])
            want_ids = live[want_ids]  # the index's ids
            cid, ct = oracle_closest((want_ids, want_t))
            assert ids[q] == cid and (t[q] == ct or math.isinf(ct)), f"step {step} ray {q}"
            row = list(zip(all_t[offsets[q]:offsets[q + 1]].tolist(),
                           all_ids[offsets[q]:offsets[q + 1]].tolist()))
            assert row == sorted(zip(want_t.tolist(), want_ids.tolist())), f"step {step} ray {q}"
        if step == 1:
            c[:20] += rng.uniform(-5, 5, (20, 3))  # moved in place
            idx.update(np.arange(20))
        elif step == 2:
            groups[live[:30]] = rng.integers(1, 16, 30).astype(np.uint32)
            idx.set_filters(live[:30], groups=groups[live[:30]], masks=masks[live[:30]])
        elif step == 3:
            idx.remove(live[5:9])
            live = np.delete(live, range(5, 9))
        elif step == 4:
            c[live[-10:]] = rng.uniform(0, 100, (10, 3))
            idx.update(live[-10:], c[live[-10:]])


def test_lean_index_closest_ties_go_to_the_smallest_id():
    # Spheres about one point: a ray from it hits all at t = 0. After id 0
    # is removed and id 3 inserted, the index's slots need not follow the
    # ids; the closest hit is still the smallest id.
    # A structure reuses id 0's slot for id 3: the same.
    c = np.zeros((3, 3))
    for structure in (None, "octree"):
        idx = broadphase.Index(c, np.array([1.0, 2.0, 3.0]), structure=structure)
        idx.remove([0])
        idx.insert(np.zeros((1, 3)), np.array([4.0]))
        ids, t = idx.ray_cast([[0, 0, 0]], [[1, 0, 0]])
        assert ids.tolist() == [1] and t.tolist() == [0.0], structure
        offsets, all_ids, all_t = idx.ray_cast([[0, 0, 0]], [[1, 0, 0]], all_hits=True)
        assert all_ids.tolist() == [1, 2, 3] and all_t.tolist() == [0.0] * 3, structure


def test_ray_cast_refuses_bad_rays():
    c = np.zeros((1, 3))
    good = dict(centers=c, radii=1.0, origins=[[0, 0, -5]], directions=[[0, 0, 1]])
    assert broadphase.ray_cast(**good)[0].tolist() == [0]
    for bad, word in (
        (dict(origins=[[np.nan, 0, 0]]), "origin"),
        (dict(directions=[[np.inf, 0, 0]]), "direction"),
        (dict(directions=[[1e-200, 0, 0]]), "smallest normal"),
        (dict(tmax=-1.0), "negative"),
        (dict(tmax=np.nan), "NaN"),
        (dict(directions=[[0, 0, 1], [0, 0, 1]]), "directions"),
        (dict(ray_masks=[-1]), "ray_masks"),
    ):
        with pytest.raises(ValueError, match=word):
            broadphase.ray_cast(**{**good, **bad})


def bits(text):
    """A filter value of a scene file: decimal (a leading 0 is not octal) or 0x hex."""
    return int(text, 16) if text.lower().startswith("0x") else int(text, 10)


def read_v3(path):
    """Objects (centres, radii, half-extents, kinds, groups) and rays of a
    version 3 scene file, for its first frame."""
    c, r, h, kinds, groups, rays = [], [], [], [], [], []
    for line in open(path):
        f = line.split()
        if not f or f[0].startswith("#"):
            continue
        g = 1
        if "filter" in f:
            at = f.index("filter")
            if f[0] != "ray":
                g = bits(f[at + 1])
            mask = bits(f[at + 1])
            f = f[:at]
        else:
            mask = 0xFFFFFFFF
        if f[0] == "sphere":
            c.append([float(v) for v in f[1:4]]); r.append(float(f[4])); h.append([0, 0, 0])
            kinds.append(0); groups.append(g)
        elif f[0] == "box":
            c.append([float(v) for v in f[1:4]]); r.append(0.0)
            h.append([float(v) for v in f[4:7]]); kinds.append(1); groups.append(g)
        elif f[0] == "ray":
            rays.append(([float(v) for v in f[1:4]], [float(v) for v in f[4:7]],
                         float(f[7]), mask))
    return (np.array(c), np.array(r), np.array(h, float), np.array(kinds, np.uint8),
            np.array(groups, np.uint32), rays)


def splitmix64(x):
    m = (1 << 64) - 1
    z = (x + 0x9E3779B97F4A7C15) & m
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & m
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & m
    return z ^ (z >> 31)


@pytest.mark.parametrize("name", ["rays-boxes-300", "rays-mixed-300", "gen-lidar-300",
                                  "gen-layers-rays-400", "gen-city-axis-300", "gen-zero-300",
                                  "gen-coincident-inside-300"])
def test_reference_scenes_first_frame(name):
    path = DATA / "scenes" / "v3" / f"{name}.scene"
    if not path.exists():
        pytest.skip(f"{path} not present")
    c, r, h, kinds, groups, rays = read_v3(path)
    o = np.array([x[0] for x in rays])
    d = np.array([x[1] for x in rays])
    tmax = np.array([x[2] for x in rays])
    masks = np.array([x[3] for x in rays], np.uint32)
    offsets, ids, t = broadphase.ray_cast(c, r, h, kinds, origins=o, directions=d, tmax=tmax,
                                          groups=groups, ray_masks=masks, all_hits=True)
    hits_hash = closest_hash = 0
    for q in range(len(rays)):
        for k in range(offsets[q], offsets[q + 1]):
            bits = int(np.float64(t[k]).view(np.uint64))
            v = splitmix64((splitmix64((q << 32) | int(ids[k])) + bits) & ((1 << 64) - 1))
            hits_hash = (hits_hash + v) % (1 << 64)
            if k == offsets[q]:
                closest_hash = (closest_hash + v) % (1 << 64)
    first = open(DATA / "scenes" / "v3" / f"{name}.expected").readline().split()
    assert int(first[3]) == int(offsets[-1])
    assert f"{hits_hash:016x}" == first[4]
    assert f"{closest_hash:016x}" == first[5]
