"""One-shot calls and the index against the O(N^2) numpy oracle, on random
sets built to have many exact ties (coordinates and sizes on a coarse
dyadic lattice, so touching pairs are common and exactly representable)."""

import numpy as np
import pytest

import broadphase
from conftest import as_set, oracle_pairs


def random_set(rng, n, kind="spheres", lattice=True, dtype=np.float64):
    if lattice:
        c = rng.integers(0, 16, size=(n, 3)) / 4.0
        r = rng.integers(0, 5, size=n) / 8.0
        h = rng.integers(0, 5, size=(n, 3)) / 8.0
    else:
        c = rng.random((n, 3))
        r = rng.random(n) * 0.15
        h = rng.random((n, 3)) * 0.1
    if kind == "spheres":
        return dict(centers=c.astype(dtype), radii=r.astype(dtype))
    if kind == "boxes":
        return dict(centers=c.astype(dtype), half_extents=h.astype(dtype))
    k = rng.integers(0, 2, size=n).astype(np.uint8)
    return dict(centers=c.astype(dtype), radii=r.astype(dtype), half_extents=h.astype(dtype), kinds=k)


def oracle(s):
    return as_set(oracle_pairs(s["centers"], s.get("radii"), s.get("half_extents"), s.get("kinds")))


@pytest.mark.parametrize("kind", ["spheres", "boxes", "mixed"])
@pytest.mark.parametrize("lattice", [True, False])
def test_one_shot_matches_oracle(rng, kind, lattice):
    for trial in range(8):
        n = int(rng.integers(0, 300))
        s = random_set(rng, n, kind, lattice)
        want = oracle(s)
        got = broadphase.pairs(**s)
        assert got.dtype == np.int64
        assert as_set(got) == want, f"trial {trial} n {n}"
        srt = broadphase.pairs(**s, sorted=True)
        assert as_set(srt) == want
        assert (np.lexsort((srt[:, 1], srt[:, 0])) == np.arange(len(srt))).all()


def test_threads_give_the_same_pairs_in_the_same_order(rng):
    s = random_set(rng, 1500, "spheres", lattice=False)
    s["radii"] = s["radii"] * 0.2
    one = broadphase.pairs(**s)
    for t in (2, 3, 0):
        assert np.array_equal(broadphase.pairs(**s, threads=t), one)
    assert as_set(one) == oracle(s)


def test_sphere_pairs_scalar_and_per_object_radii(rng):
    c = rng.random((400, 3))
    want = as_set(oracle_pairs(c, np.full(400, 0.05)))
    assert as_set(broadphase.sphere_pairs(c, 0.05)) == want
    assert as_set(broadphase.sphere_pairs(c, np.full(400, 0.05))) == want
    assert as_set(broadphase.sphere_pairs(c, [0.05])) == want


def test_box_pairs_from_corners(rng):
    c = rng.integers(0, 16, size=(300, 3)) / 4.0
    h = rng.integers(0, 5, size=(300, 3)) / 8.0
    got = broadphase.box_pairs(c - h, c + h)
    assert as_set(got) == as_set(oracle_pairs(c, half=h, kinds=np.ones(300, np.uint8)))


def test_bipartite_matches_oracle(rng):
    a = random_set(rng, 200, "mixed")
    b = random_set(rng, 150, "mixed")
    n = 200
    joined = {k: np.concatenate([a[k], b[k]]) for k in a}
    want = {(i, j - n) for i, j in oracle(joined) if i < n <= j}
    got = broadphase.pairs_between(a["centers"], a["radii"], b["centers"], b["radii"],
                                   half_extents=a["half_extents"], kinds=a["kinds"],
                                   other_half_extents=b["half_extents"], other_kinds=b["kinds"])
    assert set(map(tuple, got.tolist())) == want
    assert len(got) == len(want)


@pytest.mark.parametrize("structure", [None, "naive", "grid-verlet:threads=2"])
def test_index_query_matches_oracle(rng, structure):
    a = random_set(rng, 250, "spheres")
    q = random_set(rng, 60, "spheres")
    ix = broadphase.Index(a["centers"], a["radii"], structure=structure)
    n = 250
    joined = {k: np.concatenate([a[k], q[k]]) for k in a}
    want = sorted((j - n, i) for i, j in oracle(joined) if i < n <= j)
    got = ix.query(q["centers"], q["radii"])
    assert [tuple(p) for p in got.tolist()] == want
    indptr, idx = ix.query(q["centers"], q["radii"], output="csr")
    assert len(indptr) == 61 and indptr[-1] == len(want)
    for k in range(60):
        assert list(idx[indptr[k]:indptr[k + 1]]) == [i for (qq, i) in want if qq == k]
    lo, hi = np.array([1.0, 1.0, 1.0]), np.array([2.0, 2.5, 3.0])
    box = {"centers": np.array([(lo + hi) / 2]), "half_extents": np.array([(hi - lo) / 2])}
    joined = {"centers": np.concatenate([a["centers"], box["centers"]]),
              "radii": np.concatenate([a["radii"], [0]]),
              "half_extents": np.concatenate([np.zeros((n, 3)), box["half_extents"]]),
              "kinds": np.concatenate([np.zeros(n, np.uint8), [1]]).astype(np.uint8)}
    want_box = sorted(i for i, j in oracle(joined) if j == n)
    assert list(ix.query_box(lo, hi)) == want_box


def test_to_sparse(rng):
    c = rng.random((200, 3))
    p = broadphase.sphere_pairs(c, 0.08)
    m = broadphase.to_sparse(p, 200)
    assert m.shape == (200, 200) and m.nnz == 2 * len(p)
    assert (m != m.T).nnz == 0
    u = broadphase.to_sparse(p, 200, format="coo", symmetric=False)
    assert u.nnz == len(p) and (u.row < u.col).all()
