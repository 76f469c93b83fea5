"""broadphase.knn and broadphase.within against a brute force in numpy with
the same arithmetic (docs/knn.md), and against scipy's cKDTree.query,
query_ball_point and pykdtree (when installed) on shared cases. Seeds are
fixed and named in each assertion's message."""

import threading

import numpy as np
import pytest
from scipy.spatial import cKDTree

import broadphase

from conftest import QUICK

try:
    from pykdtree.kdtree import KDTree as PyKDTree
except ImportError:  # python3-pykdtree is optional
    PyKDTree = None

SEEDS = range(2 if QUICK else 5)


def rule_d2(q, p, box=None):
    """(M, N) squared distances, one IEEE operation per ufunc (no FMA):
    dx = q - p per axis; a periodic axis takes the smallest square of the
    three images p, p + L, p - L; then dx2 + dy2 + dz2, left to right."""
    q = np.asarray(q, np.float64)
    p = np.asarray(p, np.float64)
    terms = []
    for a in range(3):
        d = q[:, None, a] - p[None, :, a]
        t = d * d
        if box is not None and box[a] != 0:
            up = q[:, None, a] - (p[None, :, a] + box[a])
            down = q[:, None, a] - (p[None, :, a] - box[a])
            t = np.minimum(t, np.minimum(up * up, down * down))
        terms.append(t)
    return (terms[0] + terms[1]) + terms[2]


def brute_knn(q, p, k, box=None, exclude_self=False):
    d2 = rule_d2(q, p, box)
    n = len(p)
    if exclude_self:
        d2[np.arange(len(q)), np.arange(len(q))] = np.inf
    order = np.lexsort((np.broadcast_to(np.arange(n), d2.shape), d2), axis=-1) if n else \
        np.zeros((len(q), 0), np.int64)
    idx = np.full((len(q), k), n, np.int64)
    dist = np.full((len(q), k), np.inf)
    m = min(k, n - (1 if exclude_self else 0)) if n else 0
    if m > 0:
        idx[:, :m] = order[:, :m]
        dist[:, :m] = np.sqrt(np.take_along_axis(d2, order[:, :m], axis=1))
    return dist, idx


def make(kind, n, rng, side=10.0):
    if kind == "uniform":
        return rng.uniform(0, side, (n, 3))
    if kind == "lattice":  # duplicates and ties of distance everywhere
        return rng.integers(0, 5, (n, 3)) * (side / 4)
    if kind == "clustered":
        c = rng.uniform(0, side, (4, 3))
        return np.clip(c[rng.integers(0, 4, n)] + rng.normal(0, side / 50, (n, 3)), 0, side)
    raise ValueError(kind)


@pytest.mark.parametrize("kind", ["uniform", "lattice", "clustered"])
def test_knn_and_within_match_brute_force(kind):
    for seed in SEEDS:
        rng = np.random.default_rng(seed)
        n = int(rng.integers(0, 300))
        p = make(kind, n, rng)
        q = make("uniform", 50, rng, 14.0)
        for k in (1, 5, n + 2):
            for queries, exclude in ((None, False), (None, True), (q, False)):
                rows = p if queries is None else queries
                want_d, want_i = brute_knn(rows, p, k, exclude_self=exclude)
                d, i = broadphase.knn(p, queries, k, exclude_self=exclude)
                if k == 1:
                    d, i = d.reshape(-1, 1), i.reshape(-1, 1)
                msg = f"seed {seed} {kind} n {n} k {k} exclude_self {exclude}"
                np.testing.assert_array_equal(i, want_i, err_msg=msg)
                np.testing.assert_array_equal(d, want_d, err_msg=msg)
        r = 2.5
        off, idx, dist = broadphase.within(p, q, r, distances=True)
        d2 = rule_d2(q, p)
        for row in range(len(q)):
            keep = np.flatnonzero(d2[row] <= r * r)
            keep = keep[np.lexsort((keep, d2[row][keep]))]
            got = idx[off[row]:off[row + 1]]
            np.testing.assert_array_equal(got, keep, err_msg=f"seed {seed} {kind} row {row}")
            np.testing.assert_array_equal(dist[off[row]:off[row + 1]], np.sqrt(d2[row][keep]))


def test_periodic_boxes_match_brute_force():
    for seed in SEEDS:
        rng = np.random.default_rng(100 + seed)
        n = int(rng.integers(1, 300))
        box = [10.0, 7.5 if seed % 2 else 0.0, 15.0 if seed % 3 else 2.5]
        p = make("lattice" if seed % 2 else "uniform", n, rng) / 10 * np.where(
            np.array(box) > 0, np.array(box), 10.0)
        for k in (1, 6, n + 1):
            want_d, want_i = brute_knn(p, p, k, box=box, exclude_self=True)
            d, i = broadphase.knn(p, k=k, box=box, exclude_self=True)
            if k == 1:
                d, i = d.reshape(-1, 1), i.reshape(-1, 1)
            msg = f"seed {seed} box {box} n {n} k {k}"
            np.testing.assert_array_equal(i, want_i, err_msg=msg)
            np.testing.assert_array_equal(d, want_d, err_msg=msg)
        off, idx = broadphase.within(p, None, 4.0, box=box)
        d2 = rule_d2(p, p, box)
        for row in range(n):
            keep = np.flatnonzero(d2[row] <= 16.0)
            keep = keep[np.lexsort((keep, d2[row][keep]))]
            np.testing.assert_array_equal(idx[off[row]:off[row + 1]], keep,
                                          err_msg=f"seed {seed} box {box} row {row}")


def test_knn_equals_ckdtree_query():
    """Uniform doubles: no two distances of a row tie, so indices and
    distances must equal cKDTree's (distances to the last bit: both take
    the square root of the same sum)."""
    for seed in SEEDS:
        rng = np.random.default_rng(200 + seed)
        p = rng.uniform(0, 1, (2000, 3))
        q = rng.uniform(-0.1, 1.1, (300, 3))
        tree = cKDTree(p)
        for k in (1, 8, 32):
            d, i = broadphase.knn(p, q, k)
            td, ti = tree.query(q, k)
            np.testing.assert_array_equal(i, ti, err_msg=f"seed {seed} k {k}")
            np.testing.assert_allclose(d, td, rtol=1e-15, atol=0, err_msg=f"seed {seed} k {k}")
        # Self-queries with k + 1 (cKDTree's users drop column 0) against
        # exclude_self.
        d, i = broadphase.knn(p, k=8, exclude_self=True)
        td, ti = tree.query(p, 9)
        np.testing.assert_array_equal(i, ti[:, 1:], err_msg=f"seed {seed} exclude_self")
        # k beyond n: cKDTree fills with inf and n, as we do.
        d, i = broadphase.knn(p[:5], q, 8)
        td, ti = cKDTree(p[:5]).query(q, 8)
        np.testing.assert_array_equal(i, ti)
        np.testing.assert_array_equal(np.isinf(d), np.isinf(td))


def test_knn_equals_ckdtree_with_ties_named():
    """Points on a lattice: many equal distances. cKDTree orders ties as
    its tree meets them; we order them by index. So each row's distances
    must be equal column by column, and the indices equal as sets within
    each group of equal distances (the last group may be cut by k: there
    both must hold only points at that distance)."""
    rng = np.random.default_rng(7)
    p = rng.integers(0, 6, (500, 3)).astype(np.float64)
    q = rng.integers(0, 6, (100, 3)).astype(np.float64) + 0.5
    for k in (1, 8, 27):
        d, i = broadphase.knn(p, q, k)
        td, ti = cKDTree(p).query(q, k)
        d, i, td, ti = (a.reshape(len(q), -1) for a in (d, i, td, ti))
        np.testing.assert_array_equal(d, td, err_msg=f"seed 7 k {k}")
        d2 = rule_d2(q, p)
        for row in range(len(q)):
            for dist in np.unique(d[row]):
                ours = set(i[row][d[row] == dist])
                theirs = set(ti[row][td[row] == dist])
                if dist < d[row][-1]:
                    assert ours == theirs, f"seed 7 k {k} row {row} distance {dist}"
                else:
                    at = set(np.flatnonzero(np.sqrt(d2[row]) == dist))
                    assert ours <= at and theirs <= at, f"seed 7 k {k} row {row}"
            # Ours: ties by index.
            for c in range(1, k):
                assert (d[row][c - 1], i[row][c - 1]) < (d[row][c], i[row][c])


def test_periodic_knn_equals_ckdtree_boxsize():
    rng = np.random.default_rng(11)
    box = np.array([1.0, 2.0, 0.5])
    p = rng.uniform(0, 1, (3000, 3)) * box
    q = rng.uniform(0, 1, (200, 3)) * box
    for k in (1, 8, 32):
        d, i = broadphase.knn(p, q, k, box=box)
        td, ti = cKDTree(p, boxsize=box).query(q, k)
        np.testing.assert_array_equal(i, ti, err_msg=f"seed 11 k {k}")
        np.testing.assert_allclose(d, td, rtol=1e-14, atol=0)
    # query_ball_point: the same sets (no distance lies within rounding of r
    # here; at exactly r the two rules may differ, which this case avoids).
    off, idx = broadphase.within(p, q, 0.1, box=box)
    balls = cKDTree(p, boxsize=box).query_ball_point(q, 0.1)
    for row in range(len(q)):
        assert set(idx[off[row]:off[row + 1]]) == set(balls[row]), f"seed 11 row {row}"


@pytest.mark.skipif(PyKDTree is None, reason="python3-pykdtree is not installed")
def test_knn_equals_pykdtree():
    """pykdtree fills missing neighbours with its own values (index 2^32-1,
    distance sqrt of the largest double): compared where it has neighbours."""
    rng = np.random.default_rng(13)
    p = rng.uniform(0, 1, (2000, 3))
    q = rng.uniform(0, 1, (300, 3))
    for k in (1, 8, 32):
        d, i = broadphase.knn(p, q, k)
        td, ti = PyKDTree(p).query(q, k=k)
        np.testing.assert_array_equal(i, ti.astype(np.int64), err_msg=f"seed 13 k {k}")
        np.testing.assert_allclose(d, td, rtol=1e-15, atol=0)


def test_shapes_and_dtypes_like_ckdtree():
    p = np.random.default_rng(3).uniform(0, 1, (50, 3))
    d, i = broadphase.knn(p, p[0], 4)
    td, ti = cKDTree(p).query(p[0], 4)
    assert d.shape == td.shape == (4,) and i.dtype == np.int64
    d, i = broadphase.knn(p, p[:3], 1)
    assert d.shape == (3,) and i.shape == (3,)
    d, i = broadphase.knn(p.astype(np.float32), p[:3].astype(np.float32), 2)
    assert d.dtype == np.float64 and d.shape == (3, 2)
    wide = broadphase.knn(p.astype(np.float32).astype(np.float64), p[:3].astype(np.float32), 2)
    np.testing.assert_array_equal(d, wide[0])
    d, i = broadphase.knn(np.zeros((0, 3)), p[:2], 2)
    np.testing.assert_array_equal(i, [[0, 0], [0, 0]])
    off, idx = broadphase.within(np.zeros((0, 3)), None, 1.0)
    assert off.tolist() == [0] and idx.size == 0


def test_bad_input_is_value_error():
    p = np.random.default_rng(3).uniform(0, 1, (10, 3))
    bad = p.copy()
    bad[4, 1] = np.nan
    with pytest.raises(ValueError, match=r"points\[4\]"):
        broadphase.knn(bad, k=2)
    with pytest.raises(ValueError, match=r"queries\[4\]"):
        broadphase.knn(p, bad, 2)
    with pytest.raises(ValueError, match="k: must be at least 1"):
        broadphase.knn(p, k=0)
    with pytest.raises(ValueError, match=r"points: expected shape \(N, 3\)"):
        broadphase.knn(p[:, :2], k=1)
    with pytest.raises(ValueError, match="r must be"):
        broadphase.within(p, None, -1.0)
    with pytest.raises(ValueError, match="outside the periodic box"):
        broadphase.knn(p * 2, k=1, box=1.0)
    with pytest.raises(ValueError, match=r"box\[1\]"):
        broadphase.knn(p, k=1, box=[1.0, -1.0, 1.0])
    with pytest.raises(ValueError, match="exclude_self: applies only"):
        broadphase.knn(p, p, 2, exclude_self=True)
    with pytest.raises(ValueError, match="exclude_self: applies only"):
        broadphase.within(p, p, 0.5, exclude_self=True)
    with pytest.raises(ValueError, match="cannot be read as numbers"):
        broadphase.knn([["a", "b", "c"]], k=1)


def test_threads_and_concurrent_calls_agree():
    rng = np.random.default_rng(17)
    p = rng.uniform(0, 1, (20000, 3))
    one = broadphase.knn(p, k=4, threads=1)
    two = broadphase.knn(p, k=4, threads=2)
    np.testing.assert_array_equal(one[1], two[1])
    out = [None, None]

    def run(slot):
        out[slot] = broadphase.knn(p, k=4)

    ts = [threading.Thread(target=run, args=(s,)) for s in (0, 1)]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    np.testing.assert_array_equal(out[0][1], one[1])
    np.testing.assert_array_equal(out[1][1], one[1])
