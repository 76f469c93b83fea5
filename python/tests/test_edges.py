"""Edge cases of the issue: 0 and 1 objects, identical centres, touching,
zero and huge radii, float32, strided, Fortran-ordered and read-only input
(read in place), wrong shapes and bad values (ValueError naming the argument
and the index), arrays that outlive the index."""

import gc

import numpy as np
import pytest

import broadphase
from conftest import as_set, oracle_pairs

EMPTY = np.zeros((0, 2), np.int64)


@pytest.mark.parametrize("structure", [None, "naive", "grid-verlet"])
def test_zero_and_one_object(structure):
    for n in (0, 1):
        c = np.zeros((n, 3))
        assert broadphase.sphere_pairs(c, 1.0).shape == (0, 2)
        ix = broadphase.Index(c, 1.0, structure=structure)
        assert ix.pairs().shape == (0, 2) and ix.count_pairs() == 0 and len(ix) == n
        assert list(ix.iter_pairs()) == []
        assert ix.query(np.zeros((0, 3)), 1.0).shape == (0, 2)
    assert broadphase.sphere_pairs([], []).shape == (0, 2)


def test_identical_centres_and_zero_radii():
    c = np.ones((5, 3))
    want = {(i, j) for i in range(5) for j in range(i + 1, 5)}
    assert as_set(broadphase.sphere_pairs(c, 0.0)) == want
    assert as_set(broadphase.box_pairs(c, c)) == want
    # Points 1e-300 apart: d2 underflows to 0 <= 0, a pair by the contract.
    pts = np.array([[0, 0, 0], [0, 0, 1e-300], [0, 0, 1e-100], [1, 1, 1]], float)
    assert as_set(broadphase.sphere_pairs(pts, 0.0)) == as_set(oracle_pairs(pts, np.zeros(4))) == {(0, 1)}


def test_touching_counts():
    c = np.array([[0, 0, 0], [2, 0, 0], [4.0000000001, 0, 0]], float)
    assert as_set(broadphase.sphere_pairs(c, 1.0)) == {(0, 1)}
    lo = np.array([[0, 0, 0], [1, 0, 0], [2, 0.5, 0], [3.5, 0, 0]], float)
    assert as_set(broadphase.box_pairs(lo, lo + 1)) == {(0, 1), (1, 2)}
    # sphere touching a box face
    got = broadphase.pairs([[0, 0, 0], [2, 0, 0]], radii=[1, 0], half_extents=[[0, 0, 0], [1, 1, 1]],
                           kinds=[0, 1])
    assert as_set(got) == {(0, 1)}


def test_huge_radius_and_far_coordinates(rng):
    c = rng.random((300, 3)) * 1e6
    r = np.full(300, 1.0)
    r[17] = 1e9
    got = as_set(broadphase.sphere_pairs(c, r))
    assert got == as_set(oracle_pairs(c, r))
    assert sum(17 in p for p in got) == 299
    far = np.array([[1e300, 0, 0], [1e300, 0, 0], [-1e300, 0, 0]])
    assert as_set(broadphase.sphere_pairs(far, 0.0)) == {(0, 1)}


def reads_in_place(a):
    """True when numpy would hand the module this very memory (no conversion)."""
    return broadphase._real(a, "x") is a


def test_float32_strided_fortran_readonly_read_in_place(rng):
    c64 = rng.random((500, 3))
    r64 = rng.random(500) * 0.05
    want = as_set(oracle_pairs(c64, r64))
    c32, r32 = c64.astype(np.float32), r64.astype(np.float32)
    want32 = as_set(oracle_pairs(c32.astype(np.float64), r32.astype(np.float64)))
    cf = np.asfortranarray(c64)
    big = np.zeros((500, 7))
    big[:, 2:5] = c64
    strided = big[:, 2:5]
    rs = np.repeat(r64, 3)[::3]
    ro = c64.copy()
    ro.setflags(write=False)
    for arr, radii, w in [(c32, r32, want32), (cf, r64, want), (strided, r64, want), (ro, rs, want)]:
        assert reads_in_place(arr) and reads_in_place(radii)
        assert as_set(broadphase.sphere_pairs(arr, radii)) == w
        ix = broadphase.Index(arr, radii)
        assert ix.borrowing and as_set(ix.pairs()) == w
    # negative strides (a reversed view) and zero strides (a broadcast radius)
    rev, rrev = c64[::-1], r64[::-1]
    assert reads_in_place(rev) and rev.strides[0] < 0
    assert as_set(broadphase.sphere_pairs(rev, rrev)) == as_set(oracle_pairs(rev, rrev))
    rb = np.broadcast_to(np.float64(0.03), (500,))
    assert reads_in_place(rb) and rb.strides == (0,)
    assert as_set(broadphase.sphere_pairs(c64, rb)) == as_set(oracle_pairs(c64, np.full(500, 0.03)))
    # float32 centres with float64 radii mix freely
    assert as_set(broadphase.sphere_pairs(c32, r32.astype(np.float64))) == want32


def test_other_types_are_converted(rng):
    c = rng.integers(0, 10, size=(100, 3))
    want = as_set(oracle_pairs(c.astype(float), np.full(100, 1.0)))
    assert not reads_in_place(c)
    assert as_set(broadphase.sphere_pairs(c, 1)) == want
    assert as_set(broadphase.sphere_pairs(c.tolist(), 1)) == want
    assert as_set(broadphase.sphere_pairs(c.astype(">f8"), 1)) == want


@pytest.mark.parametrize("call,message", [
    (lambda: broadphase.sphere_pairs(np.zeros((4, 2)), 1.0), "centers: expected shape (N, 3), got (4, 2)"),
    (lambda: broadphase.sphere_pairs(np.zeros((4, 3, 1)), 1.0), "centers: expected shape"),
    (lambda: broadphase.sphere_pairs(np.zeros((4, 3)), np.ones(3)), "radii: expected 4 rows"),
    (lambda: broadphase.sphere_pairs(np.zeros((4, 3)), np.ones((4, 1))), "radii: expected shape"),
    (lambda: broadphase.sphere_pairs([[0, 0, 0], [0, np.nan, 0]], 1.0), "centers[1, 1] is nan"),
    (lambda: broadphase.sphere_pairs([[0, 0, 0], [0, 0, np.inf]], 1.0), "centers[1, 2] is inf"),
    (lambda: broadphase.sphere_pairs(np.zeros((3, 3)), [1, 1, -0.5]), "radii[2] is negative"),
    (lambda: broadphase.sphere_pairs(np.zeros((3, 3)), -1.0), "radii is negative"),
    (lambda: broadphase.sphere_pairs(np.zeros((3, 3)), [1, np.nan, 1]), "radii[1] is nan"),
    (lambda: broadphase.pairs(np.zeros((2, 3)), half_extents=[[1, 1, 1], [1, -1, 1]]),
     "half_extents[1, 1] is negative"),
    (lambda: broadphase.pairs(np.zeros((2, 3)), 1.0, [[1, 1, 1]] * 2), "kinds"),
    (lambda: broadphase.pairs(np.zeros((2, 3)), 1.0, [[1, 1, 1]] * 2, kinds=[0, 2]), "kinds[1] is 2"),
    (lambda: broadphase.pairs(np.zeros((2, 3))), "radii"),
    (lambda: broadphase.box_pairs(np.zeros((2, 3)), -np.ones((2, 3))), "hi[0, 0] < lo[0, 0]"),
    (lambda: broadphase.sphere_pairs([["a", "b", "c"]], 1.0), "centers"),
    (lambda: broadphase.Index(np.zeros((2, 3)), 1.0, structure="no-such"), "unknown structure 'no-such'"),
    (lambda: broadphase.Index(np.zeros((2, 3)), 1.0, structure="grid-verlet:nope=1"), "nope"),
    (lambda: broadphase.Index(np.zeros((2, 3)), 1.0).update(np.zeros((3, 3))), "keeps its object count"),
    (lambda: broadphase.Index(np.zeros((2, 3)), 1.0).remove([5]), "ids[0] is 5"),
    (lambda: broadphase.Index(np.zeros((2, 3)), 1.0).update([0], [[0, 0, np.nan]]), "centers[0, 2] is nan"),
    (lambda: broadphase.Index(np.zeros((2, 3)), 1.0).query([[0, 0, 0]], -1.0), "other_radii is negative"),
    (lambda: broadphase.Index(np.zeros((2, 3)), 1.0).query_box([0, 0, 0], [1, np.nan, 1]), "hi[1] is nan"),
    (lambda: broadphase.Index(np.zeros((2, 3)), 1.0).iter_pairs(0).__next__(), "chunk"),
    (lambda: broadphase.Index(np.zeros((2, 3)), 1.0, skin=np.nan), "option 'skin'"),
    (lambda: broadphase.Index(np.zeros((2, 3)), 1.0, skin=-1.0), "option 'skin'"),
    (lambda: broadphase.Index(np.zeros((2, 3)), 1.0, skin=np.inf), "option 'skin'"),
])
def test_bad_input_raises_value_error_naming_it(call, message):
    with pytest.raises(ValueError) as e:
        call()
    assert message in str(e.value)


def test_bad_in_place_change_is_refused_and_index_unchanged():
    c = np.array([[0, 0, 0], [1, 0, 0], [5, 0, 0]], float)
    ix = broadphase.Index(c, 0.6)
    c[2, 0] = np.nan
    with pytest.raises(ValueError, match=r"centers\[2, 0\] is nan"):
        ix.update()
    assert as_set(ix.pairs()) == {(0, 1)}
    c[2, 0] = 1.5
    ix.update([2])
    assert as_set(ix.pairs()) == {(0, 1), (1, 2)}


def test_returned_arrays_outlive_the_index(rng):
    c = rng.random((300, 3))
    ix = broadphase.Index(c, 0.1)
    p = ix.pairs()
    chunks = ix.iter_pairs(chunk=7)
    first = next(chunks)
    want = as_set(oracle_pairs(c, np.full(300, 0.1)))
    del ix
    gc.collect()
    _ = [np.ones(10000) for _ in range(50)]
    assert as_set(p) == want
    p[0, 0] = 0  # writable, its own memory
    rest = list(chunks)
    assert as_set(np.concatenate([first] + rest)) == want
    assert all(len(x) <= 7 for x in rest)


def test_returned_array_owns_its_memory():
    p = broadphase.sphere_pairs(np.zeros((3, 3)), 1.0)
    assert p.flags.writeable and p.flags.c_contiguous and p.dtype == np.int64
    assert p.base is not None  # the module's buffer, kept alive by the array


def test_a_refused_update_changes_nothing():
    c = np.array([[0, 0, 0], [1.5, 0, 0], [2.5, 0, 0]], float)
    r = np.array([1.0, 0, 0])
    h = np.array([[0, 0, 0], [0.5, 0.5, 0.5], [0.5, 0.5, 0.5]])
    for structure in (None, "aabb-tree"):
        ix = broadphase.Index(c, r, h, [0, 1, 1], structure=structure)
        before = as_set(ix.pairs())
        with pytest.raises(ValueError, match="object 1: a sphere takes radii, a box half_extents"):
            ix.update([0, 1], [[9.0, 9, 9], [9.0, 9, 9]], radii=[1.0, 1.0])
        assert as_set(ix.pairs()) == before == {(0, 1), (1, 2)}
        assert ix.borrowing == (structure is None)
        ix.update([2], [[2.5, 0, 0]])  # a later change sees object 0 where it was
        assert as_set(ix.pairs()) == {(0, 1), (1, 2)}


def test_large_outputs_are_whole_and_outlive_the_call():
    # Past 4 MiB an output grows inside address space of its own: 1 500
    # spheres on one place give 1 124 250 pairs (18 MB), every one of them.
    n = 1500
    c = np.zeros((n, 3))
    for structure in (None, "aabb-tree"):
        p = (broadphase.sphere_pairs(c, 1.0) if structure is None
             else broadphase.Index(c, 1.0, structure=structure).pairs())
        assert p.shape == (n * (n - 1) // 2, 2)
        i, j = p[:, 0], p[:, 1]
        assert (i < j).all()
        key = np.unique(i * n + j)
        assert len(key) == len(p)
        gc.collect()
        _ = [np.ones(100000) for _ in range(20)]
        p[-1, 1] = 7  # writable to its last row
        assert p[-1, 1] == 7


def test_kept_memory_is_reused_whole_and_can_be_returned():
    # A freed output of 4 MiB or more is kept for the next output (its
    # pages in place): the next outputs, grown into it from the heap and
    # past it, are whole, and two live outputs never share memory.
    def spheres(q, k):  # k apart (no pairs), then q places of 50 spheres each
        c = np.zeros((k + 50 * q, 3))
        c[:k, 0] = 10.0 * (np.arange(k) + 1)
        c[k:, 1] = 10.0 * (np.arange(50 * q) // 50 + 1)
        return c

    def whole(p, q, k):
        assert p.shape == (1225 * q, 2)
        i, j = p[:, 0], p[:, 1]
        assert (i < j).all() and i.min() >= k and j.max() < k + 50 * q
        assert ((i - k) // 50 == (j - k) // 50).all()
        assert len(np.unique(i * (k + 50 * q) + j)) == len(p)

    limit = broadphase._broadphase.scratch_limit()
    try:
        p = broadphase.sphere_pairs(spheres(800, 3000), 1.0)  # 16 MB
        del p
        gc.collect()
        assert broadphase.scratch_bytes() >= 16 << 20
        a = broadphase.sphere_pairs(spheres(300, 0), 1.0)  # 6 MB: from the heap into p's range
        b = broadphase.sphere_pairs(spheres(1300, 1000), 1.0)  # 25 MB, fresh
        whole(a, 300, 0)
        whole(b, 1300, 1000)
        assert not np.shares_memory(a, b)
        del a
        gc.collect()
        c = broadphase.sphere_pairs(spheres(1300, 1000), 1.0)  # p's range again, grown past it
        whole(c, 1300, 1000)
        assert np.array_equal(b, c) and not np.shares_memory(b, c)
        broadphase.set_scratch_limit(0)
        assert broadphase.scratch_bytes() == 0
        del b, c
        gc.collect()
        assert broadphase.scratch_bytes() == 0  # nothing kept at 0
        with pytest.raises(ValueError, match="limit"):
            broadphase.set_scratch_limit(-1)
    finally:
        broadphase.set_scratch_limit(limit)
