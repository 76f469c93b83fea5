"""The index against a model: random updates, inserts and removes on every
structure, checked against the oracle after each step (update == rebuild);
borrowing versus owning."""

import numpy as np
import pytest

import broadphase
from conftest import QUICK, as_set, oracle_pairs

STRUCTURES = [None] + [name for name, _ in broadphase.structures()] + ["grid-verlet:threads=3,grain=1"]


class Model:
    """What the index should hold: id -> (centre, radius, half, kind)."""

    def __init__(self):
        self.objs = {}

    def pairs(self):
        ids = sorted(self.objs)
        if not ids:
            return set()
        c = np.array([self.objs[i][0] for i in ids])
        r = np.array([self.objs[i][1] for i in ids])
        h = np.array([self.objs[i][2] for i in ids])
        k = np.array([self.objs[i][3] for i in ids], np.uint8)
        return {(ids[a], ids[b]) for a, b in oracle_pairs(c, r, h, k).tolist()}


def draw(rng, n, mixed):
    c = rng.integers(0, 16, size=(n, 3)) / 4.0
    r = rng.integers(0, 5, size=n) / 8.0
    h = rng.integers(0, 5, size=(n, 3)) / 8.0
    k = rng.integers(0, 2, size=n).astype(np.uint8) if mixed else np.zeros(n, np.uint8)
    h[k == 0] = 0
    r[k == 1] = 0
    return c, r, h, k


@pytest.mark.parametrize("structure", STRUCTURES)
@pytest.mark.parametrize("mixed", [False, True])
def test_random_operations_match_the_model(rng, structure, mixed):
    n = 120
    c, r, h, k = draw(rng, n, mixed)
    if mixed:
        ix = broadphase.Index(c, r, h, k, structure=structure)
    else:
        ix = broadphase.Index(c, r, structure=structure)
    model = Model()
    for i in range(n):
        model.objs[i] = (c[i], r[i], h[i], k[i])
    steps = 12 if QUICK else 40
    for step in range(steps):
        op = rng.integers(0, 5)
        live = np.array(sorted(model.objs), np.int64)
        if op == 0 and len(live):  # some move
            ids = rng.choice(live, size=min(len(live), int(rng.integers(1, 20))), replace=False)
            nc = rng.integers(0, 16, size=(len(ids), 3)) / 4.0
            ix.update(ids, nc)
            for i, x in zip(ids, nc):
                model.objs[i] = (x,) + model.objs[i][1:]
        elif op == 1 and len(live):  # all move
            nc = rng.integers(0, 16, size=(len(live), 3)) / 4.0
            ix.update(nc)
            for i, x in zip(live, nc):
                model.objs[i] = (x,) + model.objs[i][1:]
        elif op == 2:
            m = int(rng.integers(1, 15))
            a, b, hh, kk = draw(rng, m, mixed)
            new = ix.insert(a, b, hh, kk) if mixed else ix.insert(a, b)
            assert len(set(new.tolist()) & set(model.objs)) == 0
            for t, i in enumerate(new):
                model.objs[int(i)] = (a[t], b[t], hh[t], kk[t])
        elif op == 3 and len(live):
            ids = rng.choice(live, size=min(len(live), int(rng.integers(1, 15))), replace=False)
            ix.remove(ids)
            for i in ids:
                del model.objs[int(i)]
        elif op == 4 and len(live) and not mixed:  # move and resize
            ids = rng.choice(live, size=min(len(live), 5), replace=False)
            nc = rng.integers(0, 16, size=(len(ids), 3)) / 4.0
            nr = rng.integers(0, 5, size=len(ids)) / 8.0
            ix.update(ids, nc, radii=nr)
            for i, x, rr in zip(ids, nc, nr):
                model.objs[i] = (x, rr) + model.objs[i][2:]
        want = model.pairs()
        assert as_set(ix.pairs()) == want, f"step {step} op {op}"
        assert ix.count_pairs() == len(want)
        assert list(ix.ids()) == sorted(model.objs)
        assert len(ix) == len(model.objs)
    ix.validate()


@pytest.mark.parametrize("structure", [None, "grid-verlet", "aabb-tree"])
def test_update_equals_rebuild(rng, structure):
    c = rng.random((800, 3))
    r = rng.random(800) * 0.04
    ix = broadphase.Index(c.copy(), r, structure=structure)
    for frame in range(10):
        c[rng.random(800) < 0.2] += rng.normal(0, 0.02, size=(1, 3))
        ix.update(c.copy())
        rebuilt = broadphase.Index(c, r, structure=structure)
        assert np.array_equal(ix.pairs(sorted=True), rebuilt.pairs(sorted=True))
        assert np.array_equal(ix.pairs(sorted=True), broadphase.sphere_pairs(c, r, sorted=True))


def test_borrowing_then_owning(rng):
    c = rng.random((100, 3))
    ix = broadphase.Index(c, 0.1)
    assert ix.borrowing
    c[3] = c[4]
    ix.update([3])  # reads the caller's array
    assert (3, 4) in as_set(ix.pairs())
    new = ix.insert([[5.0, 5, 5]], 0.1)
    assert not ix.borrowing and list(new) == [100]
    before = as_set(ix.pairs())
    c[:] = 0  # no longer read
    ix.update([0], [[7.0, 7, 7]])
    assert as_set(ix.pairs()) == {p for p in before if 0 not in p}
    with pytest.raises(RuntimeError, match="owns its data"):
        ix.update()


def test_iter_pairs_is_the_pairs_in_chunks(rng):
    c = rng.random((2000, 3))
    ix = broadphase.Index(c, 0.03)
    whole = ix.pairs()
    chunks = list(ix.iter_pairs(chunk=1000))
    assert all(len(x) <= 1000 for x in chunks)
    assert np.array_equal(np.concatenate(chunks), whole)


def test_spare_bytes_bound_the_memory_not_the_pairs(rng):
    """A crowded world (each sphere overlaps several) whose movers move in
    place: the same pairs as brute force on every frame with no bytes
    spared, some, and the default. The three runs see the same world and
    the same motion, so the lean tracker's memory is what differs: it grows
    with the bytes spared (96 KiB may already hold every pair, as the
    default's 16 MiB does, so the last step may be equal)."""
    n = 1200
    start = rng.uniform(0, 15, size=(n, 3))
    r = rng.uniform(0.5, 1.5, size=n)
    movers = np.flatnonzero(rng.integers(0, 7, size=n) == 0)
    steps = [rng.uniform(-0.05, 0.05, size=(len(movers), 3)) for _ in range(6 if QUICK else 12)]
    memory = []
    for spare in (1, 96 << 10, 0):
        c = start.copy()
        ix = broadphase.Index(c, r, spare_bytes=spare)
        for frame, step in enumerate(steps):
            c[movers] += step
            ix.update(movers)
            got = as_set(ix.pairs())
            assert len(got) > 2 * n, "not a crowded world"
            assert got == as_set(oracle_pairs(c, r)), f"spare_bytes {spare}, frame {frame}"
        memory.append(ix.memory_bytes())
    assert memory[0] < memory[1] <= memory[2], memory


def test_spare_bytes_must_not_be_negative():
    with pytest.raises(ValueError, match="spare_bytes"):
        broadphase.Index(np.zeros((2, 3)), 1.0, spare_bytes=-1)
