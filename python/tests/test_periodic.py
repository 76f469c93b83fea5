"""Periodic pairs (``pairs(..., box=, periodic=)``) against the numpy
oracle of conftest with j's centre moved by S·L for every S of the
periodic axes: random bulk, slab and tube cells with a length per axis,
spheres, boxes and both, objects exactly on the faces, sizes up to just
below L/2, filters; bad cells and objects refused with ValueError."""

import itertools

import numpy as np
import pytest

import broadphase
from conftest import QUICK, oracle_pairs


def periodic_oracle(s, box, axes):
    want = set()
    ranges = [(-1, 0, 1) if a in axes else (0,) for a in "xyz"]
    for S in itertools.product(*ranges):
        shift = [S[a] * box[a] for a in range(3)]
        for i, j in oracle_pairs(s["centers"], s.get("radii"), s.get("half_extents"),
                                 s.get("kinds"), shift=shift).tolist():
            want.add((i, j) + tuple(S))
    return want


def random_world(rng, n, kind):
    axes = "".join(a for a in "xyz" if rng.random() < 0.6) or "x"
    box = (rng.uniform(5, 40, size=3)).tolist()
    c = rng.random((n, 3)) * box
    # Some centres exactly on the faces, at 0 and at L.
    on = rng.random((n, 3)) < 0.15
    c = np.where(on, np.where(rng.random((n, 3)) < 0.5, 0.0, np.array(box)), c)
    room = min(box) / 2
    r = rng.random(n) * room * rng.choice([0.05, 0.3, 1.0])
    r = np.minimum(r, np.nextafter(room, 0))
    h = rng.random((n, 3)) * np.array(box) / 2 * rng.choice([0.05, 0.3, 1.0])
    h = np.minimum(h, np.nextafter(np.array(box) / 2, 0))
    s = dict(centers=c)
    if kind in ("spheres", "mixed"):
        s["radii"] = r
    if kind in ("boxes", "mixed"):
        s["half_extents"] = h
    if kind == "mixed":
        s["kinds"] = rng.integers(0, 2, size=n).astype(np.uint8)
    return s, box, axes


@pytest.mark.parametrize("kind", ["spheres", "boxes", "mixed"])
def test_periodic_pairs_match_the_oracle(kind):
    for seed in range(6 if QUICK else 20):
        rng = np.random.default_rng(1000 + seed)
        n = int(rng.integers(1, 150))
        s, box, axes = random_world(rng, n, kind)
        p, shifts = broadphase.pairs(**s, box=box, periodic=axes, sorted=True)
        assert p.dtype == np.int64 and p.shape == (len(p), 2)
        assert shifts.dtype == np.int8 and shifts.shape == (len(p), 3)
        got = [tuple(a) + tuple(b) for a, b in zip(p.tolist(), shifts.tolist())]
        assert len(set(got)) == len(got), f"seed {seed}: a triple twice"
        assert set(got) == periodic_oracle(s, box, axes), f"seed {seed}, {axes}, {box}"
        assert got == sorted(got, key=lambda t: (t[0], t[1], (t[2] + 1) + 3 * (t[3] + 1) + 9 * (t[4] + 1)))


def test_periodic_pairs_with_filters_and_a_cube():
    rng = np.random.default_rng(7)
    c = rng.random((200, 3)) * 10
    r = rng.random(200) * 2
    g = rng.integers(1, 4, size=200)
    m = rng.integers(0, 4, size=200)
    p, s = broadphase.pairs(c, r, box=10, groups=g, masks=m)
    want = {t for t in periodic_oracle(dict(centers=c, radii=r), [10, 10, 10], "xyz")
            if (g[t[0]] & m[t[1]]) and (g[t[1]] & m[t[0]])}
    assert {tuple(a) + tuple(b) for a, b in zip(p.tolist(), s.tolist())} == want


def test_across_the_face():
    c = np.array([[0.5, 5, 5], [9.5, 5, 5]])
    p, s = broadphase.pairs(c, 1.0, box=(10, 20, 20), periodic="x")
    assert p.tolist() == [[0, 1]] and s.tolist() == [[-1, 0, 0]]
    p, s = broadphase.pairs(c, 1.0, box=(10, 20, 20), periodic="y")
    assert p.shape == (0, 2) and s.shape == (0, 3)


def test_bad_cells_and_objects():
    c = np.array([[1.0, 1, 1], [2, 2, 2]])
    with pytest.raises(ValueError, match=r"centers|objects\[1\]: x \(11\) is outside"):
        broadphase.pairs(np.array([[1.0, 1, 1], [11, 2, 2]]), 1.0, box=10)
    with pytest.raises(ValueError, match=r"radius \(5\) is not below L/2"):
        broadphase.pairs(c, 5.0, box=10)
    with pytest.raises(ValueError, match="box"):
        broadphase.pairs(c, 1.0, box=(10, 10))
    with pytest.raises(ValueError, match="box"):
        broadphase.pairs(c, 1.0, periodic="x")
    with pytest.raises(ValueError, match="not an axis"):
        broadphase.pairs(c, 1.0, box=10, periodic="w")
    with pytest.raises(ValueError, match="twice"):
        broadphase.pairs(c, 1.0, box=10, periodic="xx")
    with pytest.raises(ValueError, match=r"box\[1\]"):
        broadphase.pairs(c, 1.0, box=(10, 0, 10))
    # A length on an axis that is not periodic is not read.
    p, s = broadphase.pairs(c, 1.0, box=(10, np.nan, 10), periodic="xz")
    assert p.tolist() == [[0, 1]]
