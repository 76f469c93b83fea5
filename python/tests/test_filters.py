"""Collision filters (groups and masks) on every call that builds pairs:
one-shot, bipartite, the index on the lean path and over named structures,
changed filters, and bad input. Against the numpy oracle with the filter
rule applied on top."""

import numpy as np
import pytest

import broadphase
from conftest import as_set, oracle_pairs


def passes(groups, masks, i, j):
    return (groups[i] & masks[j]) != 0 and (groups[j] & masks[i]) != 0


def filtered(pairs, groups, masks):
    return {(int(i), int(j)) for i, j in pairs if passes(groups, masks, i, j)}


def filter_bits(rng, n, layers):
    """Random bits (layers 0), or `layers` groups each pairing with itself
    and its two neighbouring groups only."""
    if layers == 0:
        return (rng.integers(0, 16, size=n).astype(np.uint32),
                rng.integers(0, 2**32, size=n, dtype=np.uint64).astype(np.uint32))
    layer = rng.integers(0, layers, size=n)
    groups = (np.uint32(1) << layer.astype(np.uint32)).astype(np.uint32)
    masks = (groups | (np.uint32(1) << ((layer + 1) % layers).astype(np.uint32))
             | (np.uint32(1) << ((layer + layers - 1) % layers).astype(np.uint32)))
    return groups, masks.astype(np.uint32)


def as_pairs(p):
    """A bipartite pair array as a set (no i < j there)."""
    return {tuple(map(int, row)) for row in np.asarray(p).tolist()}


def spheres(rng, n):
    c = rng.integers(0, 16, size=(n, 3)) / 4.0
    r = rng.integers(0, 5, size=n) / 8.0
    return c, r


@pytest.mark.parametrize("layers", [0, 4, 16])
def test_one_shot_with_filters_matches_oracle(rng, layers):
    for trial in range(6):
        n = int(rng.integers(2, 400))
        c, r = spheres(rng, n)
        g, m = filter_bits(rng, n, layers)
        want = filtered(oracle_pairs(c, r), g, m)
        for threads in (1, 2):
            assert as_set(broadphase.sphere_pairs(c, r, groups=g, masks=m, threads=threads)) == want
        assert as_set(broadphase.pairs(c, r, groups=g, masks=m, sorted=True)) == want
        h = np.full((n, 3), 0.25)
        boxes = broadphase.box_pairs(c - h, c + h, groups=g, masks=m)
        assert as_set(boxes) == filtered(oracle_pairs(c, half=h), g, m)


def test_one_of_groups_and_masks_takes_the_default_for_the_other(rng):
    c, r = spheres(rng, 200)
    g, _ = filter_bits(rng, 200, 4)
    full = np.full(200, 0xFFFFFFFF, np.uint32)
    want = filtered(oracle_pairs(c, r), g, full)
    assert as_set(broadphase.sphere_pairs(c, r, groups=g)) == want
    masks = np.full(200, 2, np.uint32)  # group 1 (the default) in no mask: nothing pairs
    assert len(broadphase.sphere_pairs(c, r, masks=masks)) == 0
    # Any integer dtype is taken.
    assert as_set(broadphase.sphere_pairs(c, r, groups=g.astype(np.int64))) == want


def test_pairs_between_with_filters(rng):
    c, r = spheres(rng, 150)
    oc, orr = spheres(rng, 120)
    g, m = filter_bits(rng, 150, 4)
    og, om = filter_bits(rng, 120, 4)
    got = broadphase.pairs_between(c, r, oc, orr, groups=g, masks=m,
                                   other_groups=og, other_masks=om)
    allc = np.vstack([c, oc])
    allr = np.concatenate([r, orr])
    want = set()
    for i, j in oracle_pairs(allc, allr):
        if i < 150 <= j and (g[i] & om[j - 150]) and (og[j - 150] & m[i]):
            want.add((int(i), int(j) - 150))
    assert as_pairs(got) == want
    # Filters on one side only: the other side has the default filter.
    one = broadphase.pairs_between(c, r, oc, orr, groups=g, masks=m)
    want_one = {(int(i), int(j) - 150) for i, j in oracle_pairs(allc, allr)
                if i < 150 <= j and (g[i] & 0xFFFFFFFF) and (1 & m[i])}
    assert as_pairs(one) == want_one


@pytest.mark.parametrize("structure", [None, "grid-verlet", "aabb-tree", "grid-static"])
def test_index_with_filters_follows_changes(rng, structure):
    n = 300
    c, r = spheres(rng, n)
    g, m = filter_bits(rng, n, 4)
    idx = broadphase.Index(c, r, structure=structure, groups=g, masks=m)
    assert as_set(idx.pairs()) == filtered(oracle_pairs(c, r), g, m)
    assert idx.count_pairs() == len(filtered(oracle_pairs(c, r), g, m))
    # Some filters change; then all of them.
    ids = rng.choice(n, size=40, replace=False)
    ng, nm = filter_bits(rng, 40, 16)
    idx.set_filters(ids, groups=ng, masks=nm)
    g[ids], m[ids] = ng, nm
    assert as_set(idx.pairs()) == filtered(oracle_pairs(c, r), g, m)
    g, m = filter_bits(rng, n, 0)
    idx.set_filters(groups=g, masks=m)
    assert as_set(idx.pairs()) == filtered(oracle_pairs(c, r), g, m)
    # Moves keep the filters.
    c2 = c + 0.125
    idx.update(c2)
    assert as_set(idx.pairs()) == filtered(oracle_pairs(c2, r), g, m)
    # Inserted objects with and without filters, then a removal.
    nc, nr = spheres(rng, 30)
    ng, nm = filter_bits(rng, 30, 4)
    new = idx.insert(nc, nr, groups=ng, masks=nm)
    more = idx.insert(nc[:5], nr[:5])
    allc = np.vstack([c2, nc, nc[:5]])
    allr = np.concatenate([r, nr, nr[:5]])
    allg = np.concatenate([g, ng, np.ones(5, np.uint32)])
    allm = np.concatenate([m, nm, np.full(5, 0xFFFFFFFF, np.uint32)])
    assert list(new) == list(range(n, n + 30)) and len(more) == 5
    assert as_set(idx.pairs()) == filtered(oracle_pairs(allc, allr), allg, allm)
    idx.remove([0, 7, n + 3])
    keep = [k for k in range(len(allc)) if k not in (0, 7, n + 3)]
    want = {(keep[i], keep[j]) for i, j in
            filtered(oracle_pairs(allc[keep], allr[keep]), allg[keep], allm[keep])}
    assert as_set(idx.pairs()) == want
    idx.validate()
    # The index's query is not filtered.
    q = idx.query(c2[:3], r[:3])
    assert len(q) >= 3


def test_bad_filters_are_refused(rng):
    c, r = spheres(rng, 10)
    good = np.ones(10, np.uint32)
    with pytest.raises(ValueError, match="groups"):
        broadphase.sphere_pairs(c, r, groups=np.ones(9, np.uint32), masks=good)
    with pytest.raises(ValueError, match="masks"):
        broadphase.sphere_pairs(c, r, groups=good, masks=np.ones(11, np.uint32))
    with pytest.raises(ValueError, match="dtype"):
        broadphase.sphere_pairs(c, r, groups=np.ones(10), masks=good)
    with pytest.raises(ValueError, match="groups"):
        broadphase.sphere_pairs(c, r, groups=np.full(10, -1), masks=good)
    with pytest.raises(ValueError, match="groups"):
        broadphase.sphere_pairs(c, r, groups=np.full(10, 2**32), masks=good)
    with pytest.raises(ValueError, match="shape"):
        broadphase.sphere_pairs(c, r, groups=np.ones((10, 1), np.uint32), masks=good)
    with pytest.raises(ValueError, match="other_masks"):
        broadphase.pairs_between(c, r, c, r, other_masks=np.ones(3, np.uint32))
    with pytest.raises(ValueError):
        broadphase.Index(c, r, groups=np.ones(3, np.uint32))
    idx = broadphase.Index(c, r)
    with pytest.raises(ValueError):
        idx.set_filters([1, 2], groups=np.ones(3, np.uint32))
    with pytest.raises(ValueError):
        idx.set_filters([1, 2])
    with pytest.raises(ValueError):
        idx.insert(c[:2], r[:2], masks=np.ones(5, np.uint32))
